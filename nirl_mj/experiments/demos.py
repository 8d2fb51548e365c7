"""Collecting demonstrations, serially or over processes, with identical results.

Episode i of a collection seeded S runs in the arena of
``rollout.episode_seed(S, i)`` with a freshly reset expert, so an episode does
not depend on which process ran it or what ran before it.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass

from nirl_mj.data.trajectory import Trajectory
from nirl_mj.experiments.seeds import episode_seed
from nirl_mj.experts import make_expert
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.spec import TaskSpec


@dataclass(frozen=True)
class ExpertConfig:
    """Which demonstrator, and its noise if ``kind`` is ``"noisy"``."""

    kind: str = "sensor"
    base: str = "sensor"
    slip: float = 0.1
    random: float = 0.05
    seed: int = 0


def default_workers() -> int:
    """All cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


class _Runner:
    """One environment and one expert, re-used for many episodes."""

    def __init__(self, task: TaskSpec, expert: ExpertConfig, seed: int) -> None:
        from nirl_mj.sim.task import make_env

        self.env = make_env(task)
        self.expert = make_expert(**asdict(expert))
        self.seed = seed

    def __call__(self, episode: int) -> tuple[int, Trajectory]:
        return episode, run_episode(self.env, self.expert, episode_seed(self.seed, episode))


_worker_runner: _Runner | None = None


def _init_worker(task: TaskSpec, expert: ExpertConfig, seed: int) -> None:
    global _worker_runner
    _worker_runner = _Runner(task, expert, seed)


def _run_in_worker(episode: int) -> tuple[int, Trajectory]:
    return _worker_runner(episode)


def collect(
    task: TaskSpec,
    expert: ExpertConfig,
    episodes: int,
    seed: int,
    workers: int = 1,
    on_episode: Callable[[Trajectory], None] | None = None,
) -> list[Trajectory]:
    """Runs ``episodes`` demonstrations; ``on_episode`` is called as each one finishes
    in episode order; the result is the same whatever ``workers`` is."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    make_expert(**asdict(expert))  # a bad configuration fails here, not in a worker
    results: dict[int, Trajectory] = {}
    if workers == 1 or episodes == 1:
        runner = _Runner(task, expert, seed)
        jobs = map(runner, range(episodes))
        for i, trajectory in jobs:
            results[i] = trajectory
            if on_episode:
                on_episode(trajectory)
    else:
        # spawn: a fresh interpreter per worker, no inherited MuJoCo or GL state.
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(
            min(workers, episodes),
            mp_context=context,
            initializer=_init_worker,
            initargs=(task, expert, seed),
        ) as pool:
            for i, trajectory in pool.map(_run_in_worker, range(episodes)):
                results[i] = trajectory
                if on_episode:
                    on_episode(trajectory)
    return [results[i] for i in range(episodes)]
