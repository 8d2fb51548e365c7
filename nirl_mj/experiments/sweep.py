"""Fig. 6: success of trained policies against the number of obstacles, at several speeds.

As in the paper (section V-A: "six completely new navigation missions using the
same weights with three different robot velocities"), each policy is trained
once, at the training task (``task``, e.g. 20 obstacles at 2 m/s), and tested
unchanged in every cell (N static obstacles, speed v) of ``obstacles`` x
``speeds``. The paper trains one policy and runs 50 tests per cell; here
``runs`` policies (training seeds) each run ``tests`` tests per cell, so the
figure shows the spread between training seeds as well.

Two phases of executor cells: the trainings (``train-METHOD-runR``), then one
cell per (method, run, obstacles, speed) testing the run's policy on the run's
test arenas (the same arenas in every cell: only the obstacle count and speed
change). Outputs in OUT: ``sweep.csv``, ``sweep.md`` (with what each method reads,
``nirl_mj.experiments.reads``, a reference in bold), ``sweep.png`` (lines like
Fig. 6, a band from the worst to the best run), ``results.json`` (``reads`` by method, as a suite's).
"""

from __future__ import annotations

import csv
import io
import json
import textwrap
from collections.abc import Callable
from pathlib import Path

from nirl_mj.data.atomic import write_figure, write_text
from nirl_mj.experiments.definition import Experiment
from nirl_mj.experiments.executors import Cell, Failure
from nirl_mj.experiments.kinds import ensure_trained
from nirl_mj.experiments.protocol import (
    Execution,
    RunJob,
    evaluate_policy,
    failed_section,
    failure_rows,
    one_writer,
    policy_of,
    prepare,
)
from nirl_mj.experiments.reads import READS_TERM, reads_by_method, reads_text
from nirl_mj.experiments.stats import summarise_runs
from nirl_mj.sim.spec import TaskSpec


def train_cell(job: RunJob) -> dict:
    """Trains (or resumes, or finds finished) one run; returns its iterations and selected iteration."""
    record = ensure_trained(job)
    # a job reading another method's run reports that run's last iterate (protocol.training_owners)
    selected = record["iterations"] - 1 if job.policy == "last" else record["selected_iteration"]
    return {
        "method": job.method.name,
        "run": job.run,
        "seed": job.seed,
        "iterations": record["iterations"],
        "selected_iteration": selected,
    }


def eval_cell(job: RunJob, task: TaskSpec, obstacles: int, speed: float) -> dict:
    """Tests one run's policy on its test arenas with ``obstacles`` obstacles at ``speed`` m/s."""
    metrics = evaluate_policy(policy_of(job, train=False), task, job.test_seeds, job.method.name)
    return {"method": job.method.name, "run": job.run, "obstacles": obstacles, "speed": speed, **metrics}


def train_id(method: str, run: int) -> str:
    return f"train-{method}-run{run:03d}"


def eval_id(method: str, run: int, obstacles: int, speed: float) -> str:
    return f"{method}-run{run:03d}-n{obstacles:03d}-v{speed:g}"


@one_writer
def run_sweep(
    experiment: Experiment,
    out: str | Path,
    execution: Execution | None = None,
    log: Callable[[str], None] = print,
    on_start: Callable[[int, int], None] | None = None,
    on_done: Callable | None = None,
) -> dict:
    """Runs (or resumes) the sweep in ``out``; writes its CSV, table and plot; returns the summary."""
    execution = execution or Execution()
    out, jobs = prepare(experiment, out, execution, log)
    trainings = [
        Cell(train_id(m, r), train_cell, (job,)) for (m, r), job in jobs.items() if job.method.trains
    ]
    tests = {
        (m, r, n, v): Cell(eval_id(m, r, n, v), eval_cell, (job, experiment.cell_task(n, v), n, v))
        for (m, r), job in jobs.items()
        for n in experiment.obstacles
        for v in experiment.speeds
    }
    with execution.start(out, log) as runner:
        if on_start:
            on_start(len(trainings) + len(tests), runner.finished([*trainings, *tests.values()]))
        trained = runner.run(trainings, on_done)
        runnable, blocked = [], {}
        for (m, r, *_), cell in tests.items():
            failed = trained.failures.get(train_id(m, r))
            if failed is None:
                runnable.append(cell)
            else:  # its policy does not exist: reported as failed too, never dropped
                blocked[cell.id] = Failure(cell.id, f"training failed: {failed.error}", "", 0)
                if on_done:
                    on_done(cell.id, None, blocked[cell.id])
        tested = runner.run(runnable, on_done)
    summary = summarise(experiment, tested.results)
    summary["failures"] = failure_rows({**trained.failures, **tested.failures, **blocked})
    summary["unfinished"] = runner.unfinished
    files = write_outputs(out, experiment, summary, tested.results) if execution.writes_tables else []
    summary["files"] = [str(f) for f in files]
    return summary


def summarise(experiment: Experiment, results: dict) -> dict:
    """One row per (method, obstacles, speed): ``stats.summarise_runs`` over the runs; and what each
    method reads (``reads``: method -> words)."""
    rows = []
    for method in experiment.methods:
        for v in experiment.speeds:
            for n in experiment.obstacles:
                found = [results[i] for r in range(experiment.runs)
                         if (i := eval_id(method.name, r, n, v)) in results]  # fmt: skip
                rows.append({"method": method.name, "obstacles": n, "speed": v, **summarise_runs(found),
                             "failed": experiment.runs - len(found)})  # fmt: skip
    return {"experiment": experiment.name, "description": experiment.description, "quick": experiment.quick,
            "runs": experiment.runs, "tests": experiment.tests, "cells": rows,
            "reads": reads_by_method(experiment)}  # fmt: skip


def json_line(summary: dict) -> str:
    """The ``--json`` last line: ``{"cells": [{method, obstacles, speed, avg, best, worst, ci, collision,
    timeout, runs, failed}], "failures": [cell ids]}``, rates as fractions."""
    keys = ("method", "obstacles", "speed", "avg", "best", "worst", "ci", "collision", "timeout", "runs",
            "failed")  # fmt: skip
    return json.dumps({"cells": [{k: row.get(k) for k in keys} for row in summary["cells"]],
                       "failures": [f["id"] for f in summary["failures"]]})  # fmt: skip


CSV_COLUMNS = ("method", "obstacles", "speed", "runs", "failed", "tests", "success_avg", "success_ci_low",
               "success_ci_high", "success_best", "success_worst", "collision_avg", "timeout_avg",
               "spl_avg")  # fmt: skip


def csv_table(summary: dict) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for row in summary["cells"]:
        ci = row.get("ci", [None, None])
        values = [row["method"], row["obstacles"], row["speed"], row["runs"], row["failed"], row.get("tests"),
                  row.get("avg"), ci[0], ci[1], row.get("best"), row.get("worst"), row.get("collision"),
                  row.get("timeout"), row.get("spl")]  # fmt: skip
        writer.writerow(["" if v is None else (f"{v:.6g}" if isinstance(v, float) else v) for v in values])
    return buffer.getvalue()


def markdown_table(summary: dict, experiment: Experiment) -> str:
    """Average success (percent, best-worst over runs) per method and speed (rows) and obstacles; and
    what each method reads, a reference in bold."""
    columns = [*(f"{n} obstacles" for n in experiment.obstacles), "reads"]
    header = "| method | speed (m/s) | " + " | ".join(columns) + " |"
    lines = [header, "|---|---|" + "---|" * len(columns)]
    by_key = {(r["method"], r["speed"], r["obstacles"]): r for r in summary["cells"]}
    reads = summary.get("reads", {})
    for method in experiment.methods:
        for v in experiment.speeds:
            cells = []
            for n in experiment.obstacles:
                r = by_key[method.name, v, n]
                spread = f" ({100 * r['worst']:.0f}-{100 * r['best']:.0f})" if r["runs"] > 1 else ""
                cells.append(f"{100 * r['avg']:.1f}{spread}" if r["runs"] else "-")
            cells.append(reads_text(reads.get(method.name)))
            lines.append(f"| {method.name} | {v:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def line_plot(path: Path, summary: dict, experiment: Experiment) -> Path:
    """Success (%) against obstacles, a line per speed and method; band: worst to best run (Fig. 6)."""
    import matplotlib

    from nirl_mj.inspect.canvas import subplots

    fig, ax = subplots(figsize=(6.4, 4.0), dpi=110)
    colours = matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]
    styles = ["-", "--", ":", "-."]
    for k, method in enumerate(experiment.methods):
        series: dict[tuple, list[int]] = {}  # a curve and the speeds (indices) that drew it
        for j, v in enumerate(experiment.speeds):
            rows = [
                r for r in summary["cells"] if r["method"] == method.name and r["speed"] == v and r["runs"]
            ]
            if rows:
                curve = tuple((r["obstacles"], r["avg"], r["worst"], r["best"]) for r in rows)
                series.setdefault(curve, []).append(j)
        for curve, speeds in series.items():
            # speeds with the same curve (a policy that ignores the speed, e.g. forward) share one line,
            # grey, instead of lines drawn over each other
            x, avg, worst, best = (list(column) for column in zip(*curve, strict=True))
            colour = colours[speeds[0] % len(colours)] if len(speeds) == 1 else "0.4"
            names = [f"{experiment.speeds[j]:g}" for j in speeds]
            label = f"{method.name}, {names[0]} m/s" if len(names) == 1 else (
                f"{method.name}, {', '.join(names[:-1])} and {names[-1]} m/s (the same)")  # fmt: skip
            ax.plot(x, [100 * a for a in avg], styles[k % len(styles)], color=colour, marker="o", ms=4,
                    label=label)  # fmt: skip
            if experiment.runs > 1:
                ax.fill_between(x, [100 * w for w in worst], [100 * b for b in best], color=colour,
                                alpha=0.12)  # fmt: skip
    ax.set_xlabel("static obstacles")
    ax.set_ylabel("success (%)")
    ax.set_ylim(0, 100)
    bands = " (bands: worst to best run)" if experiment.runs > 1 else ""
    ax.set_title(f"{experiment.name}: {experiment.runs} policies x {experiment.tests} tests per point{bands}",
                 fontsize=10)  # fmt: skip
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    write_figure(path, fig)
    return path


def write_outputs(out: Path, experiment: Experiment, summary: dict, results: dict) -> list[Path]:
    line_plot(out / "sweep.png", summary, experiment)
    train = experiment.task
    text = f"""# {experiment.name}{" (quick)" if experiment.quick else ""}: {experiment.description}

{experiment.runs} policies per method, each trained once on `{train.name}`
({train.arena.static_obstacles} obstacles, {train.control.speed:g} m/s) from {experiment.demos} demonstrations
({experiment.expert} expert), then tested unchanged on {experiment.tests} held-out arenas of
`{experiment.test_task.name}` per cell, with the cell's number of static obstacles and speed.
Success in percent: average over the policies (worst-best in brackets).
{textwrap.fill(f"{READS_TERM}.", 100, break_long_words=False, break_on_hyphens=False)}

{markdown_table(summary, experiment)}

![success against obstacles](sweep.png)
{failed_section(summary)}"""
    write_text(out / "sweep.md", text)
    write_text(out / "sweep.csv", csv_table(summary))
    write_text(out / "results.json", json.dumps({**summary, "cells_raw": results}, indent=1))
    return [out / "sweep.md", out / "sweep.csv", out / "sweep.png", out / "results.json"]
