"""The robot's nine MJCF rangefinders: in the standalone model, and ray for ray against the task's rays."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from nirl_mj.data import features
from nirl_mj.sim import sensing
from nirl_mj.sim import spec as specs
from nirl_mj.sim.drive import BODY_RADIUS
from nirl_mj.sim.task import make_env

SCENE = Path(__file__).resolve().parents[1] / "models" / "robotino" / "scene.xml"
PEN = 3.0  # m, inner half-width of scene.xml's pen of walls


def _scene_model(extra_geoms: tuple[dict, ...] = ()) -> tuple[mujoco.MjModel, mujoco.MjData]:
    spec = mujoco.MjSpec.from_file(str(SCENE))
    for geom in extra_geoms:
        spec.worldbody.add_geom(**geom)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def test_scene_has_nine_camera_rangefinders_that_see_the_world_only() -> None:
    model = mujoco.MjModel.from_xml_path(str(SCENE))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rangefinder = int(mujoco.mjtSensor.mjSENS_RANGEFINDER)
    assert model.nsensor == features.N_SENSORS
    assert [model.sensor(i).name for i in range(model.nsensor)] == [f"S{i}" for i in range(1, 10)]
    assert np.all(model.sensor_type == rangefinder)
    assert np.all(model.sensor_objtype == int(mujoco.mjtObj.mjOBJ_CAMERA))
    assert np.all(model.sensor_dim == 5) and model.nsensordata == 45
    # The robot stands in the middle of the pen: every ray reads the distance to the pen's
    # walls from the robot's axis, so none of them hits the robot (wheels included).
    angles = sensing.camera_ray_angles(5)
    expected = PEN / np.maximum(np.abs(np.cos(angles)), np.abs(np.sin(angles)))
    np.testing.assert_allclose(data.sensordata, expected, rtol=0, atol=1e-12)


def test_camera_rays_span_the_cone_close_to_the_task_rays() -> None:
    for k in range(1, 65):
        cam, task = sensing.camera_ray_angles(k), sensing.ray_angles(k)
        assert cam.shape == task.shape == (features.N_SENSORS * k,)
        # A pinhole spaces its rays equally in tangent: at most ~0.33 degrees from equal angles.
        assert np.max(np.abs(cam - task)) < math.radians(0.35)
        if k % 2:  # the centre ray is the sensor's direction in both
            centre = slice(k // 2, None, k)
            np.testing.assert_allclose(cam[centre], features.SENSOR_ANGLES, atol=1e-15)
        # fovy: a one-row image of k square pixels spans 40 degrees horizontally
        half_width = k * math.tan(math.radians(sensing.cone_fovy(k)) / 2)
        assert math.degrees(2 * math.atan(half_width)) == pytest.approx(40.0, abs=1e-9)
    assert sensing.ray_angles(1) == pytest.approx(sensing.camera_ray_angles(1), abs=1e-15)


def test_known_obstacle_at_known_distance() -> None:
    # A post of radius 0.2 m centred 1.5 m ahead: S1's centre ray meets it 1.3 m from the
    # robot's axis, a clearance of 1.3 - BODY_RADIUS from the outline, in both sensors.
    post = {"type": mujoco.mjtGeom.mjGEOM_CYLINDER, "size": [0.2, 0.25, 0], "pos": [1.5, 0, 0.25]}
    model, data = _scene_model((post,))
    assert data.sensordata[2] == pytest.approx(1.3, abs=1e-12)
    ids = np.arange(features.N_SENSORS)
    mjcf_rays = sensing.Rangefinders(model, ids, 5.0, BODY_RADIUS).read(data)
    origin = data.site_xpos[model.site("sensor_origin").id]
    walls = np.zeros(model.ngeom, bool)
    cast = sensing.RangeSensors(model, walls, 5, 5.0, BODY_RADIUS).scan(data, origin, 0.0, np.zeros(2))
    assert mjcf_rays[2] == pytest.approx(1.3 - BODY_RADIUS, abs=1e-12)
    assert cast.rays[2] == pytest.approx(1.3 - BODY_RADIUS, abs=1e-12)
    assert cast.ranges[0] == pytest.approx(1.3 - BODY_RADIUS, abs=1e-12)


def test_the_sensing_range_is_measured_from_the_robots_outline_for_obstacles_and_the_target() -> None:
    # 5.1, 5.2 and 5.3 m from the centre are 4.875, 4.975 and 5.075 m from the 0.225 m outline: the
    # first two within a 5 m range, the third beyond it (a miss, inf), though all three are 5 m+ away
    dist = np.array([5.1, 5.2, 5.3])
    rays = sensing._clearance(dist, np.ones(3, bool), 0.225, 5.0)
    np.testing.assert_allclose(rays, [4.875, 4.975, np.inf], rtol=1e-12)
    np.testing.assert_array_equal(sensing.target_sight(False, np.inf, dist, 0.225, 5.0), [True, True, False])


def test_rangefinders_reject_what_they_cannot_convert() -> None:
    model, _ = _scene_model()
    with pytest.raises(ValueError, match="shape"):
        sensing.Rangefinders(model, np.arange(3), 5.0, BODY_RADIUS)
    model.cam_pos[model.sensor_objid[0], 0] = 0.2  # a camera off the robot's axis
    with pytest.raises(ValueError, match="vertical axis"):
        sensing.Rangefinders(model, np.arange(9), 5.0, BODY_RADIUS)


def _crowded(drive: str, rays_per_sensor: int):
    return specs.replace(
        specs.load_task("navigate"),
        arena={
            "size": [24.0, 24.0],
            "start": [3.0, 3.0],
            "target": [21.0, 21.0],
            "clear_radius": 1.0,
            "static_obstacles": 25,
            "obstacle_size": [0.2, 1.5],
            "interior_walls": 3,
            "interior_wall_length": [2.0, 8.0],
            "moving_obstacles": 3,
        },
        robot={"drive": drive, "rays_per_sensor": rays_per_sensor},
    )


@pytest.mark.parametrize(("drive", "k"), [("tyre", 5), ("rollers", 3), ("planar", 7), ("tyre", 1)])
def test_rangefinders_agree_with_the_task_rays_ray_for_ray(drive: str, k: int) -> None:
    """Random arenas and poses: the MJCF rangefinders (cameras above the wheels, sensors computed
    on demand) read what RangeSensors casts along the same directions from the task's sensor
    origin, within floating point."""
    task_spec = _crowded(drive, k)
    env = make_env(task_spec, seed=7)
    task = env.task
    rng = np.random.default_rng(k)
    hinges = [j for j in task.robot.mjcf_model.find_all("joint") if j.name.startswith("wheel")]
    hits = 0
    for _ in range(4):
        env.reset()
        physics = env.physics
        model, data = physics.model.ptr, physics.data.ptr
        cast = sensing.RangeSensors(
            model,
            task._arena.wall_mask(physics),
            k,
            task_spec.sensing.range,
            BODY_RADIUS,
            angles=sensing.camera_ray_angles(k),
        )
        origin = data.site_xpos[model.site("robotino/sensor_origin").id]
        for _ in range(10):
            x, y = rng.uniform(1.0, 23.0, size=2)
            yaw = rng.uniform(-math.pi, math.pi)
            task.robot.set_pose(physics, x, y, yaw)
            if hinges:  # wheels (and rollers) at random angles
                physics.bind(hinges).qpos = rng.uniform(-math.pi, math.pi, size=len(hinges))
            mujoco.mj_forward(model, data)
            mjcf_rays = task.rangefinder_rays(physics)
            expected = cast.scan(data, origin, yaw, np.asarray(task.layout.target)).rays
            assert mjcf_rays.shape == (features.N_SENSORS * k,)
            np.testing.assert_array_equal(np.isfinite(mjcf_rays), np.isfinite(expected))
            np.testing.assert_allclose(mjcf_rays, expected, rtol=0, atol=1e-12)
            hits += int(np.isfinite(expected).sum())
    assert hits > 40 * features.N_SENSORS * k * 0.2  # not vacuous: a fifth of the rays see something


def test_task_compiles_the_rangefinders_disabled() -> None:
    task_spec = specs.replace(specs.load_task("navigate"), robot={"rays_per_sensor": 3})
    env = make_env(task_spec, seed=0)
    env.reset()
    model, data = env.physics.model.ptr, env.physics.data.ptr
    # The rangefinders are the model's only sensors, so disabling sensors skips exactly them.
    assert model.nsensor == features.N_SENSORS
    assert np.all(model.sensor_type == int(mujoco.mjtSensor.mjSENS_RANGEFINDER))
    assert model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
    assert np.all(model.cam_resolution[model.sensor_objid] == (3, 1))
    assert model.nsensordata == features.N_SENSORS * 3
    for _ in range(3):
        env.step(0)
    assert not data.sensordata.any()  # never computed by the physics steps
    rays = env.task.rangefinder_rays(env.physics)
    assert rays.shape == (features.N_SENSORS * 3,)
    assert model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_SENSOR)  # restored
