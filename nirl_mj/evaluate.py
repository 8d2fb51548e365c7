"""The evaluation protocol: a policy on held-out arenas, success and its companions.

Arena seeds come from disjoint domains: demonstrations use
``rollout.episode_seed(seed, i)``; training, validation and test arenas use
:func:`domain_seed` with their own domain word, and an evaluation refuses test
seeds that a run has seen (the sets are stored in the run directory).

SPL (success weighted by path length) = (1/N) sum_i S_i L_i / max(L_i, P_i),
with P_i the path driven and L_i the straight-line distance from start to the
target's rim: a lower bound of the shortest path, so this SPL errs low.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import dm_env
import numpy as np

from nirl_mj.rollout import PolicyAgent, path_length, run_episode
from nirl_mj.trajectory import Trajectory

DOMAINS = {"train": 101, "validation": 102, "test": 103}


def domain_seed(domain: str, seed: int, index: int) -> int:
    """Arena seed ``index`` of ``domain`` ("train", "validation" or "test") for run seed ``seed``."""
    return int(np.random.SeedSequence([DOMAINS[domain], seed, index]).generate_state(1)[0])


def domain_seeds(domain: str, seed: int, count: int, start: int = 0) -> list[int]:
    return [domain_seed(domain, seed, i) for i in range(start, start + count)]


def held_out_seeds(seed: int, count: int, seen: set[int]) -> list[int]:
    """``count`` test-arena seeds of ``seed``, skipping any arena in ``seen``."""
    seeds, i = [], 0
    while len(seeds) < count:
        s = domain_seed("test", seed, i)
        i += 1
        if s not in seen:
            seeds.append(s)
    return seeds


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
