"""Collecting demonstrations as experiment cells, serially or over processes, with identical results.

Episode i of a collection seeded S runs in the arena of ``seeds.episode_seed(S, i)``
with a freshly reset expert, so an episode does not depend on which process ran it
or what ran before it. Each episode is one cell of an
:class:`~nirl_mj.experiments.executors.Executor` (serial for one worker, local
processes for more): the same executors and process pool as every experiment, without
retries. A cell writes its trajectory as a one-episode dataset in a scratch
directory (cell results travel as JSON; a dataset file keeps every array exact).
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from nirl_mj.data.dataset import load_dataset, save_dataset
from nirl_mj.data.lock import process_folder
from nirl_mj.data.trajectory import Trajectory
from nirl_mj.experiments.executors import Cell, Executor, Failure
from nirl_mj.experiments.seeds import episode_seed
from nirl_mj.experts import DEMONSTRATORS, EXPERT_KINDS, Expert, demonstrator_names, make_expert
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.spec import TaskSpec

SCRATCH = "nirl-mj-demos-"
"""The prefix of a collection's scratch folder in the temporary directory, followed by its process id."""


@dataclass(frozen=True)
class ExpertConfig:
    """Which demonstrator, its noise if ``kind`` is ``"noisy"``, and its delay in decisions (0: none,
    :class:`nirl_mj.experts.late.LateExpert`)."""

    kind: str = "sensor"
    base: str = "sensor"
    slip: float = 0.1
    random: float = 0.05
    seed: int = 0
    delay: int = 0

    @classmethod
    def named(cls, name: str, seed: int = 0) -> ExpertConfig:
        """The demonstrator ``name`` (an expert kind or a ``nirl_mj.experts.DEMONSTRATORS`` name)."""
        if name in DEMONSTRATORS:
            return cls(**DEMONSTRATORS[name], seed=seed)
        if name not in EXPERT_KINDS:
            raise ValueError(f"unknown demonstrator {name!r}: accepted: {', '.join(demonstrator_names())}")
        return cls(name, seed=seed)

    def build(self) -> Expert:
        """A fresh demonstrator of this configuration."""
        fields = asdict(self)
        delay = fields.pop("delay")
        expert = make_expert(**fields)
        if delay:
            from nirl_mj.experts.late import LateExpert

            expert = LateExpert(expert, delay)
        return expert


class _Runner:
    """One environment and one expert, re-used for many episodes of one collection."""

    def __init__(self, task: TaskSpec, expert: ExpertConfig) -> None:
        from nirl_mj.sim.task import make_env

        self.key = (task, expert)
        self.env = make_env(task)
        self.expert = expert.build()


_runner: _Runner | None = None  # this process's, kept between the cells of one collection


def demo_cell(task: TaskSpec, expert: ExpertConfig, seed: int, episode: int, folder: str) -> str:
    """Records demonstration ``episode`` of the collection seeded ``seed`` into ``folder``;
    returns the one-episode dataset's path."""
    global _runner
    if _runner is None or _runner.key != (task, expert):
        _runner = _Runner(task, expert)
    trajectory = run_episode(_runner.env, _runner.expert, episode_seed(seed, episode))
    path = Path(folder) / f"episode-{episode:06d}.npz"
    save_dataset(path, [trajectory], overwrite=True)  # a retried cell writes its episode again
    return str(path)


def collect(
    task: TaskSpec,
    expert: ExpertConfig,
    episodes: int,
    seed: int,
    workers: int = 1,
    on_episode: Callable[[Trajectory], None] | None = None,
) -> list[Trajectory]:
    """Runs ``episodes`` demonstrations on ``workers`` processes (this one for 1); ``on_episode``
    is called as each one finishes; the result, in episode order, is the same whatever ``workers`` is."""
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    expert.build()  # a bad configuration fails here, not in a worker
    done: dict[str, Trajectory] = {}

    def arrived(cell_id: str, path: Any, failure: Failure | None) -> None:
        if failure is not None:
            raise RuntimeError(f"demonstration {cell_id} failed: {failure.error}")
        done[cell_id] = load_dataset(path)[0]
        if on_episode:
            on_episode(done[cell_id])

    folder = process_folder(tempfile.gettempdir(), SCRATCH)  # those of killed collections go
    try:
        cells = [
            Cell(f"demo-{i:06d}", demo_cell, (task, expert, seed, i, str(folder))) for i in range(episodes)
        ]
        executor = "serial" if workers == 1 or episodes == 1 else "local"
        with Executor(executor, min(workers, episodes), retries=0) as runner:
            runner.run(cells, on_done=arrived)
        return [done[cell.id] for cell in cells]
    finally:
        shutil.rmtree(folder, ignore_errors=True)
