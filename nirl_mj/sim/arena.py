"""The dm_control composer arena that shows any :class:`~nirl_mj.sim.layout.Layout` of a spec.

The MJCF is built once per :class:`~nirl_mj.sim.spec.ArenaSpec` with pools of
obstacle slots; :meth:`NavigationArena.apply_layout` writes an episode's
layout into the compiled model, so episodes never recompile.

How a slot is moved and resized (measured on MuJoCo 3.17, see tests):

- Each obstacle slot is its own static body (child of the world body) with
  one geom at its origin. Slots are moved through ``body_pos``/``body_quat``,
  not ``geom_pos``: geoms in the world body share the world's bounding-volume
  hierarchy (``bvh_aabb``), which is computed at compile time and used by the
  collision midphase and by ``mj_multiRay``, so moved world-body geoms are
  silently missed. One body per slot has a one-node hierarchy we can rewrite.
- Resizing writes ``geom_size`` and also ``geom_rbound``, ``geom_aabb`` and the
  slot body's ``bvh_aabb`` node: the compiler derives them from the size and
  the collision pipeline culls with all three (each one left stale loses the
  contact). Rays only need ``geom_size`` and a pose.
- Unused slots are parked at z = -50, fully transparent (``mj_ray`` and
  ``mj_multiRay`` skip geoms with alpha 0) and get contype = conaffinity = 0
  on geom and body, so the broadphase drops them entirely.
- Moving obstacles are mocap bodies; their state (positions and velocities)
  lives in this object as numpy arrays, not in ``physics``: ``physics.reset()``
  puts them back at the episode's initial positions (``body_pos`` is set too)
  but the arena's own state is only reset by :meth:`apply_layout`.

Geom conventions: obstacles and walls contype=1, conaffinity=2, group 0 (robot
geoms are contype=2, conaffinity=1, groups >= 1, so obstacles never collide
with each other and range rays that only see group 0 never see the robot);
the floor has contype=conaffinity=0 (the robot's wheels touch it through
explicit ``<pair>`` elements); markers are visual only (group 2).
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np
from dm_control import composer, mjcf

from nirl_mj.sim.floorplans import slot_counts
from nirl_mj.sim.layout import Layout, advance_in_place, time_to_wall
from nirl_mj.sim.spec import ArenaSpec

__all__ = ["NavigationArena", "PARK_Z"]

PARK_Z = -50.0  # height (m) of unused slots: far below the floor, out of every ray's way

# Colours (RGBA).
_BOX_RGBA = (0.45, 0.45, 0.50, 1.0)
_CYLINDER_RGBA = (0.55, 0.40, 0.28, 1.0)
_WALL_RGBA = (0.28, 0.28, 0.32, 1.0)
_MOVING_RGBA = (1.0, 0.55, 0.10, 1.0)
_TARGET_RGBA = (0.10, 0.80, 0.20, 0.6)
_START_RGBA = (0.15, 0.35, 0.95, 0.6)
_PARKED_SIZE = 0.1  # m, any small positive size for unused slots

_MARKER_HALF_HEIGHT = 0.002  # m: flat discs
_START_MARKER_RADIUS = 1.0  # m
_OVERVIEW_FOVY = 45.0  # degrees
OFFSCREEN_SIZE = (1280, 960)
"""The offscreen buffer (width, height) in pixels: the largest frame any camera renders."""
_OVERVIEW_ASPECT = OFFSCREEN_SIZE[0] / OFFSCREEN_SIZE[1]  # the overview fills the buffer

# Contact bits (see module docstring).
_OBSTACLE_CONTYPE, _OBSTACLE_CONAFFINITY = 1, 2


class _Cache:
    """Element ids and array views of one compiled model/data pair."""

    def __init__(self, physics: Any, arena: NavigationArena) -> None:
        self.model = physics.model.ptr
        self.data = physics.data.ptr

        def ids(elements: list) -> np.ndarray:
            # By name rather than physics.bind: bind maps mocap bodies to a
            # "mocap_body" namespace that has no element ids.
            out = np.empty(len(elements), dtype=np.intp)
            for k, el in enumerate(elements):
                kind = mujoco.mjtObj.mjOBJ_BODY if el.tag == "body" else mujoco.mjtObj.mjOBJ_GEOM
                out[k] = mujoco.mj_name2id(self.model, kind, el.full_identifier)
                if out[k] < 0:
                    raise KeyError(f"{el.tag} {el.full_identifier!r} not in this physics' model")
            return out

        self.border = ids(arena._border_walls)
        self.pools = {}
        for pool, (bodies, geoms) in arena._pools.items():
            body_ids = ids(bodies)
            self.pools[pool] = (
                body_ids,
                ids(geoms),
                np.asarray(self.model.body_bvhadr[body_ids], dtype=np.intp),
            )
        self.mover_bodies, self.mover_geoms = ids(arena._mover_bodies), ids(arena._mover_geoms)
        self.mover_bvh = np.asarray(self.model.body_bvhadr[self.mover_bodies], dtype=np.intp)
        self.mocap = np.asarray(self.model.body_mocapid[self.mover_bodies], dtype=np.intp)
        self.target_body = int(ids([arena._target_marker])[0])
        self.start_body = int(ids([arena._start_marker])[0])
        # Moving bodies are consecutive mocap bodies: a slice view writes
        # mocap_pos without fancy-index temporaries on the hot path.
        mocap_pos = self.data.mocap_pos
        if self.mocap.size and np.all(np.diff(self.mocap) == 1):
            self.mocap_xy = mocap_pos[self.mocap[0] : self.mocap[-1] + 1, :2]
        else:
            self.mocap_xy = None

        ngeom = self.model.ngeom
        mask = np.zeros(ngeom, dtype=bool)
        mask[self.border] = True
        mask[self.pools["wall"][1]] = True
        mask.flags.writeable = False
        self.wall_mask = mask
        obstacle = np.concatenate([self.border, *(g for _, g, _ in self.pools.values()), self.mover_geoms])
        obstacle.flags.writeable = False
        self.obstacle_ids = obstacle


class NavigationArena(composer.Arena):
    """Border walls, a floor, pools of obstacle slots and markers for one spec.

    Slots: ``spec.static_obstacles`` + explicit boxes box slots,
    ``spec.static_obstacles`` + explicit cylinders cylinder slots,
    ``spec.interior_walls`` + explicit walls wall slots, each plus the most
    the floor plan adds (:func:`~nirl_mj.sim.floorplans.slot_counts`), and
    ``spec.moving_obstacles`` mocap cylinders, enough for any layout that
    :func:`~nirl_mj.sim.layout.generate_layout` draws from ``spec``.
    """

    def _build(self, spec: ArenaSpec, name: str = "arena") -> None:  # type: ignore[override]
        super()._build(name=name)
        self._spec = spec
        self._layout: Layout | None = None
        self._cache: _Cache | None = None
        width, height = (float(s) for s in spec.size)
        self._size = np.array([width, height])
        root = self._mjcf_root
        self._build_visual(root, width, height)

        thick, wall_h = spec.wall_thickness, spec.wall_height
        root.asset.add(
            "texture",
            name="grid",
            type="2d",
            builtin="checker",
            rgb1=(0.82, 0.82, 0.80),
            rgb2=(0.74, 0.74, 0.72),
            mark="edge",
            markrgb=(0.6, 0.6, 0.6),
            width=512,
            height=512,
        )
        # texuniform: texrepeat counts repetitions per metre; 0.1 -> a 10 m
        # texture tile of 2 x 2 checker squares of 5 m.
        root.asset.add(
            "material", name="grid", texture="grid", texrepeat=(0.1, 0.1), texuniform=True, reflectance=0
        )
        world = root.worldbody
        self._ground = world.add(
            "geom",
            name="ground",
            type="plane",
            size=(width / 2 + thick, height / 2 + thick, 0.1),
            pos=(width / 2, height / 2, 0.0),
            material="grid",
            contype=0,
            conaffinity=0,
            group=0,
        )
        # Border walls: inner faces at 0 and size; the south/north walls run
        # past the corners so the corners are closed.
        walls = {
            "wall_south": ((width / 2, -thick / 2), (width / 2 + thick, thick / 2)),
            "wall_north": ((width / 2, height + thick / 2), (width / 2 + thick, thick / 2)),
            "wall_west": ((-thick / 2, height / 2), (thick / 2, height / 2)),
            "wall_east": ((width + thick / 2, height / 2), (thick / 2, height / 2)),
        }
        self._border_walls = [
            world.add(
                "geom",
                name=wname,
                type="box",
                pos=(x, y, wall_h / 2),
                size=(hx, hy, wall_h / 2),
                rgba=_WALL_RGBA,
                contype=_OBSTACLE_CONTYPE,
                conaffinity=_OBSTACLE_CONAFFINITY,
                group=0,
            )
            for wname, ((x, y), (hx, hy)) in walls.items()
        ]

        explicit = [o.shape for o in spec.obstacles]
        plan = slot_counts(spec)
        counts = {
            "box": spec.static_obstacles + explicit.count("box") + plan["box"],
            "cylinder": spec.static_obstacles + explicit.count("cylinder") + plan["cylinder"],
            "wall": spec.interior_walls + explicit.count("wall") + plan["wall"],
        }
        self._pools: dict[str, tuple[list, list]] = {}
        slot = 0
        for pool, count in counts.items():
            bodies, geoms = [], []
            gtype = "cylinder" if pool == "cylinder" else "box"
            for k in range(count):
                body = world.add("body", name=f"{pool}_{k:03d}", pos=self._park_position(slot))
                slot += 1
                # Explicit inertial at the body origin: the body's bvh_aabb node
                # is expressed in the inertial frame, which then is the body frame.
                body.add("inertial", pos=(0, 0, 0), mass=1.0, diaginertia=(1, 1, 1))
                geoms.append(
                    body.add(
                        "geom",
                        name=f"{pool}_{k:03d}",
                        type=gtype,
                        size=(_PARKED_SIZE,) * 3 if gtype == "box" else (_PARKED_SIZE, _PARKED_SIZE),
                        rgba=(0, 0, 0, 0),
                        contype=_OBSTACLE_CONTYPE,
                        conaffinity=_OBSTACLE_CONAFFINITY,
                        group=0,
                    )
                )
                bodies.append(body)
            self._pools[pool] = (bodies, geoms)

        self._mover_bodies, self._mover_geoms = [], []
        for k in range(spec.moving_obstacles):
            body = world.add("body", name=f"moving_{k:03d}", mocap=True, pos=self._park_position(slot))
            slot += 1
            body.add("inertial", pos=(0, 0, 0), mass=1.0, diaginertia=(1, 1, 1))
            self._mover_geoms.append(
                body.add(
                    "geom",
                    name=f"moving_{k:03d}",
                    type="cylinder",
                    size=(_PARKED_SIZE, _PARKED_SIZE),
                    rgba=(0, 0, 0, 0),
                    contype=_OBSTACLE_CONTYPE,
                    conaffinity=_OBSTACLE_CONAFFINITY,
                    group=0,
                )
            )
            self._mover_bodies.append(body)

        def marker(mname: str, xy: tuple[float, float], radius: float, rgba: tuple) -> mjcf.Element:
            body = world.add("body", name=mname, pos=(xy[0], xy[1], 0.0))
            body.add(
                "geom",
                name=mname,
                type="cylinder",
                size=(radius, _MARKER_HALF_HEIGHT),
                pos=(0, 0, _MARKER_HALF_HEIGHT),
                rgba=rgba,
                contype=0,
                conaffinity=0,
                group=2,
            )
            return body

        self._target_marker = marker("target_marker", spec.target, spec.target_radius, _TARGET_RGBA)
        self._start_marker = marker("start_marker", spec.start, _START_MARKER_RADIUS, _START_RGBA)

        # Moving-obstacle state (hot path): positions (M, 2) m, velocities (M, 2) m/s, radii (M,) m.
        self._pos = np.zeros((0, 2))
        self._vel = np.zeros((0, 2))
        self._radii = np.zeros(0)
        self._low = np.zeros((0, 1))
        self._high = np.zeros((0, 2))
        self._until_wall = math.inf  # s until the first moving obstacle can touch a wall
        self._mocap_xy: np.ndarray | None = None
        self._movers_cache: _Cache | None = None
        self._mocap_ids = np.zeros(0, dtype=np.intp)

    def _build_visual(self, root: mjcf.RootElement, width: float, height: float) -> None:
        root.visual.map.znear = 0.001  # relative to the extent: ~7 cm in a 100 m arena
        root.visual.quality.offsamples = 0
        glob = getattr(root.visual, "global")  # "global" is a Python keyword
        glob.offwidth, glob.offheight = OFFSCREEN_SIZE
        # A fixed statistic keeps znear/zfar and the free camera independent of
        # where unused slots are parked.
        root.statistic.center = (width / 2, height / 2, 0.0)
        root.statistic.extent = math.hypot(width, height) / 2
        thick = self._spec.wall_thickness
        half = max(height / 2, width / 2 / _OVERVIEW_ASPECT) + thick
        z = 1.02 * half / math.tan(math.radians(_OVERVIEW_FOVY) / 2) + self._spec.wall_height
        # Default camera orientation looks along -z with +y up: straight down.
        root.worldbody.add("camera", name="overview", pos=(width / 2, height / 2, z), fovy=_OVERVIEW_FOVY)
        root.worldbody.add(
            "light",
            name="sun",
            pos=(width / 2, height / 2, z),
            dir=(0, 0, -1),
            directional=True,
            castshadow=False,
            diffuse=(0.5, 0.5, 0.5),
            specular=(0.1, 0.1, 0.1),
        )

    def _park_position(self, slot: int) -> tuple[float, float, float]:
        # Spread along x so parked slots never overlap each other either.
        return (3.0 * slot, -10.0, PARK_Z)

    # -- properties -------------------------------------------------------------------

    @property
    def spec(self) -> ArenaSpec:
        """The spec this arena was built for."""
        return self._spec

    @property
    def ground_geom(self) -> mjcf.Element:
        """The floor plane (contype=conaffinity=0; robots touch it through pairs)."""
        return self._ground

    @property
    def layout(self) -> Layout | None:
        """The layout last applied with :meth:`apply_layout` (None before)."""
        return self._layout

    @property
    def slot_counts(self) -> dict[str, int]:
        """Slots per pool: ``box``, ``cylinder``, ``wall``, ``moving``."""
        counts = {pool: len(bodies) for pool, (bodies, _) in self._pools.items()}
        counts["moving"] = len(self._mover_bodies)
        return counts

    @property
    def moving_positions(self) -> np.ndarray:
        """Current moving-obstacle centres, (M, 2) metres (a copy)."""
        return self._pos.copy()

    @property
    def moving_velocities(self) -> np.ndarray:
        """Current moving-obstacle velocities, (M, 2) m/s (a copy)."""
        return self._vel.copy()

    @property
    def moving_radii(self) -> np.ndarray:
        """Moving-obstacle radii, (M,) metres (a copy)."""
        return self._radii.copy()

    # -- per physics ------------------------------------------------------------------

    def _get_cache(self, physics: Any) -> _Cache:
        cache = self._cache
        # physics.data.ptr changes when the model is recompiled or reloaded.
        if cache is None or cache.data is not physics.data.ptr or cache.model is not physics.model.ptr:
            cache = self._cache = _Cache(physics, self)
        return cache

    def wall_mask(self, physics: Any) -> np.ndarray:
        """Read-only bool array (ngeom,): True for the border walls and every wall
        slot (interior and explicit walls, used or not)."""
        return self._get_cache(physics).wall_mask

    def obstacle_geom_ids(self, physics: Any) -> np.ndarray:
        """Read-only int array of every geom a robot can collide with: border
        walls, all static slots and moving obstacles (unused slots included;
        they are parked out of reach)."""
        return self._get_cache(physics).obstacle_ids

    def arm_every_slot(self, physics: Any, model: mujoco.MjModel) -> None:
        """Gives every static obstacle slot of ``model`` (a copy of ``physics``' compiled model) the
        contact bits of an obstacle in use. For a simulator that keeps one set of contact bits for
        many arenas at once (MuJoCo Warp, :mod:`nirl_mj.sim.warp_worlds`): an unused slot is parked
        at ``PARK_Z``, out of every robot's and ray's reach, so its bits never matter there, and an
        obstacles' pair never collides (contype 1 against conaffinity 2)."""
        cache = self._get_cache(physics)
        for pool in ("box", "cylinder", "wall"):
            bodies, geoms, _ = cache.pools[pool]
            model.geom_contype[geoms] = _OBSTACLE_CONTYPE
            model.geom_conaffinity[geoms] = _OBSTACLE_CONAFFINITY
            model.body_contype[bodies] = _OBSTACLE_CONTYPE
            model.body_conaffinity[bodies] = _OBSTACLE_CONAFFINITY

    def apply_layout(self, physics: Any, layout: Layout, forward: bool = True) -> None:
        """Shows ``layout`` in the compiled model of ``physics``.

        Writes pose, size, bounds, colour and contact bits of every slot (unused
        ones are parked), the moving obstacles' mocap and initial positions and
        sizes (their velocities are kept here for :meth:`move_obstacles`) and
        the markers. Calls ``mujoco.mj_forward`` unless ``forward=False`` (then
        the caller must run at least ``mj_kinematics`` before casting rays).
        Raises ValueError if the layout does not fit this arena's slots.
        """
        spec = self._spec
        if not np.allclose(layout.size, self._size):
            raise ValueError(
                f"layout size {list(layout.size)} != arena size {list(self._size)}; build a new arena"
            )
        cache = self._get_cache(physics)
        m, d = cache.model, cache.data
        groups: dict[str, list] = {"box": [], "cylinder": [], "wall": []}
        for ob in layout.obstacles:
            groups["wall" if ob.is_wall else ob.shape].append(ob)
        for pool, obs in groups.items():
            if len(obs) > len(cache.pools[pool][0]):
                raise ValueError(
                    f"layout has {len(obs)} {pool} obstacles but the arena has {len(cache.pools[pool][0])} "
                    f"{pool} slots; was it generated from another spec?"
                )
        if len(layout.moving) > cache.mover_bodies.size:
            raise ValueError(
                f"layout has {len(layout.moving)} moving obstacles but the arena has "
                f"{cache.mover_bodies.size} slots; was it generated from another spec?"
            )

        for pool, obs in groups.items():
            body_ids, geom_ids, bvh = cache.pools[pool]
            n = len(obs)
            height = spec.wall_height if pool == "wall" else spec.obstacle_height
            rgba = {"box": _BOX_RGBA, "cylinder": _CYLINDER_RGBA, "wall": _WALL_RGBA}[pool]
            used_b, used_g, used_bvh = body_ids[:n], geom_ids[:n], bvh[:n]
            if n:
                xy = np.array([(o.x, o.y) for o in obs])
                yaw = np.array([o.yaw for o in obs])
                m.body_pos[used_b] = np.column_stack([xy, np.full(n, height / 2)])
                m.body_quat[used_b] = np.column_stack(
                    [np.cos(yaw / 2), np.zeros(n), np.zeros(n), np.sin(yaw / 2)]
                )
                if pool == "cylinder":
                    r = np.array([o.size[0] for o in obs])
                    half = np.column_stack([r, r, np.full(n, height / 2)])
                    m.geom_size[used_g] = np.column_stack([r, np.full(n, height / 2), np.zeros(n)])
                    m.geom_rbound[used_g] = np.hypot(r, height / 2)
                else:
                    half = np.column_stack([np.array([o.size[:2] for o in obs]), np.full(n, height / 2)])
                    m.geom_size[used_g] = half
                    m.geom_rbound[used_g] = np.linalg.norm(half, axis=1)
                _set_bounds(m, used_g, used_bvh, half)
                _set_active(m, used_b, used_g, rgba)
            self._park(m, body_ids[n:], geom_ids[n:], bvh[n:], cylinder=pool == "cylinder")

        # Moving obstacles.
        n = len(layout.moving)
        height = spec.obstacle_height
        self._pos = np.array([(o.x, o.y) for o in layout.moving], dtype=np.float64).reshape(n, 2)
        self._vel = np.array([(o.vx, o.vy) for o in layout.moving], dtype=np.float64).reshape(n, 2)
        self._radii = np.array([o.radius for o in layout.moving], dtype=np.float64).reshape(n)
        # Bounds of the centres for advance_in_place: radius .. size - radius.
        self._low = self._radii.reshape(n, 1).copy()
        self._high = self._size.reshape(1, 2) - self._low
        self._until_wall = time_to_wall(self._pos, self._vel, self._low, self._high)
        if n:
            used_b, used_g, used_bvh = cache.mover_bodies[:n], cache.mover_geoms[:n], cache.mover_bvh[:n]
            pos3 = np.column_stack([self._pos, np.full(n, height / 2)])
            d.mocap_pos[cache.mocap[:n]] = pos3
            d.mocap_quat[cache.mocap[:n]] = (1, 0, 0, 0)
            # mj_resetData copies body_pos into mocap_pos: physics.reset() then
            # restores the episode's initial positions, not the parking spot.
            m.body_pos[used_b] = pos3
            r = self._radii
            m.geom_size[used_g] = np.column_stack([r, np.full(n, height / 2), np.zeros(n)])
            m.geom_rbound[used_g] = np.hypot(r, height / 2)
            _set_bounds(m, used_g, used_bvh, np.column_stack([r, r, np.full(n, height / 2)]))
            _set_active(m, used_b, used_g, _MOVING_RGBA)
        parked = cache.mover_bodies[n:]
        if parked.size:
            self._park(m, parked, cache.mover_geoms[n:], cache.mover_bvh[n:], cylinder=True)
            park = m.body_pos[parked]
            d.mocap_pos[cache.mocap[n:]] = park
        self._bind_movers(cache)

        m.body_pos[cache.target_body, :2] = layout.target
        m.body_pos[cache.start_body, :2] = layout.start
        self._layout = layout
        if forward:
            mujoco.mj_forward(m, d)

    def _park(
        self, m: mujoco.MjModel, bodies: np.ndarray, geoms: np.ndarray, bvh: np.ndarray, cylinder: bool
    ) -> None:
        if not bodies.size:
            return
        n = bodies.size
        m.body_pos[bodies, 2] = PARK_Z
        m.body_quat[bodies] = (1, 0, 0, 0)
        size = np.full((n, 3), _PARKED_SIZE)
        if cylinder:
            m.geom_size[geoms] = (_PARKED_SIZE, _PARKED_SIZE, 0)
            m.geom_rbound[geoms] = math.hypot(_PARKED_SIZE, _PARKED_SIZE)
        else:
            m.geom_size[geoms] = size
            m.geom_rbound[geoms] = np.linalg.norm(size, axis=1)
        _set_bounds(m, geoms, bvh, size)
        m.geom_rgba[geoms] = (0, 0, 0, 0)  # alpha 0: rays skip it, renders hide it
        m.geom_contype[geoms] = 0
        m.geom_conaffinity[geoms] = 0
        m.body_contype[bodies] = 0  # the broadphase filters on the body's bits
        m.body_conaffinity[bodies] = 0

    def move_obstacles(self, physics: Any, dt: float) -> None:
        """Advances the moving obstacles by ``dt`` seconds (straight lines,
        bouncing off the border walls, through static obstacles) and writes
        their mocap positions. Hot path: no ``physics.bind``, in-place updates."""
        if not self._radii.size:
            return
        cache = self._get_cache(physics)
        if cache is not self._movers_cache:  # physics reloaded since apply_layout
            self._bind_movers(cache)
        if self._until_wall > dt:
            # No rim can reach a wall during this step: a straight move is exact.
            self._pos += self._vel * dt
            self._until_wall -= dt
        else:
            advance_in_place(self._pos, self._vel, self._low, self._high, dt)
            self._until_wall = time_to_wall(self._pos, self._vel, self._low, self._high)
        if self._mocap_xy is not None:
            self._mocap_xy[...] = self._pos
        else:
            cache.data.mocap_pos[self._mocap_ids, :2] = self._pos

    def _bind_movers(self, cache: _Cache) -> None:
        # The hot path writes through a view of exactly the used movers' rows.
        n = self._radii.size
        self._mocap_xy = cache.mocap_xy[:n] if cache.mocap_xy is not None else None
        self._mocap_ids = cache.mocap[:n]
        self._movers_cache = cache


def _set_bounds(m: mujoco.MjModel, geoms: np.ndarray, bvh: np.ndarray, half: np.ndarray) -> None:
    """Writes the local-frame bounding boxes (centre 0, half-sizes ``half`` (n, 3))
    that the compiler would have derived: ``geom_aabb`` and the slot body's
    single ``bvh_aabb`` node (inertial frame == body frame == geom frame)."""
    aabb = np.concatenate([np.zeros_like(half), half], axis=1)
    m.geom_aabb[geoms] = aabb
    m.bvh_aabb[bvh] = aabb


def _set_active(m: mujoco.MjModel, bodies: np.ndarray, geoms: np.ndarray, rgba: tuple) -> None:
    m.geom_rgba[geoms] = rgba
    m.geom_contype[geoms] = _OBSTACLE_CONTYPE
    m.geom_conaffinity[geoms] = _OBSTACLE_CONAFFINITY
    m.body_contype[bodies] = _OBSTACLE_CONTYPE
    m.body_conaffinity[bodies] = _OBSTACLE_CONAFFINITY
