"""Model tests for the Robotino entity in its three fidelities."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from dm_control import composer, mjcf

from nirl_mj.sim import drive, robot
from nirl_mj.sim.robot import FIDELITIES, Robotino
from nirl_mj.sim.sensing import cone_fovy
from nirl_mj.sim.spec import ArenaSpec

MODELS = Path(__file__).resolve().parents[1] / "models" / "robotino"
CMD_DT = 0.01
TIMESTEP = 0.005
NSUB = round(CMD_DT / TIMESTEP)
SPEED = 2.0


class _Arena(composer.Arena):
    """A bare floor: contype=conaffinity=0, the robot adds the wheel pairs."""

    def _build(self) -> None:
        super()._build()
        # composer.Arena defaults to dt 0.002 and 5 noslip iterations; the
        # robot is tuned for dt 0.005 without noslip.
        self.mjcf_model.option.timestep = TIMESTEP
        self.mjcf_model.option.noslip_iterations = 0
        self.ground_geom = self.mjcf_model.worldbody.add(
            "geom", name="ground", type="plane", size=[50, 50, 0.1], contype=0, conaffinity=0
        )


def _make(fidelity: str) -> tuple[Robotino, mjcf.Physics]:
    arena = _Arena()
    bot = Robotino(fidelity=fidelity)
    bot.attach_to(arena, arena.ground_geom)
    physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
    bot.set_pose(physics, 0.0, 0.0, 0.0)
    return bot, physics


def _run_commands(bot: Robotino, physics: mjcf.Physics, commands: np.ndarray) -> None:
    """One command period per row: set the wheel speeds, then step NSUB times."""
    m, d = physics.model.ptr, physics.data.ptr
    for omega in commands:
        bot.set_wheel_speeds(physics, omega, CMD_DT)
        mujoco.mj_step(m, d, NSUB)


def _drive(bot, physics, actions, speed=SPEED, controller=None) -> list[np.ndarray]:
    """Run decisions; returns the pose after each one (first entry: start pose)."""
    ctl = controller or drive.DriveController()
    poses = [bot.get_pose(physics)]
    for action in actions:
        _run_commands(bot, physics, ctl.plan(action, speed, 0.5, CMD_DT, 4.0))
        poses.append(bot.get_pose(physics))
    return poses


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _warnings(physics) -> list[int]:
    return [int(w.number) for w in physics.data.warning]


# ----------------------------------------------------------------- model files
def test_scene_loads_standalone() -> None:
    model = mujoco.MjModel.from_xml_path(str(MODELS / "scene.xml"))
    data = mujoco.MjData(model)
    assert model.npair == 3
    assert model.opt.timestep == pytest.approx(0.005)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert mujoco.mj_getTotalmass(model) == pytest.approx(20.0, rel=1e-3)
    # Drive forward on the standalone scene: positive twist moves forward.
    omega = drive.wheel_speeds([1.0, 0.0, 0.0])
    for k in range(300):
        data.ctrl[:] = omega * min(1.0, k / 50)
        mujoco.mj_step(model, data)
    assert data.qpos[0] > 1.0
    assert abs(data.qpos[1]) < 0.01
    assert not any(w.number for w in data.warning)


def test_model_conventions() -> None:
    model = mujoco.MjModel.from_xml_path(str(MODELS / "robotino.xml"))
    for i in range(model.ngeom):
        g = model.geom(i)
        pair = (int(g.contype[0]), int(g.conaffinity[0]))
        assert pair in {(0, 0), (2, 1)}, g.name
        assert g.group[0] >= 1, g.name
        if g.name in {"bumper", "chassis", "top_plate", "front_marker"} or g.name.endswith("_visual"):
            assert pair == (0, 0) and g.group[0] == 2
    base = model.geom("base_collision")
    assert base.size[0] == pytest.approx(0.225)
    assert base.pos[2] - base.size[1] > 0.0  # never reaches the floor
    for k in range(9):
        pos = model.site(f"S{k + 1}").pos
        assert math.hypot(pos[0], pos[1]) == pytest.approx(0.2264, abs=1e-4)
        assert math.degrees(math.atan2(pos[1], pos[0])) % 360 == pytest.approx(40 * k, abs=0.05)
        assert pos[2] == pytest.approx(0.0566)
    assert model.site("sensor_origin").pos == pytest.approx([0, 0, 0.0566])
    for name in ("chase", "top"):
        tracking = (mujoco.mjtCamLight.mjCAMLIGHT_TRACK, mujoco.mjtCamLight.mjCAMLIGHT_TRACKCOM)
        assert int(model.camera(name).mode[0]) in {int(t) for t in tracking}
    assert model.vis.global_.offwidth == 1280
    assert model.vis.map.znear == pytest.approx(0.001)


def test_unknown_fidelity() -> None:
    with pytest.raises(ValueError, match="tyre, rollers, planar"):
        Robotino(fidelity="hover")


def test_missing_model_file(monkeypatch, tmp_path) -> None:
    missing = tmp_path / "nope" / "robotino.xml"
    monkeypatch.setattr(robot, "MODEL_PATH", missing)
    with pytest.raises(FileNotFoundError, match=str(missing)):
        Robotino()


# ------------------------------------------------------------------ simulation
@pytest.mark.parametrize("fidelity", FIDELITIES)
def test_random_commands_no_warnings(fidelity: str) -> None:
    bot, physics = _make(fidelity)
    assert bot.fidelity == fidelity
    assert len(bot.wheel_actuators) == (0 if fidelity == "planar" else 3)
    rng = np.random.default_rng(0)
    robot_bodies = set(physics.bind(bot.mjcf_model.find_all("body")).element_id.tolist())
    m, d = physics.model.ptr, physics.data.ptr
    ctl = drive.DriveController()
    for _ in range(2):  # 2 decisions of random, rate-limited wheel commands = 1 s
        targets = rng.uniform(-60, 60, size=(50, 3))
        cmds = drive.rate_limit(ctl.last, targets, 4.0 / drive.WHEEL_RADIUS, CMD_DT)
        ctl.reset(cmds[-1])
        for omega in cmds:
            bot.set_wheel_speeds(physics, omega, CMD_DT)
            mujoco.mj_step(m, d, NSUB)
            for c in d.contact[: d.ncon]:
                b1, b2 = m.geom_bodyid[c.geom1], m.geom_bodyid[c.geom2]
                assert not (b1 in robot_bodies and b2 in robot_bodies), "robot-vs-robot contact"
    assert _warnings(physics) == [0] * len(_warnings(physics))
    assert np.all(np.isfinite(d.qpos))
    # Upright: the base z axis still points up.
    assert physics.bind(bot.base_body).xmat[8] > 0.95


@pytest.mark.parametrize("fidelity", FIDELITIES)
def test_forward_speed_and_heading(fidelity: str) -> None:
    bot, physics = _make(fidelity)
    bot.set_pose(physics, 1.0, -2.0, 0.4)
    poses = _drive(bot, physics, [0] * 6)
    # Steady state: the last two decisions (after the 0.5 s ramp).
    step = np.linalg.norm(poses[-1][:2] - poses[-3][:2]) / 1.0
    assert step == pytest.approx(SPEED, rel=0.02)
    vx, vy, wz = bot.get_velocity(physics)
    assert vx == pytest.approx(SPEED, rel=0.02)
    assert abs(math.degrees(_wrap(poses[-1][2] - 0.4))) < 1.0
    # The motion is along the heading.
    d = poses[-1][:2] - poses[0][:2]
    assert abs(math.degrees(_wrap(math.atan2(d[1], d[0]) - 0.4))) < 1.0


@pytest.mark.parametrize("fidelity", FIDELITIES)
def test_backward(fidelity: str) -> None:
    bot, physics = _make(fidelity)
    poses = _drive(bot, physics, [5, 5, 5])
    assert poses[-1][0] < -1.0
    assert abs(poses[-1][1]) < 0.05
    assert abs(math.degrees(_wrap(poses[-1][2]))) < 1.0
    assert bot.get_velocity(physics)[0] < -1.9


@pytest.mark.parametrize("fidelity", FIDELITIES)
@pytest.mark.parametrize("action", [1, 2, 3, 4])
def test_turns(fidelity: str, action: int) -> None:
    bot, physics = _make(fidelity)
    ctl = drive.DriveController()
    _drive(bot, physics, [0, 0], controller=ctl)  # cruise first
    before = bot.get_pose(physics)[2]
    after = _drive(bot, physics, [action], controller=ctl)[-1][2]
    turned = math.degrees(_wrap(after - before))
    assert turned == pytest.approx(math.degrees(drive.ACTIONS[action].turn), abs=3.0)


def test_fidelities_agree() -> None:
    actions = [0, 0, 2, 0, 4, 1, 0, 3, 5, 5, 0, 0, 2, 2, 0, 4, 3, 0, 1, 0]
    ends, paths = {}, {}
    for fidelity in FIDELITIES:
        bot, physics = _make(fidelity)
        poses = np.array(_drive(bot, physics, actions))
        ends[fidelity] = poses[-1]
        paths[fidelity] = np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1).sum()
    travelled = paths["planar"]
    assert travelled > 10.0
    for fidelity in ("tyre", "rollers"):
        err = np.linalg.norm(ends[fidelity][:2] - ends["planar"][:2])
        assert err < 0.05 * travelled, (fidelity, ends[fidelity], ends["planar"])


@pytest.mark.parametrize("fidelity", FIDELITIES)
def test_set_pose_rests_on_floor(fidelity: str) -> None:
    bot, physics = _make(fidelity)
    _drive(bot, physics, [0, 2])  # moving, turned
    bot.set_pose(physics, 3.0, -4.0, -2.5)
    np.testing.assert_allclose(bot.get_pose(physics), [3.0, -4.0, -2.5], atol=1e-12)
    np.testing.assert_allclose(bot.get_velocity(physics), 0.0, atol=1e-12)
    _run_commands(bot, physics, np.zeros((50, 3)))  # 0.5 s standing still
    np.testing.assert_allclose(bot.get_pose(physics), [3.0, -4.0, -2.5], atol=2e-3)
    np.testing.assert_allclose(bot.get_velocity(physics), 0.0, atol=1e-2)
    physics.forward()
    np.testing.assert_allclose(physics.bind(bot.base_body).xpos[:2], [3.0, -4.0], atol=2e-3)
    assert abs(physics.bind(bot.base_body).xpos[2]) < 2e-3  # base origin is on the floor
    assert _warnings(physics) == [0] * len(_warnings(physics))


def test_entity_properties() -> None:
    bot, physics = _make("tyre")
    assert bot.base_body.name == "base"
    assert bot.sensor_origin.name == "sensor_origin"
    assert [g.name for g in bot.collision_geoms] == ["base_collision"]
    assert len(bot.contact_geoms) == 3
    origin = physics.bind(bot.sensor_origin).xpos
    assert origin[2] == pytest.approx(0.0566, abs=2e-3)
    assert len(Robotino(fidelity="rollers").contact_geoms) == 3 * 12


def test_cache_survives_recompile() -> None:
    arena = _Arena()
    bot = Robotino()
    bot.attach_to(arena, arena.ground_geom)
    p1 = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
    bot.set_wheel_speeds(p1, np.array([1.0, 2.0, 3.0]))
    p2 = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
    bot.set_wheel_speeds(p2, np.array([4.0, 5.0, 6.0]))
    np.testing.assert_allclose(p1.bind(bot.wheel_actuators).ctrl, [1, 2, 3])
    np.testing.assert_allclose(p2.bind(bot.wheel_actuators).ctrl, [4, 5, 6])


def _geom_top(m: mujoco.MjModel, d: mujoco.MjData, g: int) -> float:
    """Highest world z of geom ``g`` (box, ellipsoid, cylinder or capsule), m."""
    rz, size, kind = d.geom_xmat[g, 6:9], m.geom_size[g], mujoco.mjtGeom(m.geom_type[g])
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        reach = float(np.abs(rz) @ size)
    elif kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        reach = float(np.linalg.norm(rz * size))
    elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:  # radius size[0], half-length size[1] along z
        reach = size[1] * abs(rz[2]) + size[0] * math.hypot(rz[0], rz[1])
    elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        reach = size[1] * abs(rz[2]) + size[0]
    else:
        raise AssertionError(f"geom {g}: unexpected type {kind}")
    return float(d.geom_xpos[g, 2] + reach)


@pytest.mark.parametrize("fidelity", FIDELITIES)
def test_rangefinders_never_see_the_robot(fidelity: str) -> None:
    """The rangefinder cameras sit on the robot's axis, above every robot geom outside the base
    body (a rangefinder ignores only its camera's body) and below the lowest obstacle or wall a
    task allows, so that horizontal rays from there meet the world where the sensor-height
    rays from the centre do; on a bare floor with the wheels at any angle nothing is hit."""
    bot, physics = _make(fidelity)
    cameras = [s.camera for s in bot.rangefinders]
    assert [s.name for s in bot.rangefinders] == [f"S{i}" for i in range(1, 10)]
    m, d = physics.model.ptr, physics.data.ptr
    cam_ids = physics.bind(cameras).element_id
    base_id = physics.bind(bot.base_body).element_id
    assert np.all(m.cam_bodyid[cam_ids] == base_id)
    np.testing.assert_array_equal(m.cam_pos[cam_ids, :2], 0.0)
    lowest_world = min(
        f.metadata["low"]
        for f in dataclasses.fields(ArenaSpec)
        if f.name in ("obstacle_height", "wall_height")
    )
    robot_geoms = physics.bind(bot.mjcf_model.find_all("geom")).element_id
    others = robot_geoms[m.geom_bodyid[robot_geoms] != base_id]
    rng = np.random.default_rng(0)
    hinges = [j for j in bot.mjcf_model.find_all("joint") if j.name.startswith("wheel")]
    for _ in range(20):
        bot.set_pose(physics, 0.0, 0.0, rng.uniform(-math.pi, math.pi))
        if hinges:
            physics.bind(hinges).qpos = rng.uniform(-math.pi, math.pi, size=len(hinges))
        mujoco.mj_forward(m, d)
        top = max(_geom_top(m, d, g) for g in others)
        cam_z = d.cam_xpos[cam_ids, 2]
        assert top < cam_z.min() and cam_z.max() < lowest_world
        np.testing.assert_array_equal(d.sensordata, -1.0)  # no hit: nothing but the floor


@pytest.mark.parametrize("k", [1, 5, 8])
def test_rays_per_sensor_sets_the_rangefinder_cameras(k: int) -> None:
    bot = Robotino(rays_per_sensor=k)
    for sensor in bot.rangefinders:
        assert tuple(sensor.camera.resolution) == (k, 1)
        assert sensor.camera.fovy == pytest.approx(cone_fovy(k))
    model = mjcf.Physics.from_mjcf_model(bot.mjcf_model).model
    assert model.nsensor == 9 and model.nsensordata == 9 * k
