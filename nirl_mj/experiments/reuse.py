"""Cells finished in an earlier comparison, taken into a new one where they are the same computation.

An output directory holds one experiment identity (``nirl_mj.experiments.protocol``), so a change
of one method's defaults makes every cell of a comparison start again, although the cells of the
other methods would compute the same numbers. ``nirl-mj compare --reuse OLD`` copies such cells
from OLD (the cell's record and its training run directory) before anything runs. A cell of
method M and run r is taken only when all of these hold:

- OLD's identity equals the new one in every key but the method list and the learners' settings
  (task, test task, seed, tests, expert, demonstrations, config, sweep axes);
- OLD's demonstrations hold the same arrays;
- M does not train and OLD holds M with the same definition; or M is a trained learner and OLD
  holds a method with the same resolved learner settings (which name the variant, the algorithm
  and every setting), of M's name (preferred) or another, as when a named variant became the
  default: the cell is taken under M's name;
- run r's test arenas in OLD (held out from everything OLD's trainable methods may see) are the
  new run's test arenas.

What this cannot see is a change in the code itself: it trusts that the same settings compute the
same numbers, as resuming an output directory does. Each copied cell records where it came from
(``reused_from``, and ``reused_as`` when it was OLD's cell of another name).
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

from nirl_mj.experiments.definition import Experiment, ExperimentError
from nirl_mj.experiments.protocol import EXPERIMENT_FILE, RunJob, run_seed

SHARED_KEYS = ("kind", "task", "test_task", "seed", "tests", "expert", "demos", "config", "obstacles",
               "speeds")  # fmt: skip
"""Identity keys OLD must share with the new experiment for any of its cells to be taken."""


def same_arrays(a: Path, b: Path) -> bool:
    """Whether two ``.npz`` files hold the same arrays under the same names."""
    with np.load(a, allow_pickle=False) as x, np.load(b, allow_pickle=False) as y:
        return sorted(x.files) == sorted(y.files) and all(np.array_equal(x[k], y[k]) for k in x.files)


def old_test_seeds(saved: dict, seed: int, tests: int, demo_seeds: set[int]) -> list[int]:
    """The test arenas OLD gave the run of training seed ``seed``: held out from its demonstrations
    and from every arena its trainable methods (``saved["learners"]``) may see."""
    from nirl_mj.experiments.seeds import held_out_seeds
    from nirl_mj.experiments.training import planned_seeds
    from nirl_mj.learn.config import LearnerConfig

    seen = set(demo_seeds)
    for flat in saved.get("learners", {}).values():
        seen |= planned_seeds(LearnerConfig.from_dict(flat), seed)
    return held_out_seeds(seed, tests, seen)


def read_old(old: str | Path, experiment: Experiment) -> tuple[Path, dict]:
    """OLD (absolute) and its saved identity; a clear error if OLD is not an experiment's output
    directory with demonstrations, or differs from ``experiment`` in a shared key. Called before
    the new output directory is made, so a wrong OLD costs nothing."""
    old = Path(old).resolve()
    marker = old / EXPERIMENT_FILE
    if not marker.is_file() or not (old / "demos.npz").is_file():
        raise ExperimentError(f"--reuse {old}: holds no nirl-mj experiment with demonstrations")
    try:
        saved = json.loads(marker.read_text())
    except json.JSONDecodeError as exc:
        raise ExperimentError(f"--reuse {old}: {marker} is corrupted ({exc})") from None
    identity = experiment.identity()
    differ = [k for k in SHARED_KEYS if saved.get(k) != identity.get(k)]
    if differ:
        raise ExperimentError(f"--reuse {old}: another experiment (it differs in: {', '.join(differ)}); "
                              "only methods and learner settings may differ")  # fmt: skip
    return old, saved


def copy_run(source: Path, target: Path) -> None:
    """``source`` copied to ``target`` (which must not exist) through a temporary sibling, so a
    killed copy leaves no half-copied run where a run is looked for."""
    temporary = target.with_name(f".{target.name}.reuse-tmp")
    shutil.rmtree(temporary, ignore_errors=True)  # left by a killed copy
    shutil.copytree(source, temporary)
    os.replace(temporary, target)


def old_sources(
    name: str, old_methods: dict, new_methods: dict, old_learners: dict, new_learners: dict
) -> list[str]:
    """The methods of OLD whose cells are the new method ``name``'s computation, best first. A
    method that does not train: ``name`` with the same definition. A trained learner: every method
    of OLD with the same resolved learner settings (they name the variant, the algorithm and every
    setting), ``name`` first, then the others by name (a renamed variant)."""
    settings = new_learners.get(name)
    if settings is None:  # not a trained learner: its definition is what it computes
        return [name] if old_methods.get(name) == new_methods[name] else []
    candidates = dict.fromkeys([name, *sorted(old_learners)])  # ordered, without repeats
    return [m for m in candidates if old_learners.get(m) == settings]


def reuse_cells(
    old: str | Path,
    experiment: Experiment,
    out: Path,
    jobs: dict[tuple[str, int], RunJob],
    cell_id: Callable[[str, int], str],
    log: Callable[[str], None],
) -> list[str]:
    """Copies into ``out`` every cell of ``jobs`` that OLD finished as the same computation (the
    rules in the module doc) and ``out`` has not; returns their ids. A cell whose training run
    ``out`` already holds (an interrupted one) is left to be computed. A clear error if OLD is not
    an output directory that shares the experiment's keys."""
    from nirl_mj.data.atomic import write_text
    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.experiments.executors import CellStore

    old, saved = read_old(old, experiment)
    if old == out:
        raise ExperimentError(f"--reuse {old} is the output directory itself; give an earlier one")
    if not same_arrays(old / "demos.npz", out / "demos.npz"):
        raise ExperimentError(f"--reuse {old}: its demonstrations differ from {out / 'demos.npz'}")
    identity = experiment.identity()
    old_methods = {m["name"]: m for m in saved.get("methods", [])}
    new_methods = {m["name"]: m for m in identity["methods"]}
    old_learners, new_learners = saved.get("learners", {}), identity["learners"]
    demo_seeds = {t.arena_seed for t in load_dataset(out / "demos.npz")}
    source, target = CellStore(old / "cells"), CellStore(out / "cells")
    taken, tests_match = [], {}
    sources = {
        name: old_sources(name, old_methods, new_methods, old_learners, new_learners) for name in new_methods
    }
    for (name, run), job in jobs.items():
        ident = cell_id(name, run)
        found = [m for m in sources[name] if source.load(cell_id(m, run)) is not None]
        if not found or target.load(ident) is not None:
            continue
        source_name = found[0]
        if run not in tests_match:
            seeds = old_test_seeds(saved, run_seed(experiment, run), experiment.tests, demo_seeds)
            tests_match[run] = seeds == list(job.test_seeds)
        old_run, new_run = old / "runs" / source_name / str(job.seed), Path(job.run_dir)
        if not tests_match[run] or new_run.exists():
            continue
        if old_run.is_dir():
            copy_run(old_run, new_run)
        record = json.loads(source.path(cell_id(source_name, run)).read_text())
        record = {k: v for k, v in record.items() if k != "reused_as"}  # OLD's own provenance is OLD's
        record.update(id=ident, result={**record["result"], "method": name}, reused_from=str(old))
        if source_name != name:
            record["reused_as"] = source_name
        target.directory.mkdir(parents=True, exist_ok=True)
        write_text(target.path(ident), json.dumps(record, indent=1))
        taken.append(ident)
    log(f"reuse: {len(taken)} finished cells taken from {old}")
    return taken
