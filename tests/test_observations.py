"""Every observation is a bounded rank-1 array with its real range (nirl_mj.sim.observations)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from dm_env import specs as dm_specs

from nirl_mj.sim import spec
from nirl_mj.sim.observations import NAMES, arena_pose, feature_bounds, yaw_limit
from nirl_mj.sim.task import make_env


def _task(**control):
    return spec.replace(spec.load_task("navigate"), arena={"static_obstacles": 30}, control=control)


def test_every_observation_spec_is_bounded_finite_and_rank_one():
    env = make_env(_task(step_budget=12), seed=0)
    obs_spec = env.observation_spec()
    assert tuple(obs_spec) == NAMES
    for name, s in obs_spec.items():
        assert isinstance(s, dm_specs.BoundedArray), name
        assert len(s.shape) == 1, name
        assert np.all(np.isfinite(s.minimum)) and np.all(np.isfinite(s.maximum)), name
        assert np.all(s.minimum < s.maximum), name
    for name in ("danger", "wall", "outcome", "steps"):
        assert np.issubdtype(obs_spec[name].dtype, np.integer), name
    assert obs_spec["steps"].maximum[0] == 12
    assert obs_spec["pose"].maximum.tolist() == [100.0, 100.0, math.pi]
    assert obs_spec["rays"].shape == (45,)


@pytest.mark.parametrize("drive", ["tyre", "planar"])
def test_observations_of_random_episodes_lie_within_their_specs(drive):
    task = spec.replace(_task(step_budget=40), robot={"drive": drive})
    env = make_env(task, seed=3)
    obs_spec = env.observation_spec()
    rng = np.random.default_rng(0)
    ts, seen = env.reset(), 0
    while seen < 120:
        for name, s in obs_spec.items():
            value = ts.observation[name]
            assert value.shape == s.shape and value.dtype == s.dtype, name
            s.validate(value)  # raises if out of bounds
        ts = env.step(np.int64(rng.integers(6)))
        seen += 1
        if ts.last():
            ts = env.reset()


def test_feature_bounds_follow_the_layout():
    low, high = feature_bounds()
    assert low.tolist() == [0] * 7 + [1, 0] + [0] * 7
    assert high.tolist() == [7] * 7 + [9, 1] + [1] * 7


def test_arena_pose_clips_to_the_arena_and_leaves_poses_inside_untouched():
    inside = np.array([3.25, 7.5, 1.0000000000000002])
    assert arena_pose(inside, 10.0, 10.0).tobytes() == inside.tobytes()
    assert arena_pose(np.array([-2.0, 12.0, 5.0]), 10.0, 10.0).tolist() == [0.0, 10.0, 5.0]


def test_yaw_is_within_pi_for_free_bodies_and_accumulates_for_the_planar_drive():
    task = _task(step_budget=10)
    assert yaw_limit(task) == math.pi
    planar = spec.replace(task, robot={"drive": "planar"})
    assert yaw_limit(planar) == pytest.approx(math.pi + 10 * math.pi / 2)
    env = make_env(spec.replace(planar, arena={"static_obstacles": 0}), seed=0)
    ts = env.reset()
    for _ in range(8):  # 8 x 60 degrees left, in an empty arena
        ts = env.step(np.int64(2))
    assert ts.observation["pose"][2] > math.pi  # continuous, not wrapped
    env.observation_spec()["pose"].validate(ts.observation["pose"])


def test_close_twice_is_harmless():
    env = make_env(_task(step_budget=3), seed=0)
    env.reset()
    env.close()
    env.close()
