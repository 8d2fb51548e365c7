"""A published suite's finished cells, taken back into an output directory (``nirl-mj suite --restore``).

A suite's output directory (``runs/NAME``) lives on the machine that computed it; what is kept
with the code is its publication in ``docs/results/suites/``: ``NAME.csv`` (one tidy row per (axis,
value, method, run)) and ``NAME.experiment.json`` (its identity). When the output directory is lost,
:func:`restore_suite` writes a cell back for every (method, run) the CSV holds, so that a resume
computes only the rest (a method added later, or methods whose code changed and that are to be
computed again: ``--only`` names the methods to take).

A restored cell holds what the CSV holds, the rates, SPL, SCT and the test count (rates as the CSV
prints them, to six significant digits), with the physics-error rate as what the three outcomes
leave. It records ``restored_from`` (the CSV's absolute path) and has no training run: nothing that
reads a run directory (``nirl-mj render``, ``docs/scripts/iterate_study.py``) can read it.

What this checks: the published identity equals the experiment's in every key but the method list
and the learners' settings, and each method taken has the same definition and resolved learner
settings in both. What it cannot see is a change in the code itself (as resuming cannot): the
caller names the methods whose code is unchanged.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable
from pathlib import Path

from nirl_mj.data.atomic import write_text
from nirl_mj.experiments import tidy
from nirl_mj.experiments.definition import Experiment, ExperimentError, MethodSpec, value_name
from nirl_mj.experiments.executors import CellStore
from nirl_mj.experiments.protocol import EXPERIMENT_FILE, cell_problem, run_seed, unspelled_identity
from nirl_mj.experiments.suite_cells import (
    ANY,
    point_key,
    reads_demonstrations,
    test_cell_id,
    training_cell_id,
)


def published_files(source: Path, name: str) -> tuple[Path, Path]:
    """The CSV and identity of suite ``name`` in ``source``: a publication folder (``NAME.csv`` and
    ``NAME.experiment.json``, as docs/results/suites) or an output directory (``suite.csv`` and
    ``experiment.json``)."""
    for csv, identity in ((f"{name}.csv", f"{name}.experiment.json"), ("suite.csv", EXPERIMENT_FILE)):
        if (source / csv).is_file() and (source / identity).is_file():
            return source / csv, source / identity
    raise ExperimentError(f"--restore {source}: holds no published suite {name} ({name}.csv and "
                          f"{name}.experiment.json, or suite.csv and {EXPERIMENT_FILE})")  # fmt: skip


def restorable_methods(saved: dict, experiment: Experiment, source: Path) -> dict[str, str]:
    """Whether each method of ``experiment`` was computed alike in ``saved`` (a published identity):
    "" if so, else why not. A published suite of another experiment (task, seed, tests, axes,
    demonstrations: any key but the methods and learners, on either side) is an error."""
    from nirl_mj.experiments.reuse import method_sources, saved_form

    was, now = unspelled_identity(saved), unspelled_identity(saved_form(experiment))
    keys = (set(was) | set(now)) - {"methods", "learners"}
    if differ := sorted(k for k in keys if was.get(k) != now.get(k)):
        raise ExperimentError(f"--restore {source}: another experiment than {experiment.name}'s (it differs "
                              f"in: {', '.join(differ)}); nothing restored")  # fmt: skip
    sources, trained = method_sources(saved, experiment), now.get("learners", {})
    why = "other learner settings (the loop's or its step's)", "another definition, or none"
    return {
        m.name: "" if m.name in sources[m.name] else why[m.name not in trained] for m in experiment.methods
    }


def cell_metrics(row: dict) -> dict:
    """A cell's metrics from its tidy row (``evaluate_policy``'s keys, what the CSV keeps of them)."""
    rates = {"success_rate": row["success"], "collision_rate": row["collision"],
             "timeout_rate": row["timeout"]}  # fmt: skip
    left = round((1.0 - sum(rates.values())) * row["tests"]) / row["tests"]  # the CSV's 6 digits
    metrics = {**rates, "physics_error_rate": max(left, 0.0), "spl": row["spl"], "tests": row["tests"]}
    return metrics if row["sct"] is None else {**metrics, "sct": row["sct"]}


Rows = dict[tuple[str, str, str, int], dict]  # (axis, value, method, run) -> tidy row


def _training_cells(experiment: Experiment, method: MethodSpec, run: int, found: Rows) -> dict[str, dict]:
    """A training axis's cells of (method, run): one per value, or one (``ANY``) for a horizontal
    line, whose rows repeat it at every value."""
    (axis,) = experiment.axes
    values = [value_name(v) for v in axis.values]
    pairs = [(v, v) for v in values] if reads_demonstrations(method, axis) else [(values[0], ANY)]
    head = {"method": method.name, "run": run, "seed": run_seed(experiment, run)}
    return {training_cell_id(axis.name, cell, method.name, run): {**head, **cell_metrics(row)}
            for value, cell in pairs if (row := found.get((axis.name, value, method.name, run)))}  # fmt: skip


def _test_cell(experiment: Experiment, method: MethodSpec, run: int, found: Rows) -> dict[str, dict]:
    """A test axis's cell of (method, run), when the rows hold every point of every axis."""
    keys = [(a.name, value_name(v), method.name, run) for a in experiment.axes for v in a.values]
    if not all(k in found for k in keys):
        return {}
    points = {point_key(a, v): cell_metrics(found[(a, v, m, r)]) for a, v, m, r in keys}
    head = {"method": method.name, "run": run, "seed": run_seed(experiment, run)}
    return {test_cell_id(method.name, run): {**head, "points": points}}


def published_cells(experiment: Experiment, rows: list[dict], methods: set[str]) -> dict[str, dict]:
    """The cells of ``methods`` that the tidy ``rows`` hold in full, by cell id."""
    found = {(r["axis"], r["value"], r["method"], r["run"]): r for r in rows if r["suite"] == experiment.name}
    of_run = _training_cells if experiment.axes[0].trains else _test_cell
    cells = {}
    for method in (m for m in experiment.methods if m.name in methods):
        for run in range(experiment.runs):
            cells.update(of_run(experiment, method, run, found))
    return cells


def published_suite(
    source: str | Path, experiment: Experiment, only: tuple[str, ...] = (), log: Callable[[str], None] = print
) -> tuple[Path, dict[str, dict]]:
    """The published CSV of ``experiment`` in ``source`` and its cells of the methods in ``only`` (all
    if empty) that were computed alike, by cell id; checked before anything is written. Every method
    left out, and why, is logged."""
    source = Path(source).resolve()
    csv, identity = published_files(source, experiment.name)
    try:
        saved = json.loads(identity.read_text())
    except (OSError, ValueError) as exc:
        raise ExperimentError(f"--restore {identity}: cannot be read ({exc})") from None
    if not isinstance(saved, dict):
        raise ExperimentError(f"--restore {identity}: not an experiment's identity (a JSON object)")
    try:
        rows = [r for r in tidy.read(csv) if r["suite"] == experiment.name]
    except tidy.TidyError as exc:
        raise ExperimentError(f"--restore {exc}") from None
    if not rows:
        raise ExperimentError(f"--restore {csv}: no row of suite {experiment.name}")
    wanted = [m.name for m in experiment.methods if not only or m.name in only]
    why = restorable_methods(saved, experiment, source)
    for name in wanted:
        if why[name]:
            log(f"restore: {name} not taken: {identity.name} computed it with {why[name]}")
    cells = published_cells(experiment, rows, {n for n in wanted if not why[n]})
    if missing := [n for n in wanted if not why[n] and not any(c["method"] == n for c in cells.values())]:
        log(f"restore: {csv.name} holds no finished cell of {', '.join(missing)}")
    return csv, cells


def restore_suite(
    csv: Path, cells: dict[str, dict], out: Path, log: Callable[[str], None] = print
) -> list[str]:
    """Writes ``cells`` (:func:`published_suite`) that ``out`` has not finished into ``out``/cells;
    returns their ids."""
    store = CellStore(out / "cells", check=cell_problem)
    taken = [cid for cid in cells if store.load(cid) is None]
    store.directory.mkdir(parents=True, exist_ok=True)
    for cid in taken:
        write_text(
            store.path(cid),
            json.dumps({"id": cid, "result": cells[cid], "restored_from": str(csv)}, indent=1),
        )
    counts = Counter(cells[cid]["method"] for cid in taken)
    each = ", ".join(f"{name} {n}" for name, n in counts.items())
    log(f"restore: {len(taken)} finished cells taken from {csv}" + (f" ({each})" if each else ""))
    return taken
