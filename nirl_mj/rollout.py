"""Running a policy for whole episodes, each in its own seeded arena."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import asdict, dataclass

import dm_env
import numpy as np

from nirl_mj.policies import Policy
from nirl_mj.task import Outcome


def episode_seed(seed: int, episode: int) -> int:
    """The arena seed of episode ``episode`` in a run seeded ``seed``: independent of
    the order in which episodes are run, so runs can be split across processes."""
    return int(np.random.SeedSequence([seed, episode]).generate_state(1)[0])


@dataclass(frozen=True)
class EpisodeResult:
    """Outcome of one episode: ``steps`` decisions, ``path_length`` metres travelled."""

    episode: int
    seed: int
    outcome: str
    steps: int
    path_length: float
    final_distance: float

    def to_dict(self) -> dict:
        return asdict(self)


def run_episode(env: dm_env.Environment, policy: Policy, seed: int, episode: int = 0) -> EpisodeResult:
    """Runs ``policy`` on phi(s) for one episode in the arena of ``seed``."""
    env.random_state.seed(seed)
    timestep = env.reset()
    xy = timestep.observation["pose"][:2].copy()
    length = 0.0
    while not timestep.last():
        timestep = env.step(policy(timestep.observation["features"]))
        new_xy = timestep.observation["pose"][:2]
        length += float(np.hypot(*(new_xy - xy)))
        xy = new_xy.copy()
    obs = timestep.observation
    return EpisodeResult(
        episode=episode,
        seed=seed,
        outcome=Outcome(int(obs["outcome"])).name.lower(),
        steps=int(obs["steps"]),
        path_length=length,
        final_distance=float(obs["target_distance"]),
    )


def run_episodes(
    env: dm_env.Environment, policy: Policy, seed: int, episodes: int
) -> Iterator[EpisodeResult]:
    """Yields the results of ``episodes`` episodes, episode i in the arena of ``episode_seed(seed, i)``."""
    for i in range(episodes):
        yield run_episode(env, policy, episode_seed(seed, i), i)


def summarise(results: list[EpisodeResult]) -> dict:
    """Success, collision, timeout and divergence rates (fractions) and mean steps."""
    n = len(results)
    count = {o.name.lower(): 0 for o in Outcome if o != Outcome.RUNNING}
    for r in results:
        count[r.outcome] += 1
    return {
        "episodes": n,
        "success_rate": count["target"] / n if n else 0.0,
        "collision_rate": count["collision"] / n if n else 0.0,
        "timeout_rate": count["timeout"] / n if n else 0.0,
        "physics_error_rate": count["physics_error"] / n if n else 0.0,
        "mean_steps": float(np.mean([r.steps for r in results])) if n else 0.0,
    }
