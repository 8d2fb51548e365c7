"""Shared pieces of the learning tests: the open arena the short runs learn in, and their measure."""

import numpy as np

from nirl_mj.data.trajectory import Trajectory
from nirl_mj.sim import spec

# An open arena (no obstacle inside the walls) the rule expert crosses in ~28 decisions: short runs
# of every learner reach the target there, and a uniform random policy does not.
OPEN = spec.replace(
    spec.load_task("navigate"),
    arena={"size": (30.0, 30.0), "start": (5.0, 5.0), "target": (25.0, 25.0), "static_obstacles": 0},
    robot={"drive": "planar"},
)


# The tables of a tiny experiment file: a 30 m arena with 3 obstacles on the planar drive, episodes of
# ~30 decisions, 2 demonstrations; seconds per cell, big enough that the policies differ.
TINY_TABLES = """
[set.arena]
size = [30.0, 30.0]
start = [5.0, 5.0]
target = [25.0, 25.0]
static_obstacles = 3
[set.robot]
drive = "planar"
[demos]
episodes = 2
"""
TINY_CONFIG = """[config]
episodes = 1
trajectories_per_episode = 2
validation_arenas = 2
"""
"""NIRL's 1 iteration of 2 rollouts, for the tiny experiments."""


def progress(trajectories: list[Trajectory]) -> float:
    """Mean share of the start-to-target distance covered by the end of each episode (1: arrived)."""
    shares = []
    for t in trajectories:
        target = np.asarray(t.task["arena"]["target"])
        start, end = (np.hypot(*(t.poses[i, :2] - target)) for i in (0, -1))
        shares.append(1.0 if t.success else (start - end) / start)
    return float(np.mean(shares))


def sleeping_cell(pid_file: str) -> int:
    """An executor cell that writes its process id to ``pid_file`` and then sleeps (for ever, as far
    as a test goes): the worker an executor test kills the parent of."""
    import os
    import time

    with open(pid_file, "w") as f:
        f.write(str(os.getpid()))
    time.sleep(600)
    return 0
