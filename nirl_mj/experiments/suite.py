"""Suites: the comparison protocol along an axis, as curves (``nirl-mj suite``).

A suite is a compare experiment (``nirl_mj.experiments.compare``: the same runs, seeds, paired test
arenas and information budget) with one or more ``[[axis]]`` tables
(``nirl_mj.experiments.definition.AXES``):

- a **training axis** (``demonstrations``, ``demonstrator``) trains every method that reads the
  demonstrations again at each value: the cells of value v are those of the comparison
  ``experiment.at(v)``, kept in ``OUT/points/AXIS-v/`` (its demonstrations and training runs);
  methods that read no demonstrations (the rule, always forward, PPO or DQN on the task's reward) are
  computed once per run (in ``OUT/points/AXIS-any/``) and stand on every value as a horizontal
  line;
- **test axes** (``obstacles``, ``speed``, ``moving``, ``family``) test the policies trained once on
  ``task`` unchanged: one cell per (method, run) trains, then drives the run's test arenas at every
  value of every axis.

Every run's test arenas are the same at every value (demonstration arenas are drawn from another
domain than test arenas, and this is checked), so a point's runs are paired with the other points'
and the other methods'. Outputs in OUT: ``suite.csv`` (one tidy row per (axis, value, method, run):
:data:`CSV_COLUMNS`), ``suite.md`` (per axis: average success with its 95 % interval, SPL, SCT and
the first method minus each other, paired by run), ``AXIS.png`` (a curve per method with its 95 %
interval band) and ``results.json``.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path

from nirl_mj.data.atomic import write_figure, write_text
from nirl_mj.experiments import tidy
from nirl_mj.experiments.definition import Axis, Experiment, ExperimentError, value_name
from nirl_mj.experiments.executors import Cell
from nirl_mj.experiments.protocol import (
    Execution,
    RunJob,
    demos_path,
    ensure_demos,
    evaluate_policy,
    failed_section,
    failure_rows,
    one_writer,
    open_output,
    policy_of,
    run_jobs,
)
from nirl_mj.experiments.reads import reads_by_method, reads_text
from nirl_mj.experiments.stats import paired, summarise_runs
from nirl_mj.experiments.suite_cells import (
    ANY,
    point_key,
    reads_demonstrations,
    test_cell_id,
    training_cell_id,
)
from nirl_mj.experiments.suite_restore import published_suite, restore_suite
from nirl_mj.sim.spec import TaskSpec

CSV_COLUMNS = tidy.COLUMNS
"""The tidy CSV's columns (``nirl_mj.experiments.tidy``)."""


def compare_point(job: RunJob, test_task: TaskSpec) -> dict:
    """A training axis's cell: trains (if it trains) and tests one (method, run) of one value."""
    metrics = evaluate_policy(policy_of(job), test_task, job.test_seeds, job.method.name)
    return {"method": job.method.name, "run": job.run, "seed": job.seed, **metrics}


def transfer_cell(job: RunJob, points: list[tuple[str, TaskSpec]]) -> dict:
    """A test axis's cell: trains (if it trains) one (method, run) once, then tests its policy on the
    run's test arenas under every point's task; ``points`` holds (``point_key``, task)."""
    policy = policy_of(job)
    return {"method": job.method.name, "run": job.run, "seed": job.seed,
            "points": {key: evaluate_policy(policy, task, job.test_seeds, job.method.name)
                       for key, task in points}}  # fmt: skip


@one_writer
def run_suite(
    experiment: Experiment,
    out: str | Path,
    execution: Execution | None = None,
    log: Callable[[str], None] = print,
    on_start: Callable[[int, int], None] | None = None,
    on_done: Callable | None = None,
) -> dict:
    """Runs (or resumes) the suite in ``out``; writes its CSV, tables and plots; returns the summary."""
    from nirl_mj.experiments.executors import default_workers

    execution = execution or Execution()
    execution.check_methods(experiment)  # before anything is made in OUT
    at_points(experiment, execution)  # a bad --points too
    if execution.reuse:
        raise ExperimentError("--reuse takes cells of compare experiments only")
    execution.check_output(out)
    if execution.restore:  # checked and read before OUT is made
        published = published_suite(execution.restore, experiment, execution.only, log)
    out = open_output(out, experiment, record=execution.writes_tables)
    if execution.restore:
        restore_suite(*published, out, log)
    workers = execution.workers or default_workers()
    if experiment.axes[0].trains:
        cells = training_cells(experiment, out, execution, workers, log)
    else:
        cells = test_cells(experiment, out, execution, workers, log)
    with execution.start(out, log) as runner:
        report = runner.run_only(
            cells, execution.only, on_start, on_done, also=at_points(experiment, execution)
        )
    rows = tidy_rows(experiment, report.results)
    summary = summarise(experiment, rows)
    summary["failures"] = failure_rows(report.failures)
    summary["unfinished"] = runner.unfinished
    files = write_outputs(out, experiment, summary, rows, report.results) if execution.writes_tables else []
    summary["files"] = [str(f) for f in files]
    return summary


def at_points(experiment: Experiment, execution: Execution) -> Callable | None:
    """``--points``: whether a cell is at one of the given values of the training axis (the cells that
    hold at every value too); None without ``--points``."""
    if not execution.points:
        return None
    (axis, *rest) = experiment.axes
    if rest or not axis.trains:
        axes = ", ".join(a.name for a in experiment.axes)
        raise ExperimentError(
            f"--points picks values of a training axis (demonstrations, demonstrator); "
            f"{experiment.name} has {axes}"
        )
    names = [value_name(v) for v in axis.values]
    unknown = [p for p in execution.points if p not in names]
    if unknown:
        raise ExperimentError(
            f"--points {', '.join(unknown)}: not a value of {axis.name} ({', '.join(names)})"
        )
    wanted = {f"{axis.name}-{p}" for p in (*execution.points, ANY)}  # training_cell_id's part before "."
    return lambda cell: cell.id.rsplit(".", 1)[0] in wanted


def _demos(
    experiment: Experiment, folder: Path, execution: Execution, workers: int, log: Callable[[str], None]
) -> dict[int, Path]:
    """Each run's demonstrations of ``experiment`` in ``folder`` (made once; a report takes those there)."""
    if execution.report_only:
        paths = {r: demos_path(folder, experiment, r) for r in range(experiment.runs)}
        return {r: p for r, p in paths.items() if p.is_file()}
    return {r: ensure_demos(folder, experiment, workers, log, r) for r in range(experiment.runs)}


def test_cells(
    experiment: Experiment, out: Path, execution: Execution, workers: int, log: Callable[[str], None]
) -> list[Cell]:
    """One cell per (method, run): trained on ``task``, tested at every value of every test axis."""
    jobs = run_jobs(experiment, out, _demos(experiment, out, execution, workers, log))
    points = [(point_key(axis.name, v), axis.task_at(v)) for axis in experiment.axes for v in axis.values]
    return [Cell(test_cell_id(m, r), transfer_cell, (job, points)) for (m, r), job in jobs.items()]


def training_cells(
    experiment: Experiment, out: Path, execution: Execution, workers: int, log: Callable[[str], None]
) -> list[Cell]:
    """One cell per (value, method, run) for the methods that read the demonstrations, one per
    (method, run) for the others (on the first value's demonstrations, which they do not read)."""
    (axis,) = experiment.axes
    cells, test_seeds = [], {}
    for i, value in enumerate(axis.values):
        at = experiment.at(value)
        folder = out / "points" / f"{axis.name}-{value_name(value)}"
        jobs = run_jobs(at, folder, _demos(at, folder, execution, workers, log))
        for (m, r), job in jobs.items():
            if test_seeds.setdefault(r, job.test_seeds) != job.test_seeds:
                raise ExperimentError(
                    f"{axis.name} = {value_name(value)}: run {r}'s test arenas differ "
                    "from the first value's; the suite's points would not be paired"
                )
            if reads_demonstrations(job.method, axis):
                cells.append(Cell(training_cell_id(axis.name, value_name(value), m, r), compare_point,
                                  (job, at.test_task)))  # fmt: skip
            elif i == 0:
                job = _moved(job, out / "points" / f"{axis.name}-{ANY}")
                cells.append(Cell(training_cell_id(axis.name, ANY, m, r), compare_point, (job, at.test_task)))
    return cells


def _moved(job: RunJob, folder: Path) -> RunJob:
    """``job`` with its training runs kept under ``folder`` (a method whose result holds at every value)."""
    return dataclasses.replace(job, run_dir=str(folder / "runs" / job.method.name / str(job.seed)))


def tidy_rows(experiment: Experiment, results: dict) -> list[dict]:
    """One row per (axis, value, method, run) with a finished cell (:data:`CSV_COLUMNS`); a method
    that does not depend on a training axis repeats its run's result at every value."""
    rows = []
    for axis in experiment.axes:
        for value in axis.values:
            for method in experiment.methods:
                for r in range(experiment.runs):
                    if axis.trains:
                        own = training_cell_id(axis.name, value_name(value), method.name, r)
                        metrics = results.get(own) or results.get(
                            training_cell_id(axis.name, ANY, method.name, r)
                        )
                    else:
                        cell = results.get(test_cell_id(method.name, r))
                        metrics = cell["points"].get(point_key(axis.name, value)) if cell else None
                    if metrics is not None:
                        rows.append(tidy.row(experiment.name, axis.name, value_name(value), method.name, r,
                                             metrics))  # fmt: skip
    return rows


def summarise(experiment: Experiment, rows: list[dict]) -> dict:
    """Per (axis, value, method): ``stats.summarise_runs`` over its runs, whether it is drawn as a
    horizontal line (it does not depend on a training axis), and the first method minus it,
    paired by run (``paired``); and what each method reads (``reads``: method -> words)."""
    points = []
    first = experiment.methods[0].name
    for axis in experiment.axes:
        for value in axis.values:
            here = [r for r in rows if r["axis"] == axis.name and r["value"] == value_name(value)]
            by_run = {
                m.name: {r["run"]: r for r in here if r["method"] == m.name} for m in experiment.methods
            }
            for method in experiment.methods:
                mine = by_run[method.name]
                both = sorted(set(mine) & set(by_run[first]))
                points.append({
                    "axis": axis.name, "value": value_name(value), "method": method.name,
                    "flat": axis.trains and not reads_demonstrations(method, axis),
                    **summarise_runs([tidy.as_metrics(mine[r]) for r in sorted(mine)]),
                    "failed": experiment.runs - len(mine),
                    "paired": None if method.name == first else paired(
                        [by_run[first][r]["success"] for r in both], [mine[r]["success"] for r in both]),
                })  # fmt: skip
    reads = reads_by_method(experiment)
    return {"experiment": experiment.name, "description": experiment.description, "quick": experiment.quick,
            "runs": experiment.runs, "tests": experiment.tests, "first": first, "points": points,
            "reads": reads}  # fmt: skip


def json_line(summary: dict) -> str:
    """The ``--json`` last line: ``{"points": [{axis, value, method, avg, ci, spl, sct, runs, failed}],
    "failures": [cell ids]}``, rates as fractions."""
    keys = ("axis", "value", "method", "avg", "ci", "spl", "sct", "runs", "failed")
    return json.dumps({"points": [{k: p.get(k) for k in keys} for p in summary["points"]],
                       "failures": [f["id"] for f in summary["failures"]]})  # fmt: skip


def _percent(p: dict, runs: int) -> str:
    if not p.get("runs"):
        return "-"
    ci = p.get("ci") or [None, None]
    band = f" [{100 * ci[0]:.0f}, {100 * ci[1]:.0f}]" if ci[0] is not None else ""
    return f"{100 * p['avg']:.1f}{band}{_fewer(p['runs'], runs)}"


def _fewer(done: int, runs: int) -> str:
    """`` (n = done)`` where a point has fewer finished runs than the experiment's ``runs``."""
    return f" (n = {done})" if done < runs else ""


def markdown_table(summary: dict, experiment: Experiment) -> str:
    """Per axis: average success (percent) with its 95 % interval, a column per value; and what each
    method reads, a reference in bold."""
    parts = []
    reads = summary.get("reads", {})
    for axis in experiment.axes:
        names = [value_name(v) for v in axis.values]
        lines = [f"| method | {axis.name} = " + " | ".join(names) + " | reads |",
                 "|---|" + "---|" * (len(names) + 1)]  # fmt: skip
        for method in experiment.methods:
            found = {
                p["value"]: p
                for p in summary["points"]
                if p["axis"] == axis.name and p["method"] == method.name
            }
            cells = [_percent(found[n], experiment.runs) for n in names]
            cells.append(reads_text(reads.get(method.name)))
            lines.append(f"| {method.name} | " + " | ".join(cells) + " |")
        parts.append("\n".join(lines))
    return "\n\n".join(parts)


def _metric_table(summary: dict, experiment: Experiment, axis: Axis, key: str) -> str:
    names = [value_name(v) for v in axis.values]
    lines = [f"| method | {axis.name} = " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for method in experiment.methods:
        found = {
            p["value"]: p for p in summary["points"] if p["axis"] == axis.name and p["method"] == method.name
        }
        cells = [f"{found[n][key]:.2f}" if found[n].get("runs") and found[n].get(key) is not None else "-"
                 for n in names]  # fmt: skip
        lines.append(f"| {method.name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _paired_table(summary: dict, experiment: Experiment, axis: Axis) -> str:
    names = [value_name(v) for v in axis.values]
    first = summary["first"]
    lines = [f"| {first} minus | {axis.name} = " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for method in experiment.methods[1:]:
        cells = []
        for n in names:
            p = next(q for q in summary["points"]
                     if (q["axis"], q["value"], q["method"]) == (axis.name, n, method.name))  # fmt: skip
            d = p.get("paired") or {}
            ci = d.get("ci") or [None, None]
            if d.get("runs", 0) > 1 and ci[0] is not None:
                cells.append(f"{100 * d['mean']:+.1f} [{100 * ci[0]:+.0f}, {100 * ci[1]:+.0f}]"
                             f"{_fewer(d['runs'], experiment.runs)}")  # fmt: skip
            else:  # one run paired has a difference but no interval (compare's table shows it too)
                cells.append(f"{100 * d['mean']:+.1f} (1 run)" if d.get("runs") == 1 else "-")
        lines.append(f"| {method.name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def curve_plot(path: Path, summary: dict, experiment: Experiment, axis: Axis) -> Path:
    """Success (%) against the axis's values: a curve per method with its 95 % interval band; a method
    that does not depend on a training axis is a dashed horizontal line with its band."""
    import matplotlib

    from nirl_mj.inspect.canvas import subplots

    fig, ax = subplots(figsize=(6.8, 4.2), dpi=110)
    names = [value_name(v) for v in axis.values]
    x = list(range(len(names)))
    drawn = []  # colours go to the methods with a result, so that no two drawn ones share one
    for method in experiment.methods:
        found = {
            p["value"]: p for p in summary["points"] if p["axis"] == axis.name and p["method"] == method.name
        }
        done = [(i, found[n]) for i, n in enumerate(names) if found[n].get("runs")]
        if done:
            drawn.append((method, done))
    colours = matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]
    if len(drawn) > len(colours):  # more rows than the default 10 colours: tab20, its dark shades first
        pairs = matplotlib.colormaps["tab20"].colors
        colours = [*pairs[::2], *pairs[1::2]]
    for k, (method, done) in enumerate(drawn):
        colour = colours[k % len(colours)]
        flat = done[0][1]["flat"]
        xs = [x[0] - 0.2, x[-1] + 0.2] if flat else [i for i, _ in done]
        ys = [done[0][1]] * 2 if flat else [p for _, p in done]
        ax.plot(xs, [100 * p["avg"] for p in ys], "--" if flat else "-", color=colour,
                marker=None if flat else "o", ms=4, label=method.name)  # fmt: skip
        if all(p.get("ci") and p["ci"][0] is not None for p in ys):
            ax.fill_between(xs, [100 * p["ci"][0] for p in ys], [100 * p["ci"][1] for p in ys], color=colour,
                            alpha=0.12)  # fmt: skip
    ax.set_xticks(x, names, rotation=20 if max(len(n) for n in names) > 6 else 0)
    ax.set_xlabel(axis.name)
    ax.set_ylabel("success (%)")
    ax.set_ylim(0, 100)
    ax.set_title(f"{experiment.name}: {experiment.runs} runs x {experiment.tests} tests per point, "
                 "95 % interval bands", fontsize=9)  # fmt: skip
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    write_figure(path, fig)
    return path


def write_outputs(
    out: Path, experiment: Experiment, summary: dict, rows: list[dict], results: dict
) -> list[Path]:
    files = [curve_plot(out / f"{axis.name}.png", summary, experiment, axis) for axis in experiment.axes]
    train = experiment.task
    sections = []
    for axis in experiment.axes:
        what = (f"every learner trained again at each value ({axis.name})" if axis.trains else
                f"the policies trained once, tested unchanged with the test task's {axis.name} set to each "
                f"value (test task `{axis.test_task.name}`)")  # fmt: skip
        sections.append(f"""## {axis.name}

{what}. Success in percent: average over the runs [95 % t interval].

{markdown_table(summary, _only_axis(experiment, axis))}

SPL:

{_metric_table(summary, experiment, axis, "spl")}

SCT (success weighted by completion time):

{_metric_table(summary, experiment, axis, "sct")}

{summary["first"]} minus each method, paired by run (points, [95 % interval]):

{_paired_table(summary, experiment, axis)}

![{axis.name}]({axis.name}.png)
""")
    text = f"""# {experiment.name}{" (quick)" if experiment.quick else ""}: {experiment.description}

{experiment.runs} runs per point; run r trains with seed {experiment.seed} + r on `{train.name}`
({train.arena.static_obstacles} obstacles, {train.control.speed:g} m/s) from {experiment.demos} demonstrations
by the {experiment.expert} expert (unless the axis changes them) and is tested on {experiment.tests} arenas
of the {experiment.test_domain} domain, the same at every point. Tidy rows: `suite.csv`.

{chr(10).join(sections)}{failed_section(summary)}"""
    write_text(out / "suite.md", text)
    write_text(out / "suite.csv", tidy.csv_text(rows))
    write_text(out / "results.json", json.dumps({**summary, "rows": rows, "cells_raw": results}, indent=1))
    return [out / "suite.md", out / "suite.csv", *files, out / "results.json"]


def _only_axis(experiment: Experiment, axis: Axis) -> Experiment:
    return dataclasses.replace(experiment, axes=(axis,))
