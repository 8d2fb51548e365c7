"""The robot's memory of its rays (nirl_mj/sim/memory.py) and the task's ``sensing.guide = "memory"``."""

from __future__ import annotations

import math

import numpy as np
import pytest

import nirl_mj
from nirl_mj.data import features
from nirl_mj.experts.policies import POLICIES, PolicyAgent
from nirl_mj.experts.sensor import SensorExpert
from nirl_mj.sim import spec as task_spec
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.memory import RayMemory

RANGE = 5.0
NOTHING_SEEN = np.full(45, RANGE)  # 9 sensors x 5 rays, every reading capped at the range

# A U-shaped pocket of boxes opening away from the target (90, 90), right on the straight line
# from the start (10, 10): a memoryless rule on phi dithers in front of its bottom.
POCKET = (
    {"shape": "box", "position": [50.0, 50.0], "size": [0.5, 6.0], "yaw": 45.0},
    {"shape": "box", "position": [42.93, 51.41], "size": [4.0, 0.5], "yaw": 45.0},
    {"shape": "box", "position": [51.41, 42.93], "size": [4.0, 0.5], "yaw": 45.0},
)


def _pocket_task(guide: str) -> task_spec.TaskSpec:
    return task_spec.from_dict(
        {
            "arena": {"static_obstacles": 0, "obstacles": list(POCKET)},
            "robot": {"drive": "planar"},
            "sensing": {"guide": guide},
        }
    )


def test_stuck_after_stuck_steps_decisions_without_progress_and_free_after_a_metre():
    memory = RayMemory(stuck_steps=10)
    memory.reset(np.array([0.0, 0.0, 0.0]), np.array([10.0, 0.0]), NOTHING_SEEN)
    for _ in range(10):  # decisions 0..9 at 10 m: the best distance was set at decision 0
        memory.update(np.array([0.0, 0.0]), 0.0, NOTHING_SEEN)
        assert not memory.escaping
    memory.update(np.array([0.0, 0.0]), 0.0, NOTHING_SEEN)  # decision 10: 10 decisions without 0.5 m
    assert memory.escaping
    memory.update(np.array([0.9, 0.0]), 0.0, NOTHING_SEEN)  # 9.1 m: not 1 m closer than 10 m yet
    assert memory.escaping
    memory.update(np.array([1.1, 0.0]), 0.0, NOTHING_SEEN)  # 8.9 m: free again
    assert not memory.escaping
    # progress of 0.5 m or more restarts the count
    for k in range(12):
        memory.update(np.array([1.1 + 0.6 * k, 0.0]), 0.0, NOTHING_SEEN)
        assert not memory.escaping


def test_escape_bearing_in_open_space_heads_for_the_target():
    # Nothing remembered: the cheapest way is the straight line, so the waypoint lies towards the
    # target, whatever the robot's heading (degrees counter-clockwise from its front).
    memory = RayMemory(stuck_steps=1)
    memory.reset(np.array([0.0, 0.0, 0.0]), np.array([20.0, 0.0]), NOTHING_SEEN)
    memory.update(np.array([0.0, 0.0]), math.pi / 2, NOTHING_SEEN)
    memory.update(np.array([0.0, 0.0]), math.pi / 2, NOTHING_SEEN)
    assert memory.escaping
    assert memory.escape_bearing(np.array([0.0, 0.0]), math.pi / 2) == pytest.approx(-90.0, abs=10.0)


def test_default_guide_keeps_the_task_identity():
    spec = task_spec.load_task("navigate")
    assert "guide" not in spec.to_dict()["sensing"]
    assert task_spec.replace(spec, sensing={"guide": "memory"}).to_dict()["sensing"]["guide"] == "memory"
    with pytest.raises(task_spec.SpecError, match="guide"):
        task_spec.replace(spec, sensing={"guide": "waypoint"})


class _Watched:
    """The sensor expert, recording per decision phi's V and where the expert's memory steered."""

    kind = "sensor"

    def __init__(self) -> None:
        self.expert, self.seen = SensorExpert(), []
        escape_bearing = self.expert._memory.escape_bearing

        def recorded(xy, yaw):
            self._bearing = escape_bearing(xy, yaw)
            return self._bearing

        self.expert._memory.escape_bearing = recorded

    def reset(self, env, timestep) -> None:
        self.expert.reset(env, timestep)

    def act(self, timestep) -> int:
        self._bearing = None
        action = self.expert.act(timestep)
        obs = timestep.observation
        target = features.target_region(float(obs["target_bearing"][0]))
        steer = target if self._bearing is None else features.target_region(math.radians(self._bearing))
        self.seen.append((int(obs["features"][7]), int(steer), self._bearing is not None))
        return action


def test_guide_memory_puts_the_experts_escape_waypoint_into_v():
    """With ``guide = "memory"`` the task's memory is the expert's, decision by decision: V is the
    target's sector until the expert escapes, and then the sector the expert steers for."""
    env = nirl_mj.make_env(_pocket_task("memory"), seed=0)
    watched = _Watched()
    trajectory = run_episode(env, watched, 0)
    assert trajectory.outcome == "target"
    v, steer, escaping = np.array(watched.seen).T
    assert escaping.sum() > 0  # the pocket made it escape
    np.testing.assert_array_equal(v, steer)


def test_the_rule_on_phi_leaves_a_pocket_only_with_the_memory_guide():
    rule = PolicyAgent(POLICIES["rule"], "rule")
    stuck = run_episode(nirl_mj.make_env(_pocket_task("target"), seed=0), rule, 0)
    guided = run_episode(nirl_mj.make_env(_pocket_task("memory"), seed=0), rule, 0)
    assert stuck.outcome != "target"
    assert guided.outcome == "target"


def test_the_main_jobs_report_names_the_memory_guide():
    from nirl_mj.experiments.main_job import _guide_note

    spec = task_spec.load_task("navigate")
    assert _guide_note(spec) == ""
    assert 'sensing.guide = "memory"' in _guide_note(task_spec.replace(spec, sensing={"guide": "memory"}))
