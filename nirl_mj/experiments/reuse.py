"""Cells finished in an earlier comparison, taken into a new one where they are the same computation.

An output directory holds one experiment identity (``nirl_mj.experiments.protocol``), so a change
of one method's defaults makes every cell of a comparison start again, although the cells of the
other methods would compute the same numbers. ``nirl-mj compare --reuse OLD`` copies such cells
from OLD (the cell's record and its training run directory; a cell that reads another method's
training run, ``protocol.training_owners``, has none of its own: its record alone) before anything
runs. A cell of method M and run r is taken only when all of these hold:

- OLD's identity equals the new one in every key of :data:`SHARED_KEYS` (task, test task, seed,
  tests, expert, demonstrations, sweep axes, test domain): not the method list, the learners'
  settings or the experiment's ``[config]``, whose effect is in each learner's settings (below);
- OLD's demonstrations hold the same arrays (drawn per run: the run's own; a run OLD has no
  demonstrations for is left to be computed);
- M is not one of NIRL's loop's learners (a Stable-Baselines3 row, BC, a reference) and OLD holds a
  method with M's definition but for its name (M's own preferred: the cell is taken under M's
  name); or M is a trained learner and OLD
  holds a method with the same resolved learner settings that it reads (the algorithm and every
  setting of the loop and of its own reward step: ``LearnerConfig.settings_read``), of M's name
  (preferred) or another, as when a named variant became the default: the cell is taken under M's
  name;
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
from nirl_mj.experiments.protocol import (
    EXPERIMENT_FILE,
    RunJob,
    cell_problem,
    demos_path,
    resolved_learners,
    run_seed,
)

SHARED_KEYS = ("kind", "task", "test_task", "seed", "tests", "expert", "demos", "obstacles", "speeds",
               "test_domain", "demos_per_run")  # fmt: skip
"""Identity keys OLD must share with the new experiment for any of its cells to be taken. Not the
experiment's learner ``config``: each learner's resolved settings are compared instead
(:func:`method_sources`), so a file that pins an old default in its ``[config]`` still matches."""


def same_arrays(a: Path, b: Path) -> bool:
    """Whether two ``.npz`` files hold the same arrays under the same names."""
    with np.load(a, allow_pickle=False) as x, np.load(b, allow_pickle=False) as y:
        return sorted(x.files) == sorted(y.files) and all(np.array_equal(x[k], y[k]) for k in x.files)


def old_test_seeds(saved: dict, seed: int, tests: int, demo_seeds: set[int]) -> list[int]:
    """The test arenas OLD gave the run of training seed ``seed``: held out from its demonstrations
    and from every arena its trainable methods (``saved["learners"]``) may see."""
    from nirl_mj.experiments.seeds import held_out_seeds
    from nirl_mj.experiments.training import planned_seeds
    from nirl_mj.learn.config import RETIRED, LearnerConfig

    seen = set(demo_seeds)
    for flat in saved.get("learners", {}).values():
        # a retired setting (a reward transform, a weight average) never chose an arena
        current = {k: v for k, v in flat.items() if k not in RETIRED}
        seen |= planned_seeds(LearnerConfig.from_record(current), seed)
    return held_out_seeds(seed, tests, seen, saved.get("test_domain", "test"))


def read_old(old: str | Path, experiment: Experiment) -> tuple[Path, dict]:
    """OLD (absolute) and its saved identity; a clear error if OLD is not an experiment's output
    directory with demonstrations, or differs from ``experiment`` in a shared key. Called before
    the new output directory is made, so a wrong OLD costs nothing."""
    old = Path(old).resolve()
    marker = old / EXPERIMENT_FILE
    if not marker.is_file() or not demos_path(old, experiment, 0).is_file():
        raise ExperimentError(f"--reuse {old}: holds no nirl-mj experiment with demonstrations")
    try:
        saved = json.loads(marker.read_text())
    except json.JSONDecodeError as exc:
        raise ExperimentError(f"--reuse {old}: {marker} is corrupted ({exc})") from None
    check_shared(saved, experiment, f"--reuse {old}")
    return old, saved


def saved_form(experiment: Experiment) -> dict:
    """``experiment``'s identity as it reads back from its saved JSON (tuples as lists), so that it
    compares equal with a saved identity wherever the two are the same."""
    return json.loads(json.dumps(experiment.identity()))


def check_shared(saved: dict, experiment: Experiment, where: str) -> None:
    """A clear error (starting with ``where``) unless the saved identity equals ``experiment``'s in
    every shared key (:data:`SHARED_KEYS`)."""
    identity = saved_form(experiment)
    differ = [k for k in SHARED_KEYS if saved.get(k) != identity.get(k)]
    if differ:
        raise ExperimentError(f"{where}: another experiment (it differs in: {', '.join(differ)}); "
                              "only methods and learner settings may differ")  # fmt: skip


def copy_run(source: Path, target: Path) -> None:
    """``source`` copied to ``target`` (which must not exist) through a temporary sibling, so a
    killed copy leaves no half-copied run where a run is looked for."""
    temporary = target.with_name(f".{target.name}.reuse-tmp")
    shutil.rmtree(temporary, ignore_errors=True)  # left by a killed copy
    shutil.copytree(source, temporary)
    os.replace(temporary, target)


def method_sources(saved: dict, experiment: Experiment) -> dict[str, list[str]]:
    """For each method of ``experiment``, the methods of the saved experiment whose cells are its
    computation, best first. A method that is not one of the loop's learners (a Stable-Baselines3
    row, BC, a reference): every saved method with the same definition but for its name (its seed is
    the run's, its name a label), its own name first, then the others by name. A learner of the loop:
    every saved method with the same resolved learner settings that it reads (the algorithm and the
    settings of the loop and of its step), its own name first, then the others by name (a renamed
    variant)."""
    from nirl_mj.learn.config import LearnerConfig

    identity = saved_form(experiment)
    old_methods = {m["name"]: m for m in saved.get("methods", [])}
    # what each learner reads: a changed default of a step that does not run changes no number;
    # a learner with a retired setting computes nothing this version can, so it is no source
    old_learners = {n: LearnerConfig.from_dict(f).settings_read()
                    for n, f in resolved_learners(saved, skip_retired=True).items()}  # fmt: skip
    sources = {}
    for method in identity["methods"]:
        name, settings = method["name"], identity["learners"].get(method["name"])
        if settings is None:  # not a trained learner: its definition, the name aside, is what it computes
            twins = [m for m in old_methods if {**old_methods[m], "name": name} == method]
            sources[name] = sorted(twins, key=lambda m: (m != name, m))
        else:
            settings = LearnerConfig.from_dict(settings).settings_read()
            candidates = dict.fromkeys([name, *sorted(old_learners)])  # ordered, without repeats
            sources[name] = [m for m in candidates if old_learners.get(m) == settings]
    return sources


def same_tests(saved: dict, experiment: Experiment, out: Path) -> Callable[[RunJob], bool]:
    """A check of whether the saved experiment gave a job's run the job's test arenas (computed
    once per run: the runs of one seed share them), held out from the run's demonstrations in
    ``out``."""
    from nirl_mj.data.dataset import load_dataset

    known: dict[int, bool] = {}

    def check(job: RunJob) -> bool:
        if job.run not in known:
            demo_seeds = {t.arena_seed for t in load_dataset(demos_path(out, experiment, job.run))}
            seeds = old_test_seeds(saved, run_seed(experiment, job.run), experiment.tests, demo_seeds)
            known[job.run] = seeds == list(job.test_seeds)
        return known[job.run]

    return check


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
    from nirl_mj.experiments.executors import CellStore

    old, saved = read_old(old, experiment)
    if old == out:
        raise ExperimentError(f"--reuse {old} is the output directory itself; give an earlier one")
    runs = sorted({run for _, run in jobs})
    if not experiment.demos_per_run:
        runs = runs[:1]  # one set of demonstrations for every run
    shared = [r for r in runs if demos_path(old, experiment, r).is_file()]  # OLD may have fewer runs
    for run in shared:
        mine, theirs = demos_path(out, experiment, run), demos_path(old, experiment, run)
        if not same_arrays(theirs, mine):
            raise ExperimentError(f"--reuse {old}: its demonstrations {theirs} differ from {mine}")
    sources, tests_match = method_sources(saved, experiment), same_tests(saved, experiment, out)
    source, target, taken = CellStore(old / "cells", check=cell_problem), CellStore(out / "cells"), []
    for (name, run), job in jobs.items():
        if experiment.demos_per_run and run not in shared:
            continue
        ident = cell_id(name, run)
        found = [m for m in sources[name] if source.load(cell_id(m, run)) is not None]
        if not found or target.load(ident) is not None:
            continue
        source_name = found[0]
        old_run, new_run = old / "runs" / source_name / str(job.seed), Path(job.run_dir)
        # a job reading another method's training run (protocol.training_owners) owns no run to copy
        if not tests_match(job) or (new_run.exists() and not job.trained_by):
            continue
        if old_run.is_dir() and not job.trained_by:
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


def restore_published(
    source: str | Path,
    experiment: Experiment,
    out: Path,
    jobs: dict[tuple[str, int], RunJob],
    cell_id: Callable[[str, int], str],
    rename: dict[str, str] | None = None,
    runs: range | None = None,
    log: Callable[[str], None] = print,
) -> list[str]:
    """Writes into ``out``/cells the cells of a published results folder SOURCE (its
    ``experiment.json`` and ``results.json``, as in docs/results) for the jobs of ``runs`` (default:
    all) that ``out`` has not finished; returns their ids. For an output directory lost with its
    machine: a resume then computes only the rest.

    The rules of :func:`reuse_cells`, but for the demonstrations, which SOURCE does not hold (they
    are made from the experiment's seed and expert, per run where it draws them per run, as
    ``out`` holds them): the identity in the shared keys, the method's
    definition or resolved learner settings (``rename``: take NEW's cells from SOURCE's OLD), and
    each run's test arenas. A method that is another computation is left to be computed, and said;
    a cell whose training run ``out`` already holds (an interrupted one) too. Every check is made
    before anything is written: differing test arenas, a ``rename`` naming a method that its
    side does not hold, or ``runs`` outside the experiment are clear errors that leave ``out`` as it was.
    A restored cell records ``restored_from`` (the absolute path of SOURCE's results.json, and
    ``reused_as`` when renamed) and has no ``seconds`` (it was not timed here) and no training run
    in ``out``/runs.
    """
    from nirl_mj.data.atomic import write_text
    from nirl_mj.experiments.executors import CellStore

    source, rename = Path(source).resolve(), rename or {}
    try:
        saved = json.loads((source / EXPERIMENT_FILE).read_text())
        published = json.loads((source / "results.json").read_text())["cells"]
    except (OSError, ValueError, KeyError) as exc:
        raise ExperimentError(f"{source}: not a published experiment (experiment.json and results.json "
                              f"with its cells): {exc}") from None  # fmt: skip
    check_shared(saved, experiment, str(source))
    sources, old_names = method_sources(saved, experiment), [m["name"] for m in saved.get("methods", [])]
    for new, old in rename.items():
        if new not in sources:
            raise ExperimentError(f"rename {new}={old}: {new} is not a method of this experiment "
                                  f"({', '.join(sources)})")  # fmt: skip
        if old not in old_names:
            raise ExperimentError(f"rename {new}={old}: {old} is not a method of {source} "
                                  f"({', '.join(old_names)})")  # fmt: skip
    planned = sorted({run for _, run in jobs})
    if runs is not None and not set(runs) & set(planned):
        raise ExperimentError(f"runs {runs.start}-{runs.stop - 1}: none is a run of this experiment "
                              f"(runs {planned[0]}-{planned[-1]})")  # fmt: skip
    tests_match = same_tests(saved, experiment, out)
    store = CellStore(out / "cells", check=cell_problem)
    chosen, other = [], set()
    for (name, run), job in jobs.items():
        wanted = rename.get(name, name)
        if runs is not None and run not in runs:
            continue
        if cell_id(wanted, run) not in published or store.load(cell_id(name, run)) is not None:
            continue
        if wanted not in sources[name]:
            other.add(f"{name} (from {wanted})" if wanted != name else name)
            continue
        if Path(job.run_dir).exists() and not job.trained_by:
            continue
        if not tests_match(job):
            raise ExperimentError(f"{source}: run {run}'s test arenas differ from {out}'s; nothing restored")
        chosen.append((name, wanted, run))
    store.directory.mkdir(parents=True, exist_ok=True)
    for name, wanted, run in chosen:
        result = {**published[cell_id(wanted, run)], "method": name}
        record = {"id": cell_id(name, run), "result": result, "restored_from": str(source / "results.json")}
        if wanted != name:
            record["reused_as"] = wanted
        write_text(store.path(record["id"]), json.dumps(record, indent=1))
    if other:
        names = ", ".join(sorted(other))
        log(f"restore: not taken, another definition or learner settings in {source}: {names}")
    log(f"restore: {len(chosen)} finished cells taken from {source}")
    return [cell_id(name, run) for name, _, run in chosen]
