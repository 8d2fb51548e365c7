"""PlannerExpert: reaches the target, steers around obstacles, backs out of dead ends, deterministic.

Episodes use the ``planar`` drive (same kinematics as ``tyre``, several times
faster) and small arenas where the point is a single situation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import nirl_mj
from nirl_mj.experiments.seeds import episode_seed
from nirl_mj.experts.planner import PlannerExpert, arc_model, cost_field
from nirl_mj.sim import spec as task_spec
from nirl_mj.sim.drive import BODY_RADIUS
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.layout import Layout, Obstacle


def run(env, expert: PlannerExpert, seed: int = 0) -> tuple[str, list[int], np.ndarray]:
    """One episode: (outcome name, actions, poses (T + 1, 3) in m/rad)."""
    trajectory = run_episode(env, expert, seed)
    return trajectory.outcome, trajectory.actions.tolist(), trajectory.poses


def small_arena(
    obstacles: list[dict], start=(5.0, 15.0), start_yaw=0.0, target=(25.0, 15.0)
) -> task_spec.TaskSpec:
    """A 30 m x 30 m arena with only the given explicit obstacles, planar drive, 2 m/s."""
    return task_spec.from_dict(
        {
            "arena": {
                "size": [30.0, 30.0],
                "start": list(start),
                "target": list(target),
                "start_yaw": start_yaw,
                "static_obstacles": 0,
                "obstacles": obstacles,
            },
            "robot": {"drive": "planar"},
        }
    )


@pytest.fixture(scope="module")
def navigate_env():
    spec = task_spec.replace(task_spec.load_task("navigate"), robot={"drive": "planar"})
    return nirl_mj.make_env(spec, seed=0)


def test_reaches_the_target_in_seeded_arenas(navigate_env):
    expert = PlannerExpert()
    for i in range(3):
        outcome, actions, _ = run(navigate_env, expert, episode_seed(0, i))
        assert outcome == "target", (i, outcome, len(actions))
        # The straight line is ~113 decisions of 1 m; the plan should not wander far off it.
        assert len(actions) < 160


def test_same_seed_same_actions(navigate_env):
    seed = episode_seed(0, 5)
    _, first, _ = run(navigate_env, PlannerExpert(), seed)
    # A fresh expert, and the first one again after another episode in between.
    expert = PlannerExpert()
    _, second, _ = run(navigate_env, expert, seed)
    run(navigate_env, expert, episode_seed(0, 6))
    _, third, _ = run(navigate_env, expert, seed)
    assert first == second == third


def test_steers_around_an_obstacle_on_the_straight_line():
    radius = 2.0
    spec = small_arena([{"shape": "cylinder", "position": [15.0, 15.0], "size": [radius]}])
    env = nirl_mj.make_env(spec, seed=0)
    outcome, actions, poses = run(env, PlannerExpert())
    assert outcome == "target"
    gap = np.hypot(poses[:, 0] - 15.0, poses[:, 1] - 15.0) - radius - BODY_RADIUS
    assert gap.min() > 0.1
    # It went around, i.e. turned off the straight line.
    assert np.abs(poses[:, 1] - 15.0).max() > radius
    assert any(a in (1, 2, 3, 4) for a in actions)


def u_pocket(x_open: float, x_closed: float, y_low: float, y_high: float) -> list[dict]:
    """Three wall segments (0.5 m thick) forming a pocket open towards -x, closed at ``x_closed``."""
    length = x_closed - x_open
    mid = 0.5 * (x_open + x_closed)
    return [
        {"shape": "wall", "position": [mid, y_low], "size": [length / 2, 0.25]},
        {"shape": "wall", "position": [mid, y_high], "size": [length / 2, 0.25]},
        {
            "shape": "wall",
            "position": [x_closed, 0.5 * (y_low + y_high)],
            "size": [(y_high - y_low) / 2 + 0.25, 0.25],
            "yaw": 90.0,
        },
    ]


def test_does_not_drive_into_a_dead_end_ahead():
    # A 3 m wide pocket 2 m ahead, opening towards the robot, the target behind it.
    spec = small_arena(u_pocket(7.0, 11.0, 13.5, 16.5))
    env = nirl_mj.make_env(spec, seed=0)
    outcome, _, poses = run(env, PlannerExpert())
    assert outcome == "target"
    # Never deep inside the pocket.
    inside = (poses[:, 0] > 8.5) & (poses[:, 0] < 11.0) & (np.abs(poses[:, 1] - 15.0) < 1.5)
    assert not inside.any()


def test_backs_out_of_a_dead_end_it_faces():
    # The robot starts inside a 2.5 m wide pocket, 1 m from its closed end: too
    # narrow to turn at speed, so it must back out before it can go round.
    spec = small_arena(u_pocket(3.0, 8.0, 13.75, 16.25), start=(6.5, 15.0))
    env = nirl_mj.make_env(spec, seed=0)
    outcome, actions, poses = run(env, PlannerExpert())
    assert outcome == "target", outcome
    assert 5 in actions[:4]
    # It left through the opening (x < 3) before going round.
    assert poses[:, 0].min() < 3.0


def test_arc_model_matches_the_action_geometry():
    model = arc_model(2.0, 0.5, 0.01, 4.0)
    # Steady forward drive: the state after an action 0 from rest, then action 0 again.
    _, cruising, _ = model.segment(model.zero_state, 0)
    _, cruising, _ = model.segment(cruising, 0)
    straight, _, vx = model.segment(cruising, 0)
    assert straight[-1, 0] == pytest.approx(1.0, abs=1e-6) and abs(straight[-1, 1]) < 1e-9
    assert vx == pytest.approx(2.0)
    left, _, _ = model.segment(cruising, 2)
    assert left[-1, 2] == pytest.approx(math.radians(60.0), abs=1e-6)
    assert left[-1, 1] > 0.2
    back, _, vx = model.segment(cruising, 5)
    # Braking from 2 m/s takes ~0.43 s and ~0.43 m; the robot is still ahead afterwards.
    assert 0.3 < back[-1, 0] < 0.6 and vx < 0.0
    # Every sequence starts with one of the six actions; braking follows each.
    table = model.table(cruising)
    assert sorted(set(table.first.tolist())) == list(range(6))
    assert table.poses.shape[0] == 36 and table.poses.shape[1] > table.end + 1


def test_cost_field_is_the_distance_in_an_open_arena_and_grows_into_obstacles():
    layout = Layout((30.0, 30.0), (5.0, 5.0), 0.0, (25.0, 25.0))
    field = cost_field(layout, 0.325)
    x = np.array([5.0, 15.0, 25.0])
    # Clearance weighting only adds cost near walls: in the middle ~the straight distance.
    value = field(x, x)
    assert value[2] <= 1.0  # zero at the centre of the target cell (1 m)
    assert value[1] == pytest.approx(math.hypot(10.0, 10.0), rel=0.1)
    assert value[0] > value[1]
    blocked = Layout((30.0, 30.0), (5.0, 5.0), 0.0, (25.0, 25.0), (Obstacle("cylinder", 15.0, 15.0, (3.0,)),))
    around = cost_field(blocked, 0.325)
    assert around(np.array([15.0]), np.array([15.0]))[0] > value[1] + 2.0
    assert around(np.array([5.0]), np.array([5.0]))[0] > value[0]
