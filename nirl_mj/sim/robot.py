"""Robotino entity for dm_control composer, in three wheel fidelities.

``models/robotino/robotino.xml`` is the one source of truth (the ``tyre``
fidelity). The ``rollers`` and ``planar`` fidelities are generated from it here
with ``dm_control.mjcf``:

- ``tyre``: each wheel one capsule tyre; anisotropic friction via floor pairs.
- ``rollers``: each wheel a hub with 2 staggered rows of 6 passive ellipsoid
  rollers, each roller touching the floor through its own pair.
- ``planar``: the base slides on x / y and turns about z under stiff velocity
  servos that track the body twist implied by the wheel speeds; the wheels are
  visual only. Exact kinematics, several times faster.

Contact conventions: robot collision geoms have contype=2, conaffinity=1 and
group 3; tyres/rollers have contype=conaffinity=0 and touch the floor only
through the ``<pair>`` elements that :meth:`Robotino.attach_to` adds.

Range sensors: the model carries nine MJCF rangefinders S1..S9, each on a
camera whose one-row image has ``rays_per_sensor`` pixels across the sensor's
40-degree cone (see :mod:`nirl_mj.sim.sensing` for why the task casts its own
rays and computes these only on demand).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from dm_control import composer, mjcf

from nirl_mj.sim import drive
from nirl_mj.sim.sensing import cone_fovy
from nirl_mj.sim.spec import DRIVES

__all__ = ["FIDELITIES", "MODEL_PATH", "Robotino"]

MODEL_PATH: Path = Path(__file__).resolve().parents[2] / "models" / "robotino" / "robotino.xml"
FIDELITIES: tuple[str, ...] = DRIVES

# Pair friction [tangent 1, tangent 2, torsional, rolling, rolling]. The
# capsule-plane collider puts tangent 1 along the capsule axis (the axle):
# low friction along the axle stands in for the free rollers. Grip 2 (not a
# rubber-like 1) along the rolling direction: 60 degree turns in 0.5 s at
# 2-3 m/s need up to 0.75 g lateral, 2/3 of which lands on one wheel; with
# grip 1 that wheel slips and turns overshoot by 15-20 degrees.
TYRE_PAIR_FRICTION = (0.001, 2.0, 0.005, 1e-4, 1e-4)
# Rollers turn freely on their own hinges, so their friction is isotropic.
ROLLER_PAIR_FRICTION = (2.0, 2.0, 0.005, 1e-4, 1e-4)

# Roller layout: 2 staggered rows of 6 rollers per wheel. Ellipsoid semi-axes
# (r, r, sqrt(r R)) centred at R - r match the wheel's outline to second order
# (rolling radius ripple < 0.3 %); capsules would stick out (+4.5 % speed).
ROLLER_RADIUS = 0.008  # r (m)
ROLLER_ROW_OFFSET = 0.009  # rows at +-this along the axle (m), >= r so rows do not overlap
ROLLERS_PER_ROW = 6
ROLLER_MASS = 0.01  # kg, taken from the 0.5 kg wheel so the total stays 20 kg
# Passive roller hinges. Damping 1e-4 already costs ~1 % forward speed (the
# rear wheel's rollers spin at v / r = 250 rad/s at 2 m/s); 1e-5 costs ~0.5 %.
# Armature between 0 and 1e-5 made no measurable difference; 1e-4 destabilises
# the turns (each roller touching down must be spun up to v_lat / r).
ROLLER_ARMATURE = 1e-5
ROLLER_DAMPING = 1e-5

# Planar servos: time constant ~0.01 s. kv = mass / tau (linear) and
# Izz / tau (yaw) for the 20 kg robot with Izz ~0.5 kg m^2.
PLANAR_TAU = 0.01
ROBOT_MASS = 20.0
ROBOT_IZZ = 0.5

# Free-joint height that puts the tyres at their static penetration (~1e-4 m),
# so set_pose starts the robot at rest instead of dropping it.
REST_HEIGHT = -1e-4


def yaw_from_quat(w, x, y, z):
    """Heading (radians) of the unit quaternion (w, x, y, z): floats, or elementwise arrays."""
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


class _Cache:
    """Indices and array views into one MjData, rebuilt when physics changes."""

    __slots__ = ("ctrl", "data", "dofs", "model", "qpos", "qposadr", "qvel", "qveladr", "sl")

    def __init__(self, physics: Any, entity: Robotino) -> None:
        self.model = physics.model.ptr
        self.data = physics.data.ptr
        # Views stay valid as long as this MjData lives (we keep a reference).
        self.ctrl = self.data.ctrl
        self.qpos = self.data.qpos
        self.qvel = self.data.qvel
        ids = np.asarray(physics.bind(entity.drive_actuators).element_id, dtype=int)
        if ids.size and np.all(np.diff(ids) == 1):
            self.sl = slice(int(ids[0]), int(ids[-1]) + 1)  # slice writes, no fancy-index copy
        else:
            self.sl = ids
        joints = entity.pose_joints(physics)
        self.qposadr = int(physics.bind(joints[0]).qposadr)
        self.qveladr = int(physics.bind(joints[0]).dofadr)
        # Every dof of the robot (pose joints, wheels, rollers), for set_pose.
        dofs = [np.arange(self.qveladr, self.qveladr + 6)] if len(joints) == 1 else []
        hinges = entity.mjcf_model.find_all("joint")
        if hinges:
            dofs.append(np.asarray(physics.bind(hinges).dofadr, dtype=int))
        self.dofs = np.concatenate(dofs)


class Robotino(composer.Entity):
    """Festo Robotino 3 with three omniwheels (see module docstring)."""

    def _build(self, fidelity: str = "tyre", name: str = "robotino", rays_per_sensor: int = 5) -> None:
        """Load robotino.xml and adapt it to ``fidelity`` (tyre, rollers, planar) and to
        ``rays_per_sensor`` rays per rangefinder."""
        if fidelity not in FIDELITIES:
            raise ValueError(f"unknown fidelity {fidelity!r}; accepted values: {', '.join(FIDELITIES)}")
        if not MODEL_PATH.is_file():
            raise FileNotFoundError(f"Robotino model not found at {MODEL_PATH}")
        self._fidelity = fidelity
        self._mjcf_root = mjcf.from_path(str(MODEL_PATH))
        self._mjcf_root.model = name
        # The standalone model carries a free joint for scene.xml; composer
        # adds its own (tyre/rollers) or we add planar joints instead.
        self._mjcf_root.find("joint", "root").remove()

        self._base = self._mjcf_root.find("body", "base")
        self._sensor_origin = self._mjcf_root.find("site", "sensor_origin")
        self._ir_sites = [self._mjcf_root.find("site", f"S{i}") for i in range(1, 10)]
        self._rangefinders = [self._mjcf_root.find("sensor", f"S{i}") for i in range(1, 10)]
        for sensor in self._rangefinders:
            # A one-row image of rays_per_sensor pixels spanning the 40-degree cone.
            sensor.camera.resolution = (rays_per_sensor, 1)
            sensor.camera.fovy = cone_fovy(rays_per_sensor)
        self._collision_geoms = [self._mjcf_root.find("geom", "base_collision")]
        self._wheels = [self._mjcf_root.find("body", f"wheel{i}") for i in (1, 2, 3)]
        self._wheel_actuators = [self._mjcf_root.find("actuator", f"wheel{i}") for i in (1, 2, 3)]
        self._contact_geoms = [self._mjcf_root.find("geom", f"tyre{i}") for i in (1, 2, 3)]
        self._planar_joints: list = []
        self._planar_actuators: list = []
        self._cache: _Cache | None = None

        if fidelity == "rollers":
            self._build_rollers()
        elif fidelity == "planar":
            self._build_planar()

    # ----------------------------------------------------------------- builders
    def _build_rollers(self) -> None:
        for geom in self._contact_geoms:
            geom.remove()
        self._contact_geoms = []
        r, big_r = ROLLER_RADIUS, drive.WHEEL_RADIUS
        c = math.sqrt(r * big_r)
        # Solid ellipsoid inertia about its own axes (long axis = local z).
        i_long = 0.4 * ROLLER_MASS * r * r
        i_short = 0.2 * ROLLER_MASS * (r * r + c * c)
        for w, wheel in enumerate(self._wheels, start=1):
            # The hub keeps the wheel's inertia minus the rollers' mass.
            hub = wheel.inertial
            hub.mass = float(hub.mass) - 2 * ROLLERS_PER_ROW * ROLLER_MASS
            for row, y in enumerate((-ROLLER_ROW_OFFSET, ROLLER_ROW_OFFSET)):
                for k in range(ROLLERS_PER_ROW):
                    # Wheel frame: x = drive direction, y = axle, z = up;
                    # rollers sit in the x-z plane, rows staggered by half a pitch.
                    phi = 2.0 * math.pi * (k + 0.5 * row) / ROLLERS_PER_ROW
                    radial = np.array([math.cos(phi), 0.0, math.sin(phi)])
                    tangent = np.array([-math.sin(phi), 0.0, math.cos(phi)])
                    body = wheel.add(
                        "body",
                        name=f"wheel{w}_roller{row}{k}",
                        pos=(big_r - r) * radial + np.array([0.0, y, 0.0]),
                        zaxis=tangent,
                    )
                    body.add(
                        "joint",
                        name=f"wheel{w}_roller{row}{k}",
                        type="hinge",
                        axis=[0, 0, 1],
                        armature=ROLLER_ARMATURE,
                        damping=ROLLER_DAMPING,
                    )
                    body.add(
                        "inertial", pos=[0, 0, 0], mass=ROLLER_MASS, diaginertia=[i_short, i_short, i_long]
                    )
                    geom = body.add(
                        "geom",
                        name=f"wheel{w}_roller{row}{k}",
                        dclass="collision",
                        type="ellipsoid",
                        size=[r, r, c],
                        contype=0,
                        conaffinity=0,
                        condim=3,
                        rgba=[0.1, 0.1, 0.1, 1],
                    )
                    self._contact_geoms.append(geom)

    def _build_planar(self) -> None:
        for geom in self._contact_geoms:
            geom.remove()
        self._contact_geoms = []
        for act in self._wheel_actuators:
            act.remove()
        self._wheel_actuators = []
        for wheel in self._wheels:
            wheel.find("joint", wheel.name).remove()
        # Slides first, hinge last: MuJoCo composes a body's joints in order, so
        # the slides stay along the parent's (world) x and y axes.
        base = self._base
        self._planar_joints = [
            base.add("joint", name="slide_x", type="slide", axis=[1, 0, 0], armature=0, damping=0),
            base.add("joint", name="slide_y", type="slide", axis=[0, 1, 0], armature=0, damping=0),
            base.add("joint", name="yaw", type="hinge", axis=[0, 0, 1], armature=0, damping=0),
        ]
        kv_lin, kv_yaw = ROBOT_MASS / PLANAR_TAU, ROBOT_IZZ / PLANAR_TAU
        self._planar_actuators = [
            self._mjcf_root.actuator.add("velocity", name=j.name, joint=j, kv=kv)
            for j, kv in zip(self._planar_joints, (kv_lin, kv_lin, kv_yaw), strict=True)
        ]

    # --------------------------------------------------------------- properties
    @property
    def mjcf_model(self) -> mjcf.RootElement:
        """The entity's MJCF root."""
        return self._mjcf_root

    @property
    def fidelity(self) -> str:
        """One of :data:`FIDELITIES`."""
        return self._fidelity

    @property
    def base_body(self) -> mjcf.Element:
        """The chassis body (use as ``bodyexclude`` for range rays)."""
        return self._base

    @property
    def sensor_origin(self) -> mjcf.Element:
        """Site at the robot centre, 0.0566 m above the floor (ray origin)."""
        return self._sensor_origin

    @property
    def ir_sites(self) -> list:
        """Sites S1..S9 (visual markers of the IR sensors, 40 deg apart; the rangefinders
        cast from the robot's axis, see :attr:`rangefinders`)."""
        return list(self._ir_sites)

    @property
    def rangefinders(self) -> list:
        """Camera rangefinder sensors S1..S9 (``rays_per_sensor`` readings each, see module doc)."""
        return list(self._rangefinders)

    @property
    def wheel_actuators(self) -> list:
        """Wheel velocity actuators (ctrl in rad/s); empty for ``planar``."""
        return list(self._wheel_actuators)

    @property
    def planar_actuators(self) -> list:
        """Velocity servos on slide x, slide y (m/s) and yaw (rad/s); ``planar`` only."""
        return list(self._planar_actuators)

    @property
    def drive_actuators(self) -> list:
        """The actuators :meth:`set_wheel_speeds` writes (wheels or planar servos)."""
        return list(self._planar_actuators or self._wheel_actuators)

    @property
    def collision_geoms(self) -> list:
        """Geoms that collide with the world (contype=2, conaffinity=1)."""
        return list(self._collision_geoms)

    @property
    def contact_geoms(self) -> list:
        """Tyre or roller geoms that touch the floor via pairs (none for ``planar``)."""
        return list(self._contact_geoms)

    # ------------------------------------------------------------------ helpers
    def attach_to(self, arena: composer.Arena, ground_geom: mjcf.Element) -> mjcf.Element:
        """Attach the robot to ``arena`` and add the wheel-floor pairs to its root.

        Tyre/rollers are attached as free entities; planar is attached fixed
        (at the world origin) because its slide/hinge joints live in the entity.

        Returns:
            The attachment frame.
        """
        if self._fidelity == "planar":
            frame = arena.attach(self)
        else:
            frame = arena.add_free_entity(self)
        friction = TYRE_PAIR_FRICTION if self._fidelity == "tyre" else ROLLER_PAIR_FRICTION
        for geom in self._contact_geoms:
            arena.mjcf_model.contact.add("pair", geom1=ground_geom, geom2=geom, condim=3, friction=friction)
        return frame

    def pose_joints(self, physics: Any) -> list:
        """Joints that carry the planar pose: the free joint, or slide x/y + yaw."""
        if self._planar_joints:
            return list(self._planar_joints)
        freejoint = mjcf.get_frame_freejoint(self._mjcf_root)
        if freejoint is None:
            raise RuntimeError("Robotino is not attached as a free entity; call attach_to() first")
        return [freejoint]

    def _get_cache(self, physics: Any) -> _Cache:
        cache = self._cache
        # physics.data.ptr changes when the model is recompiled or reloaded.
        if cache is None or cache.data is not physics.data.ptr or cache.model is not physics.model.ptr:
            cache = self._cache = _Cache(physics, self)
        return cache

    # ---------------------------------------------------------------- hot path
    def set_wheel_speeds(self, physics: Any, omega: np.ndarray, cmd_dt: float = 0.01) -> None:
        """Command the three wheel speeds (rad/s), shape (3,).

        For ``planar`` the wheel speeds are turned into the body twist
        (forward kinematics) and rotated into the world frame with the yaw
        expected at the middle of the coming command period,
        ``yaw + wz * cmd_dt / 2`` (s), so a straight segment per period
        follows the arc the wheels would drive.
        """
        self.wheel_commander(physics, cmd_dt)(np.asarray(omega, dtype=float))

    def wheel_commander(self, physics: Any, cmd_dt: float = 0.01) -> Callable[[np.ndarray], None]:
        """:meth:`set_wheel_speeds` bound to ``physics`` and ``cmd_dt`` (s), for the per-period
        hot loop: it takes float64 arrays of shape (3,) only, and (``planar``) remembers the body
        twist of the last wheel speeds, which repeat for most of a decision."""
        c = self._get_cache(physics)
        ctrl, sl = c.ctrl, c.sl
        if not self._planar_joints:

            def command(omega: np.ndarray) -> None:
                ctrl[sl] = omega

            return command
        qpos, yaw_adr = c.qpos, c.qposadr + 2
        i = sl.start if isinstance(sl, slice) else None
        last: list = [b"", (0.0, 0.0, 0.0)]

        def command(omega: np.ndarray) -> None:
            key = omega.tobytes()
            if key != last[0]:
                last[0], last[1] = key, tuple(drive.body_twist(omega))
            vx, vy, wz = last[1]
            yaw = qpos[yaw_adr] + 0.5 * wz * cmd_dt
            cy, sy = math.cos(yaw), math.sin(yaw)
            if i is None:
                ctrl[sl] = (cy * vx - sy * vy, sy * vx + cy * vy, wz)
            else:
                ctrl[i] = cy * vx - sy * vy
                ctrl[i + 1] = sy * vx + cy * vy
                ctrl[i + 2] = wz

        return command

    def get_pose(self, physics: Any) -> np.ndarray:
        """Planar pose ``(x, y, yaw)`` (m, m, rad), shape (3,), from qpos (current)."""
        c = self._get_cache(physics)
        q, a = c.qpos, c.qposadr
        if self._planar_joints:
            return np.array([q[a], q[a + 1], q[a + 2]])
        return np.array([q[a], q[a + 1], yaw_from_quat(q[a + 3], q[a + 4], q[a + 5], q[a + 6])])

    def get_velocity(self, physics: Any) -> np.ndarray:
        """Body-frame twist ``(vx, vy, wz)`` (m/s, m/s, rad/s), shape (3,)."""
        c = self._get_cache(physics)
        v, a = c.qvel, c.qveladr
        yaw = self.get_pose(physics)[2]
        cy, sy = math.cos(yaw), math.sin(yaw)
        # Slides and the free joint's linear part are world-frame; the free
        # joint's angular velocity is body-frame (~world z while upright).
        vxw, vyw = v[a], v[a + 1]
        wz = v[a + 2] if self._planar_joints else v[a + 5]
        return np.array([cy * vxw + sy * vyw, -sy * vxw + cy * vyw, wz])

    def set_pose(self, physics: Any, x: float, y: float, yaw: float) -> None:  # type: ignore[override]
        """Place the robot at ``(x, y)`` (m) heading ``yaw`` (rad), at rest.

        The wheels touch the floor; every robot joint velocity and the drive
        commands are zeroed. Derived quantities (xpos, ...) update at the next
        ``physics.forward()`` or step.
        """
        c = self._get_cache(physics)
        q, a = c.qpos, c.qposadr
        if self._planar_joints:
            q[a : a + 3] = (x, y, yaw)
        else:
            q[a : a + 7] = (x, y, REST_HEIGHT, math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw))
        c.qvel[c.dofs] = 0.0
        c.ctrl[c.sl] = 0.0
