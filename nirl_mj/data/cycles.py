"""The repeating cycle of actions an episode ends in.

A greedy policy on phi(s) has no memory: once it meets a state it met before, in the same
configuration, it repeats itself until the episode times out. Such an end shows as a periodic tail of
discrete actions (forward, backward, forward, ... in front of an obstacle; a turn repeated on an orbit
around the target). This finds that tail, so a run's timeouts can be told apart: a cycle on the spot
against slow progress.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nirl_mj.data.trajectory import Trajectory


@dataclass(frozen=True)
class Cycle:
    """A periodic tail of an episode's discrete actions.

    ``actions``: the last ``period`` action indices, in order; ``length``: decisions in the tail
    (at least two periods); ``radius``: metres, the largest distance of the robot's positions over
    the tail (its length + 1 poses, the final one included) from their mean, how far the cycle
    strays; ``states``: phi(s) at each decision of the last period, shape (period, 16).
    """

    actions: tuple[int, ...]
    length: int
    radius: float
    states: np.ndarray

    @property
    def period(self) -> int:
        return len(self.actions)


def final_cycle(trajectory: Trajectory, max_period: int = 12, min_length: int = 24) -> Cycle | None:
    """The period p <= ``max_period`` that explains the longest tail of at least two periods of the
    actions (a[i] = a[i - p] for every decision i of the tail after its first period), the shortest
    such p on a tie; None when there is none, when that tail is shorter than ``min_length``
    decisions, or when the actions are continuous."""
    if max_period < 1 or min_length < 2:
        raise ValueError(
            f"final_cycle: expected max_period >= 1 and min_length >= 2, got {max_period}, {min_length}"
        )
    a = np.asarray(trajectory.actions)
    if a.ndim != 1:
        return None
    best_p, best_len = 0, 0
    for p in range(1, min(max_period, len(a) - 1) + 1):
        same = a[p:] == a[:-p]  # same[i] says a[i + p] == a[i]
        run = len(same) - (np.flatnonzero(~same)[-1] + 1) if not same.all() else len(same)
        if run >= p and run + p > best_len:  # a period counts once its tail holds two of it
            best_p, best_len = p, run + p
    if best_p == 0 or best_len < min_length:
        return None
    positions = np.asarray(trajectory.poses)[len(a) - best_len :, :2]
    radius = float(np.linalg.norm(positions - positions.mean(axis=0), axis=1).max())
    states = np.asarray(trajectory.features)[len(a) - best_p : len(a)]
    return Cycle(tuple(int(x) for x in a[-best_p:]), int(best_len), radius, states)
