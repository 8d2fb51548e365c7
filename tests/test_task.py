"""The navigation task through its dm_env interface: sensing, termination, determinism."""

import math

import numpy as np
import pytest
from dm_env import test_utils

from nirl_mj import make_env
from nirl_mj.sim import spec
from nirl_mj.sim.drive import BODY_RADIUS
from nirl_mj.sim.task import Outcome

FORWARD, LEFT60, BACKWARD = 0, 2, 5


def scene(obstacles=(), start=(10.0, 50.0), yaw=0.0, target=(90.0, 50.0), **control):
    """An arena with only the given obstacles; the robot at ``start`` facing ``yaw`` degrees."""
    return spec.from_dict(
        {
            "arena": {
                "static_obstacles": 0,
                "start": list(start),
                "start_yaw": yaw,
                "target": list(target),
                "obstacles": [dict(o) for o in obstacles],
            },
            "control": control,
        },
        "test scene",
    )


def first_observation(task_spec):
    env = make_env(task_spec, seed=0)
    return env, env.reset().observation


class NavigationConformanceTest(test_utils.EnvironmentTestMixin):
    def make_object_under_test(self):
        return make_env(spec.replace(spec.load_task("navigate"), control={"step_budget": 8}), seed=3)


def test_dm_env_conformance():
    # EnvironmentTestMixin is unittest-based; run its checks through pytest.
    import unittest

    suite = unittest.defaultTestLoader.loadTestsFromTestCase(
        type("Conformance", (NavigationConformanceTest, unittest.TestCase), {})
    )
    result = unittest.TextTestRunner(verbosity=0).run(suite)
    assert result.wasSuccessful(), result.failures + result.errors


def test_observations_have_the_documented_names_and_shapes():
    env = make_env("navigate", seed=0)
    obs = env.reset().observation
    shapes = {k: np.shape(v) for k, v in obs.items()}
    assert shapes["features"] == (16,)
    assert shapes["ranges"] == (9,)
    assert shapes["pose"] == (3,)
    assert shapes["target"] == (2,)
    np.testing.assert_allclose(obs["pose"][:2], [10, 10], atol=1e-3)
    assert obs["pose"][2] == pytest.approx(math.pi / 4, abs=1e-3)  # facing the target
    np.testing.assert_array_equal(obs["target"], [90, 90])
    assert env.action_spec().num_values == 6


def test_box_in_front_gives_the_documented_danger_level():
    # Front face 3.0 m from the robot centre: clearance 2.775 m -> band (2.775 - 1) / (4/6) = 2.66 -> level 4.
    box = {"shape": "box", "position": [13.5, 50.0], "size": [0.5, 1.0]}
    _, obs = first_observation(scene([box]))
    assert obs["ranges"][0] == pytest.approx(3.0 - BODY_RADIUS, abs=0.01)
    assert obs["danger"][0] == 4
    assert obs["wall"][0] == 0
    assert obs["features"][0] == 4 and obs["features"][9] == 0  # D_S1, U_S1
    # The box spans +-18.4 degrees: S2 and S9 (cones 20..60 degrees off) see nothing.
    assert obs["danger"][1] == 0 and obs["danger"][8] == 0
    np.testing.assert_array_equal(obs["features"][1:7], 0)


@pytest.mark.parametrize(("distance", "level"), [(1.1, 7), (1.8, 6), (4.0, 2), (6.0, 0)])
def test_danger_level_follows_the_clearance(distance, level):
    box = {"shape": "box", "position": [10.0 + distance + 0.5, 50.0], "size": [0.5, 1.0]}
    _, obs = first_observation(scene([box]))
    assert obs["danger"][0] == level


def test_border_wall_sets_the_wall_flag():
    _, obs = first_observation(scene(start=(3.0, 50.0), yaw=180.0))
    assert obs["ranges"][0] == pytest.approx(3.0 - BODY_RADIUS, abs=0.01)
    assert obs["danger"][0] == 4
    assert obs["wall"][0] == 1 and obs["features"][9] == 1


def test_explicit_wall_segment_is_a_wall_and_a_box_is_not():
    wall = {"shape": "wall", "position": [13.5, 50.0], "size": [2.0, 0.25], "yaw": 90.0}
    _, obs = first_observation(scene([wall]))
    assert obs["wall"][0] == 1 and obs["danger"][0] > 0


def test_target_region_and_indicator():
    _, obs = first_observation(scene(target=(10.0, 53.0)))  # 3 m to the left: 90 degrees
    assert obs["features"][7] == 3  # sector of S3 (80 +- 20 degrees)
    assert obs["features"][8] == 1
    _, obs = first_observation(scene(target=(90.0, 50.0)))  # straight ahead, 80 m away
    assert obs["features"][7] == 1 and obs["features"][8] == 0
    blocker = {"shape": "box", "position": [10.0, 51.5], "size": [1.0, 0.2]}
    _, obs = first_observation(scene([blocker], target=(10.0, 53.0)))
    assert obs["features"][7] == 3 and obs["features"][8] == 0  # in range, but not in line of sight


def rollout(env, actions):
    timestep = env.reset()
    poses = [timestep.observation["pose"].copy()]
    for a in actions:
        timestep = env.step(a)
        poses.append(timestep.observation["pose"].copy())
        if timestep.last():
            break
    return timestep, np.array(poses)


def test_same_seed_same_arena_and_trajectory_other_seed_other_arena():
    actions = [FORWARD, LEFT60, FORWARD, 3, 4, FORWARD, BACKWARD, FORWARD] * 2
    a, b, c = (make_env("dynamic", seed=s) for s in (7, 7, 8))
    _, pa = rollout(a, actions)
    _, pb = rollout(b, actions)
    _, pc = rollout(c, actions)
    assert a.task.layout == b.task.layout
    np.testing.assert_array_equal(pa, pb)
    assert a.task.layout != c.task.layout


def test_terminates_on_target():
    env = make_env(scene(target=(14.0, 50.0)), seed=0)
    timestep, _ = rollout(env, [FORWARD] * 10)
    assert timestep.last()
    assert timestep.observation["outcome"] == Outcome.TARGET
    assert timestep.discount == 0.0 and timestep.reward > 1.0
    assert timestep.observation["target_distance"] <= 1.0 + 0.05


def test_terminates_on_collision():
    box = {"shape": "box", "position": [14.0, 50.0], "size": [0.5, 2.0]}
    env = make_env(scene([box]), seed=0)
    timestep, poses = rollout(env, [FORWARD] * 10)
    assert timestep.last()
    assert timestep.observation["outcome"] == Outcome.COLLISION
    assert timestep.discount == 0.0 and timestep.reward < 0.0
    # Stopped at the box face (x = 13.5), not through it.
    assert poses[-1][0] == pytest.approx(13.5 - BODY_RADIUS, abs=0.1)


def test_terminates_on_step_budget():
    env = make_env(scene(step_budget=3), seed=0)
    timestep, poses = rollout(env, [FORWARD] * 10)
    assert len(poses) == 4
    assert timestep.last() and timestep.observation["outcome"] == Outcome.TIMEOUT
    assert timestep.discount == 1.0


def test_physics_divergence_ends_the_episode_as_a_counted_failure():
    env = make_env(scene(), seed=0)
    env.reset()
    env.physics.data.qvel[:] = np.nan
    timestep = env.step(FORWARD)
    assert timestep.last()
    assert timestep.observation["outcome"] == Outcome.PHYSICS_ERROR
    assert timestep.discount == 0.0
    assert env.reset().observation["outcome"] == Outcome.RUNNING  # and the run goes on


@pytest.mark.parametrize("action", [6, -1, 2.5, "0", np.array([0, 1])])
def test_action_outside_0_to_5_is_a_clear_error(action):
    env = make_env(scene(), seed=0)
    env.reset()
    with pytest.raises(ValueError, match="action must be one integer in 0..5"):
        env.step(action)


def test_unknown_task_is_a_clear_error():
    with pytest.raises(spec.SpecError, match="unknown task 'nope'"):
        make_env("nope")


@pytest.mark.parametrize("camera", ["robotino/chase", "robotino/top"])
def test_headless_render_shows_the_robot(camera):
    env = make_env("navigate", seed=0)
    env.reset()
    physics = env.physics
    frame = physics.render(120, 160, camera_id=camera)
    assert frame.shape == (120, 160, 3) and frame.std() > 0
    segmentation = physics.render(120, 160, camera_id=camera, segmentation=True)
    robot_root = physics.bind(env.task.robot.base_body).rootid
    geom_ids = segmentation[..., 0][segmentation[..., 1] == 5]  # mjOBJ_GEOM
    robot_geoms = physics.model.body_rootid[physics.model.geom_bodyid[geom_ids]] == robot_root
    assert robot_geoms.sum() > 20  # pixels of the robot


@pytest.mark.parametrize("speed", [1.0, 2.0])
def test_default_env_drives_as_commanded(speed):
    """Through the real action path at the default (auto) timestep: forward speed within
    2 %, heading within 1 degree; each turn by its angle within 3 degrees; backward."""
    task = spec.replace(scene(start=(20.0, 50.0)), control={"speed": speed})
    assert task.physics_timestep == 0.01
    _, poses = rollout(make_env(task, seed=0), [FORWARD] * 8)
    measured = (poses[-1][0] - poses[-3][0]) / (2 * task.control.decision_period)
    assert measured == pytest.approx(speed, rel=0.02)
    assert abs(math.degrees(poses[-1][2])) < 1.0
    for action, angle in [(1, 30), (2, 60), (3, -30), (4, -60)]:
        _, poses = rollout(make_env(task, seed=0), [FORWARD] * 4 + [action, FORWARD])
        assert math.degrees(poses[-1][2] - poses[-3][2]) == pytest.approx(angle, abs=3.0)
    _, poses = rollout(make_env(task, seed=0), [BACKWARD] * 4)
    assert poses[-1][0] < poses[0][0] - 1.0


def test_drive_fidelities_agree_through_the_env():
    actions = [0, 1, 0, 2, 0, 0, 3, 4, 0, 5, 5, 0, 1, 1, 0, 3, 0, 2, 4, 0]
    ends = {}
    for drive in ("tyre", "rollers", "planar"):
        task = spec.replace(scene(start=(20.0, 50.0)), robot={"drive": drive})
        _, poses = rollout(make_env(task, seed=0), actions)
        ends[drive] = poses[-1]
    travelled = math.hypot(ends["planar"][0] - 20.0, ends["planar"][1] - 50.0)
    for drive in ("tyre", "rollers"):
        gap = math.hypot(*(ends[drive][:2] - ends["planar"][:2]))
        assert gap < 0.05 * travelled, (drive, gap, travelled)


def test_unchecked_decisions_are_the_same_physics_step_for_step(monkeypatch):
    # Far from everything, decisions run as one mj_step call per command change;
    # checking every command period instead must give the very same trajectory.
    actions = [FORWARD, LEFT60, FORWARD, 3, BACKWARD, FORWARD, 4, FORWARD]
    for drive in ("tyre", "planar"):
        task = spec.replace(scene(start=(20.0, 50.0)), robot={"drive": drive})
        _, fast = rollout(make_env(task, seed=0), actions)
        with monkeypatch.context() as m:
            m.setattr("nirl_mj.sim.task.NavigationTask._nothing_within_reach", lambda self: False)
            _, checked = rollout(make_env(task, seed=0), actions)
        np.testing.assert_array_equal(fast, checked)


@pytest.mark.parametrize("delayed", [False, True])
def test_observations_are_composers_own(monkeypatch, delayed):
    # nirl_mj.sim.environment plans the observation schedule directly for plain observables;
    # composer's general updater must see the same observations, dtypes and shapes, and
    # a delayed observable must fall back to composer's path.
    from dm_control import composer

    def observations(env):
        if delayed:
            env.task.observables["pose"].delay = 1
        rng = np.random.default_rng(1)
        seen = [env.reset().observation]
        ends = 0
        while len(seen) < 40:
            ts = env.step(np.int64(rng.integers(6)))
            seen.append(ts.observation)
            if ts.last():
                ends += 1
                seen.append(env.reset().observation)
        assert ends >= 2  # resets after an episode's end are compared too
        return seen, env.observation_spec()

    task = spec.replace(
        spec.load_task("navigate"), arena={"static_obstacles": 30}, control={"step_budget": 12}
    )
    ours, our_spec = observations(make_env(task, seed=5))
    monkeypatch.setattr("nirl_mj.sim.task.Environment", composer.Environment)
    theirs, their_spec = observations(make_env(task, seed=5))
    assert our_spec == their_spec
    for a, b in zip(ours, theirs, strict=True):
        assert a.keys() == b.keys()
        for key in a:
            assert np.asarray(a[key]).dtype == np.asarray(b[key]).dtype, key
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
