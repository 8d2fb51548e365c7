"""The sensor-limited demonstrator on short planar-drive episodes.

Everything runs with the planar drive (same kinematics as the tyre drive,
several times faster) so the whole file stays well under a minute.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import nirl_mj
from nirl_mj.experiments.seeds import episode_seed
from nirl_mj.experts.sensor import SensorExpert
from nirl_mj.sim import spec as task_spec
from nirl_mj.sim.drive import BODY_RADIUS
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import Outcome

SENSING_RANGE = 5.0  # metres from the outline, the default of tasks/navigate.toml


def _planar(spec: task_spec.TaskSpec) -> task_spec.TaskSpec:
    return task_spec.replace(spec, robot={"drive": "planar"})


def _scene(*obstacles: dict) -> task_spec.TaskSpec:
    """The default arena with no random obstacles, only ``obstacles`` (ObstacleSpec tables)."""
    return task_spec.from_dict(
        {
            "arena": {"static_obstacles": 0, "obstacles": list(obstacles)},
            "robot": {"drive": "planar"},
        }
    )


def _drive(env, expert: SensorExpert, seed: int) -> tuple[list[int], np.ndarray, Outcome]:
    """One episode: the actions, the poses (T + 1, 3) before each action and at the end, the outcome."""
    trajectory = run_episode(env, expert, seed)
    return trajectory.actions.tolist(), trajectory.poses, Outcome[trajectory.outcome.upper()]


@pytest.fixture(scope="module")
def navigate_env():
    return nirl_mj.make_env(_planar(task_spec.load_task("navigate")), seed=0)


@pytest.mark.parametrize("episode", [0, 1, 2, 3])
def test_reaches_the_target_in_seeded_arenas(navigate_env, episode):
    _, _, outcome = _drive(navigate_env, SensorExpert(), episode_seed(0, episode))
    assert outcome == Outcome.TARGET


def test_same_seed_same_actions(navigate_env):
    # One expert reused (reset must forget the previous episode) and a fresh one.
    reused = SensorExpert()
    first, _, _ = _drive(navigate_env, reused, episode_seed(0, 5))
    _drive(navigate_env, reused, episode_seed(0, 6))
    again, _, _ = _drive(navigate_env, reused, episode_seed(0, 5))
    fresh, _, _ = _drive(navigate_env, SensorExpert(), episode_seed(0, 5))
    assert first == again == fresh


def test_reset_reads_only_the_timestep(navigate_env):
    navigate_env.random_state.seed(episode_seed(0, 0))
    timestep = navigate_env.reset()
    expert = SensorExpert()
    expert.reset(None, timestep)  # no environment at all: nothing is read from it
    assert expert.act(timestep) in range(6)
    assert not any(value is navigate_env for value in vars(expert).values())


def test_decisions_ignore_an_obstacle_beyond_the_sensing_range():
    # The same scene twice, the second with one more obstacle on the way,
    # far from the start: until the robot's rays can reach that obstacle the
    # two runs must decide exactly alike.
    near = {"shape": "cylinder", "position": [30.0, 28.0], "size": [2.0]}
    hidden_xy, hidden_radius = np.array([65.0, 65.0]), 2.5
    hidden = {"shape": "cylinder", "position": hidden_xy.tolist(), "size": [hidden_radius]}
    runs = []
    for spec in (_scene(near), _scene(near, hidden)):
        env = nirl_mj.make_env(spec, seed=0)
        runs.append(_drive(env, SensorExpert(), seed=1))
    (actions_a, poses_a, outcome_a), (actions_b, poses_b, outcome_b) = runs
    assert outcome_a == outcome_b == Outcome.TARGET
    # Steps whose pose is farther from the hidden obstacle than the rays reach
    # (range from the outline plus the body radius, plus a small margin).
    gap = np.hypot(*(poses_b[:-1, :2] - hidden_xy).T) - hidden_radius
    out_of_range = gap > SENSING_RANGE + BODY_RADIUS + 0.05
    first_in_range = int(np.argmin(out_of_range))
    assert first_in_range > 20, "the hidden obstacle must start out of range for the test to mean anything"
    assert actions_a[:first_in_range] == actions_b[:first_in_range]
    # Once seen it matters: the runs part (the hidden obstacle lies on the straight line).
    assert actions_a != actions_b


def test_avoids_a_single_obstacle_on_the_straight_line():
    centre, radius = np.array([50.0, 50.0]), 3.0
    env = nirl_mj.make_env(
        _scene({"shape": "cylinder", "position": centre.tolist(), "size": [radius]}), seed=0
    )
    _, poses, outcome = _drive(env, SensorExpert(), seed=0)
    assert outcome == Outcome.TARGET
    clearance = np.hypot(*(poses[:, :2] - centre).T) - radius - BODY_RADIUS
    assert clearance.min() > 0.2
    # It went round, not through: the path left the start-target line by more than the obstacle's radius.
    offset = np.abs(poses[:, 0] - poses[:, 1]) / math.sqrt(2.0)
    assert offset.max() > radius


def test_ordinary_decisions_are_the_rule_on_phi():
    # The scores behind ordinary decisions pick exactly what rule_policy picks
    # on phi(s), backing off when it rules every arc out.
    from nirl_mj.experts.policies import rule_policy, rule_scores

    rng = np.random.default_rng(0)
    for _ in range(2000):
        phi = np.zeros(16)
        phi[:7] = rng.integers(0, 8, 7)
        phi[7] = rng.integers(1, 10)
        scores = rule_scores(phi)
        action = 5 if np.all(np.isinf(scores)) else int(np.argmin(scores))
        assert action == rule_policy(phi)


def test_follows_the_rule_on_phi_almost_always(navigate_env):
    # Learners see only phi(s): away from the rare escapes and memory vetoes
    # the expert must do what the rule on phi(s) does.
    from nirl_mj.experts.policies import rule_policy

    expert = SensorExpert()
    agree = total = 0
    for episode in (0, 1):
        navigate_env.random_state.seed(episode_seed(0, episode))
        timestep = navigate_env.reset()
        expert.reset(navigate_env, timestep)
        while not timestep.last():
            action = expert.act(timestep)
            agree += action == rule_policy(timestep.observation["features"])
            total += 1
            timestep = navigate_env.step(action)
    assert agree / total > 0.95


def test_escapes_a_pocket_facing_the_target():
    # A U-shaped pocket of boxes opening away from the target, right on the
    # straight line: the rule alone would dither in front of its bottom.
    pocket = (
        {"shape": "box", "position": [50.0, 50.0], "size": [0.5, 6.0], "yaw": 45.0},
        {"shape": "box", "position": [42.93, 51.41], "size": [4.0, 0.5], "yaw": 45.0},
        {"shape": "box", "position": [51.41, 42.93], "size": [4.0, 0.5], "yaw": 45.0},
    )
    env = nirl_mj.make_env(_scene(*pocket), seed=0)
    _, _, outcome = _drive(env, SensorExpert(), seed=0)
    assert outcome == Outcome.TARGET
