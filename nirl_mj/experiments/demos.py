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

from nirl_mj.data.atomic import write_text
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
    path = Path(folder) / _episode_file(episode)
    save_dataset(path, [trajectory], overwrite=True)  # a retried cell writes its episode again
    return str(path)


def collect(
    task: TaskSpec,
    expert: ExpertConfig,
    episodes: int,
    seed: int,
    workers: int = 1,
    on_episode: Callable[[Trajectory], None] | None = None,
    keep: str | Path | None = None,
    log: Callable[[str], None] | None = None,
) -> list[Trajectory]:
    """Runs ``episodes`` demonstrations on ``workers`` processes (this one for 1); ``on_episode``
    is called as each one finishes; the result, in episode order, is the same whatever ``workers`` is.

    ``keep``: a folder that keeps each finished episode (the caller removes it once the dataset is
    written), so that the same collection stopped part-way and started again records only the
    episodes it lacks (said through ``log``); one of another collection there is replaced."""
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

    if keep is None:
        folder = process_folder(tempfile.gettempdir(), SCRATCH)  # those of killed collections go
    else:
        folder = _kept_folder(Path(keep), task, expert, seed)
    try:
        cells = [
            Cell(f"demo-{i:06d}", demo_cell, (task, expert, seed, i, str(folder))) for i in range(episodes)
        ]
        todo = []
        for i, cell in enumerate(cells):
            path = folder / _episode_file(i)
            if keep is not None and path.is_file():  # written atomically: whole, or not there
                arrived(cell.id, path, None)
            else:
                todo.append(cell)
        if done and log:
            log(f"resumed: {len(done)} of {episodes} episodes were recorded in {folder}")
        executor = "serial" if workers == 1 or len(todo) == 1 else "local"
        if todo:
            with Executor(executor, min(workers, len(todo)), retries=0) as runner:
                runner.run(todo, on_done=arrived)
        return [done[cell.id] for cell in cells]
    finally:
        if keep is None:
            shutil.rmtree(folder, ignore_errors=True)


def kept_episodes_folder(out: str | Path) -> Path:
    """Where ``nirl-mj demos --out OUT`` keeps its finished episodes until OUT is written: a hidden
    folder beside OUT (under OUT's lock)."""
    out = Path(out)
    return out.parent / f".{out.name}.episodes"


def _episode_file(episode: int) -> str:
    return f"episode-{episode:06d}.npz"


def _kept_folder(folder: Path, task: TaskSpec, expert: ExpertConfig, seed: int) -> Path:
    """``folder`` for the collection (task, expert, seed), recorded by this code (a digest of
    nirl_mj's Python sources): kept if it holds that collection's episodes, emptied if another's."""
    import hashlib
    import json

    digest = hashlib.sha256(repr((task, expert, seed)).encode())
    package = Path(__file__).resolve().parents[1]
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes())
    identity = digest.hexdigest()
    marker = folder / "collection.json"
    try:
        same = json.loads(marker.read_text())["identity"] == identity
    except (OSError, ValueError, KeyError, TypeError):
        same = False
    if not same:
        ours = (".", "episode-", marker.name)  # its temporaries, episodes and marker
        names = [p.name for p in folder.iterdir()] if folder.is_dir() else [folder.name] * folder.exists()
        foreign = [n for n in names if not n.startswith(ours)]
        if foreign:
            raise FileExistsError(f"{folder} holds files no collection wrote ({', '.join(foreign[:3])}): "
                                  "move it aside, or choose another --out")  # fmt: skip
        shutil.rmtree(folder, ignore_errors=True)  # another collection's episodes
        folder.mkdir(parents=True)
        write_text(marker, json.dumps({"identity": identity, "seed": seed, "expert": asdict(expert)}))
    return folder
