"""The evaluation protocol: a policy on held-out arenas, success and its companions.

Arena seeds come from disjoint domains: demonstrations use
``seeds.episode_seed``; training, validation and test arenas use
``seeds.domain_seed`` with their own domain word, and an evaluation refuses test
seeds that a run has seen (``nirl_mj.experiments.seeds``).

SPL (success weighted by path length) = (1/N) sum_i S_i L_i / max(L_i, P_i),
with P_i the path driven and L_i the straight-line distance from start to the
target's rim: a lower bound of the shortest path, so this SPL errs low.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import dm_env
import numpy as np

from nirl_mj.data.trajectory import Trajectory, path_length
from nirl_mj.experts.policies import PolicyAgent
from nirl_mj.sim.episode import run_episode


def metrics_of(trajectories: list[Trajectory]) -> dict:
    """success/collision/timeout rates, mean path length (metres) and SPL over trajectories."""
    n = len(trajectories)
    outcomes = [t.outcome for t in trajectories]
    spl = 0.0
    for t in trajectories:
        if t.success:
            start, target = t.poses[0, :2], np.asarray(t.task["arena"]["target"])
            shortest = max(float(np.hypot(*(target - start))) - t.task["arena"]["target_radius"], 1e-9)
            spl += shortest / max(shortest, path_length(t))
    return {
        "success_rate": outcomes.count("target") / n,
        "collision_rate": outcomes.count("collision") / n,
        "timeout_rate": outcomes.count("timeout") / n,
        "physics_error_rate": outcomes.count("physics_error") / n,
        "mean_path_length": float(np.mean([path_length(t) for t in trajectories])),
        "spl": spl / n,
        "tests": n,
    }


def evaluate(
    env: dm_env.Environment,
    policy: Callable[[np.ndarray], int],
    seeds: Iterable[int],
    name: str = "policy",
    on_episode: Callable[[Trajectory], None] | None = None,
) -> tuple[dict, list[Trajectory]]:
    """Runs the (greedy) ``policy`` on phi(s) once in each arena; returns metrics and trajectories."""
    agent = PolicyAgent(policy, name)
    trajectories = []
    for seed in seeds:
        trajectories.append(run_episode(env, agent, seed))
        if on_episode:
            on_episode(trajectories[-1])
    return metrics_of(trajectories), trajectories
