"""The evaluation protocol: a policy on held-out arenas, success and its companions.

Arena seeds come from disjoint domains: demonstrations use
``seeds.episode_seed``; training, validation and test arenas use
``seeds.domain_seed`` with their own domain word, and an evaluation refuses test
seeds that a run has seen (``nirl_mj.experiments.seeds``). The metrics (success
rate and its companions, SPL) are :func:`nirl_mj.data.outcomes.metrics_of`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import dm_env
import numpy as np

from nirl_mj.data.outcomes import metrics_of
from nirl_mj.data.trajectory import Trajectory
from nirl_mj.experts.policies import PolicyAgent
from nirl_mj.sim.episode import Agent, run_episode
from nirl_mj.sim.rollouts import Rollouts


def evaluate(
    env: dm_env.Environment | None,
    policy: Callable[[np.ndarray], int] | Agent,
    seeds: Iterable[int],
    name: str = "policy",
    on_episode: Callable[[Trajectory], None] | None = None,
    rollouts: Rollouts | None = None,
) -> tuple[dict, list[Trajectory]]:
    """Runs the (greedy) ``policy`` on phi(s), or an Agent (an expert), once in each arena; returns
    metrics and trajectories. On a task with continuous actions the policy answers with the two
    shares in [-1, 1] (or a discrete action, driven as its twin: ``sim.episode.run_episode``).
    ``rollouts`` runs them on another backend (:mod:`nirl_mj.sim.rollouts`; then ``env`` is unused
    and ``on_episode`` is called once they all ended)."""
    agent = policy if hasattr(policy, "act") else PolicyAgent(policy, name)
    if env is None and rollouts is None:
        raise ValueError("evaluate needs an environment (the cpu backend) or rollouts (another backend)")
    if rollouts is not None:
        trajectories = rollouts(agent, list(seeds))
        for trajectory in trajectories:
            if on_episode:
                on_episode(trajectory)
        return metrics_of(trajectories), trajectories
    trajectories = []
    for seed in seeds:
        trajectories.append(run_episode(env, agent, seed))
        if on_episode:
            on_episode(trajectories[-1])
    return metrics_of(trajectories), trajectories
