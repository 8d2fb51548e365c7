"""How episodes ended: outcome rates, evaluation metrics and dataset summaries.

:func:`outcome_rates` is the one place rates are computed from outcomes; the
learner's per-iteration metrics, :func:`metrics_of` (an evaluation) and
:func:`summarise` (``nirl-mj inspect``/``rollout``) all use it.

SPL (success weighted by path length, Anderson et al. 2018) =
(1/N) sum_i S_i L_i / max(L_i, P_i), with P_i the path driven and L_i the
straight-line distance from start to the target's rim: a lower bound of the
shortest path, so this SPL errs low.

SCT (success weighted by completion time, Yokoyama et al. 2021) =
(1/N) sum_i S_i C_i / max(C_i, T_i), with T_i the episode's duration (seconds,
decisions times the decision period) and C_i = L_i / v the time of that
straight line at the commanded speed v: a lower bound of the fastest
completion. SPL does not see time spent turning or backing off on the spot;
SCT does.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from nirl_mj.data.features import ACTION_NAMES, N_ACTIONS
from nirl_mj.data.trajectory import Trajectory, path_length, task_json

RATE_KEYS = {
    "target": "success_rate",
    "collision": "collision_rate",
    "timeout": "timeout_rate",
    "physics_error": "physics_error_rate",
}
"""Outcome (:data:`nirl_mj.data.trajectory.OUTCOMES`) -> the key of its rate, in that order."""


def outcome_rates(outcomes: Iterable[str]) -> dict[str, float]:
    """The fraction of episodes (0..1) that ended each way, keyed by :data:`RATE_KEYS`'s
    values (``success_rate`` first); all 0.0 for no episodes."""
    counts = Counter(outcomes)
    n = counts.total()
    return {key: counts[outcome] / n if n else 0.0 for outcome, key in RATE_KEYS.items()}


def shortest_length(trajectory: Trajectory) -> float:
    """L: the straight-line distance (metres) from the episode's start to the target's rim, a lower
    bound of the shortest path (never below 1e-9)."""
    start, target = trajectory.poses[0, :2], np.asarray(trajectory.task["arena"]["target"])
    return max(float(np.hypot(*(target - start))) - trajectory.task["arena"]["target_radius"], 1e-9)


def duration(trajectory: Trajectory) -> float:
    """T: how long the episode lasted, seconds."""
    return float(trajectory.times[-1] - trajectory.times[0])


def spl(trajectories: Sequence[Trajectory]) -> float:
    """Success weighted by path length (module docstring), 0..1; needs one trajectory at least."""
    total = 0.0
    for t in trajectories:
        if t.success:
            shortest = shortest_length(t)
            total += shortest / max(shortest, path_length(t))
    return total / len(trajectories)


def sct(trajectories: Sequence[Trajectory]) -> float:
    """Success weighted by completion time (module docstring), 0..1; needs one trajectory at least."""
    total = 0.0
    for t in trajectories:
        if t.success:
            fastest = shortest_length(t) / t.speed
            total += fastest / max(fastest, duration(t))
    return total / len(trajectories)


def metrics_problem(value: Any) -> str | None:
    """Why ``value`` (a stored result, or anything holding evaluations' metrics in its dicts and lists)
    is not what :func:`metrics_of` writes: a rate or SPL/SCT that is not a number in [0, 1], or a test
    count below 1; None if every metrics dict in it is sound."""
    if isinstance(value, list):
        return next((p for v in value if (p := metrics_problem(v))), None)
    if not isinstance(value, dict):
        return None
    if "success_rate" in value:
        for key in (*RATE_KEYS.values(), "spl", *(["sct"] if "sct" in value else [])):
            v = value.get(key)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 <= v <= 1.0:
                return f"{key} = {v!r}: not a fraction in [0, 1]"
        tests = value.get("tests")
        if isinstance(tests, bool) or not isinstance(tests, int) or tests < 1:
            return f"tests = {tests!r}: not a count >= 1"
        return None
    return next((p for v in value.values() if (p := metrics_problem(v))), None)


def holds_metrics(value: Any) -> bool:
    """Whether ``value`` is, or holds in its dicts and lists, an evaluation's metrics."""
    if isinstance(value, list):
        return any(holds_metrics(v) for v in value)
    return isinstance(value, dict) and (
        "success_rate" in value or any(holds_metrics(v) for v in value.values())
    )


def metrics_of(trajectories: list[Trajectory]) -> dict:
    """An evaluation's metrics: outcome rates, mean path length (metres), SPL, SCT and the
    number of episodes (``tests``)."""
    return {
        **outcome_rates(t.outcome for t in trajectories),
        "mean_path_length": float(np.mean([path_length(t) for t in trajectories])),
        "spl": spl(trajectories),
        "sct": sct(trajectories),
        "tests": len(trajectories),
    }


def summarise(trajectories: Sequence[Trajectory]) -> dict[str, Any]:
    """Summary of a dataset for ``nirl-mj inspect``: outcome rates (fractions), steps per
    episode (decisions), the action histogram, episodes per demonstrator and per
    speed (m/s), number of distinct tasks. Continuous actions have no histogram (its
    counts are empty): ``action_kind`` ``"continuous"`` and ``mean_action``, the mean
    shares of the forward speed, of the yaw rate and of its size, say how they drove."""
    n = len(trajectories)
    steps = np.array([len(t) for t in trajectories], dtype=np.int64)
    counts = np.zeros(N_ACTIONS, dtype=np.int64)
    continuous = {}
    if any(t.action_kind == "continuous" for t in trajectories):
        shares = np.concatenate([t.actions for t in trajectories]).astype(np.float64)
        mean = shares.mean(axis=0) if len(shares) else np.zeros(2)
        continuous = {"action_kind": "continuous", "mean_action": {
            "forward": float(mean[0]), "yaw_rate": float(mean[1]),
            "abs_yaw_rate": float(np.abs(shares[:, 1]).mean()) if len(shares) else 0.0}}  # fmt: skip
        counts = np.zeros(0, dtype=np.int64)
        names: Sequence[str] = ()
        total = len(shares)
    else:
        for t in trajectories:
            counts += np.bincount(t.actions, minlength=N_ACTIONS)
        names = ACTION_NAMES
        total = int(counts.sum())
    return {
        "episodes": n,
        **outcome_rates(t.outcome for t in trajectories),
        "pairs": total,
        "mean_steps": float(steps.mean()) if n else 0.0,
        "min_steps": int(steps.min()) if n else 0,
        "max_steps": int(steps.max()) if n else 0,
        "action_counts": {name: int(c) for name, c in zip(names, counts, strict=True)},
        "action_fractions": {
            name: (float(c) / total if total else 0.0) for name, c in zip(names, counts, strict=True)
        },
        **continuous,
        "demonstrators": dict(sorted(Counter(t.demonstrator for t in trajectories).items())),
        "speeds": dict(sorted(Counter(t.speed for t in trajectories).items())),
        "tasks": len({task_json(t.task) for t in trajectories}),
    }
