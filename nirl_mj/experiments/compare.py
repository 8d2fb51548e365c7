"""The paper's Table I protocol: every method, R runs of T tests each, next to the paper's numbers.

A cell is one (method, run): run r trains the method with seed ``seed + r`` on
the experiment's demonstrations (trainable methods; resumable in
``OUT/runs/METHOD/SEED``) and tests its greedy policy on the T held-out arenas
of run r, the same for every method (``nirl_mj.experiments.protocol``). Per method: average
/ best / worst success over the runs with a 95 % Student-t interval of the
average (``nirl_mj.experiments.stats``), mean collision, timeout and physics-error rates,
SPL, what it reads (``nirl_mj.experiments.reads``); every run's success; and the first method
listed minus each other, paired by run (the runs of one seed share their training seed,
demonstrations and test arenas, so the pairing removes their luck). ``--only`` computes some
methods' cells and reports the others as stored.
Outputs in OUT:

- ``table.md``, ``table.csv``, ``table.png`` (bar chart next to the paper's);
- ``rows.csv``: one tidy row per (method, run) (``nirl_mj.experiments.tidy``, as suites write);
- ``results.json``: the summaries, every cell's metrics, failed cells;
- ``strip.png`` with a ``[strip]`` table (Fig. 8: snapshots of one test episode).
"""

from __future__ import annotations

import csv
import io
import json
import math
import textwrap
from collections.abc import Callable
from pathlib import Path

from nirl_mj.data.atomic import write_figure, write_text
from nirl_mj.experiments import tidy
from nirl_mj.experiments.definition import Experiment
from nirl_mj.experiments.executors import Cell
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
from nirl_mj.experiments.reads import READS_TERM, method_reads, reads_text
from nirl_mj.experiments.stats import paired, summarise_runs
from nirl_mj.sim.spec import TaskSpec


def compare_cell(job: RunJob, test_task: TaskSpec) -> dict:
    """Trains (if it trains) and tests one (method, run); returns its ``evaluate`` metrics."""
    metrics = evaluate_policy(policy_of(job), test_task, job.test_seeds, job.method.name)
    return {"method": job.method.name, "run": job.run, "seed": job.seed, **metrics}


def cell_id(method: str, run: int) -> str:
    return f"{method}-run{run:03d}"


@one_writer
def run_compare(
    experiment: Experiment,
    out: str | Path,
    execution: Execution | None = None,
    log: Callable[[str], None] = print,
    on_start: Callable[[int, int], None] | None = None,
    on_done: Callable | None = None,
) -> dict:
    """Runs (or resumes) the comparison in ``out``; writes the tables and returns the summary.

    ``on_start(cells, already finished)`` and ``on_done(cell id, result, failure)`` report progress.
    """
    execution = execution or Execution()
    execution.check_methods(experiment)  # before anything is made in OUT
    if execution.reuse:
        from nirl_mj.experiments.reuse import read_old, reuse_cells

        read_old(execution.reuse, experiment)  # a wrong OLD is refused before OUT is made
    out, jobs = prepare(experiment, out, execution, log)
    if execution.reuse:
        reuse_cells(execution.reuse, experiment, out, jobs, cell_id, log)
    cells = [Cell(cell_id(m, r), compare_cell, (job, experiment.test_task)) for (m, r), job in jobs.items()]
    with execution.start(out, log) as runner:
        report = runner.run_only(cells, execution.only, on_start, on_done)
    summary = summarise(experiment, report.results)
    summary["failures"] = failure_rows(report.failures)
    summary["unfinished"] = runner.unfinished
    files = write_outputs(out, experiment, summary, report.results) if execution.writes_tables else []
    if experiment.strip is not None and not execution.report_only:
        if cell_id(experiment.strip.method, 0) in report.results:
            files.append(write_strip(out, experiment, jobs, log))
        else:
            log(f"strip: not written: {cell_id(experiment.strip.method, 0)} failed")
    summary["files"] = [str(f) for f in files if f is not None]
    return summary


def summarise(experiment: Experiment, results: dict) -> dict:
    """Per method: ``stats.summarise_runs`` over its finished runs, failed runs, the paper's row,
    each run's success by run index (``by_run``), and the first method minus it, paired over the
    runs both finished (``paired``; not for the first method itself)."""
    methods = {}
    for method in experiment.methods:
        by_run = {r: results[i]["success_rate"] for r in range(experiment.runs)
                  if (i := cell_id(method.name, r)) in results}  # fmt: skip
        rows = [results[cell_id(method.name, r)] for r in by_run]
        methods[method.name] = {
            "reads": method_reads(method, experiment.config),
            **summarise_runs(rows),
            "failed": experiment.runs - len(rows),  # failed, or unfinished in a --report
            "paper": {k: v / 100 for k, v in experiment.paper.get(method.name, {}).items()} or None,
            "by_run": by_run,
        }
    reference = methods[experiment.methods[0].name]["by_run"]
    for method in experiment.methods[1:]:
        mine = methods[method.name]["by_run"]
        both = [r for r in reference if r in mine]
        methods[method.name]["paired"] = paired([reference[r] for r in both], [mine[r] for r in both])
    return {
        "experiment": experiment.name,
        "description": experiment.description,
        "quick": experiment.quick,
        "runs": experiment.runs,
        "tests": experiment.tests,
        "methods": methods,
    }


def json_line(summary: dict) -> str:
    """The ``--json`` last line: ``{"methods": {NAME: {avg, best, worst, ci, collision, timeout, runs,
    failed}}, "failures": [cell ids]}``, rates as fractions."""
    keys = ("avg", "best", "worst", "ci", "collision", "timeout", "runs", "failed")
    return json.dumps({
        "methods": {name: {k: s.get(k) for k in keys} for name, s in summary["methods"].items()},
        "failures": [f["id"] for f in summary["failures"]],
    })  # fmt: skip


def _pct(value: float | None, digits: int = 1) -> str:
    return (
        "-"
        if value is None or (isinstance(value, float) and math.isnan(value))
        else f"{100 * value:.{digits}f}"
    )


def markdown_table(summary: dict) -> str:
    """The results next to the paper's Table I: rates in percent, SPL from 0 to 1."""
    lines = [
        "| method | runs | success avg [95 % CI] | best | worst | collision | timeout | SPL "
        "| paper avg / best / worst | reads |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, s in summary["methods"].items():
        paper = s["paper"] or {}
        paper_text = " / ".join(_pct(paper.get(k), 0) for k in ("avg", "best", "worst")) if paper else "-"
        reads = reads_text(s.get("reads"))
        runs = f"{s['runs']}" + (f" ({s['failed']} missing)" if s["failed"] else "")
        if not s["runs"]:
            lines.append(f"| {name} | {runs} | - | - | - | - | - | - | {paper_text} | {reads} |")
            continue
        ci = s["ci"]
        ci_text = f" [{_pct(ci[0])}, {_pct(ci[1])}]" if ci[0] is not None else ""
        lines.append(
            f"| {name} | {runs} | {_pct(s['avg'])}{ci_text} | {_pct(s['best'], 0)} | {_pct(s['worst'], 0)} "
            f"| {_pct(s['collision'])} | {_pct(s['timeout'])} | {s['spl']:.2f} | {paper_text} | {reads} |"
        )
    return "\n".join(lines)


def terms_section() -> str:
    """What the columns of :func:`markdown_table` mean, for a reader without the code."""
    from nirl_mj.inspect.figures import NIRL_PAPER, SPL_TEXT  # matplotlib: only where reports are written

    text = (
        "**Terms.** *success avg*: the mean over the runs of a run's success rate, the percentage of its "
        "tests (one per held-out arena) that reached the target; *best*, *worst*: the best and the worst "
        "run; *collision*, *timeout*: the mean percentage of tests that hit an obstacle or a wall, or used "
        f"up the step budget first; {SPL_TEXT} (here the mean over the runs); *paper avg / best / worst*: "
        f'the success the NIRL paper ({NIRL_PAPER}) reports in its Table I ("-": a method it does not '
        f"report); {READS_TERM}."
    )
    return textwrap.fill(text, 100, break_long_words=False, break_on_hyphens=False)


def runs_section(summary: dict) -> str:
    """Every run's success (percent), one row per method ("-": not finished or failed)."""
    runs = summary["runs"]
    lines = [f"| method | {' | '.join(str(r) for r in range(runs))} |", "|---|" + "---|" * runs]
    for name, s in summary["methods"].items():
        by_run = s.get("by_run", {})
        lines.append(f"| {name} | {' | '.join(_pct(by_run.get(r), 0) for r in range(runs))} |")
    return (
        "\n**Success per run** (percent; run r of every method shares its test arenas):\n\n"
        + "\n".join(lines)
        + "\n"
    )


def paired_section(summary: dict) -> str:
    """The first method minus each other, paired by run (empty with one method)."""
    names = list(summary["methods"])
    rows = [(n, s["paired"]) for n, s in summary["methods"].items() if s.get("paired", {}).get("runs")]
    if not rows:
        return ""
    lines = [
        "| against | runs | mean difference (SE) [95 % CI] | better / worse / equal |",
        "|---|---|---|---|",
    ]
    for name, p in rows:
        se = f" (SE {_pct(p['se'])})" if p["se"] is not None else ""
        ci = f" [{_pct(p['ci'][0])}, {_pct(p['ci'][1])}]" if p["ci"][0] is not None else ""
        mean = f"{100 * p['mean']:+.1f}"
        lines.append(
            f"| {name} | {p['runs']} | {mean}{se}{ci} | {p['better']} / {p['worse']} / {p['equal']} |"
        )
    return (f"\n**{names[0]} minus each method, paired by run** (points; over the runs both finished; "
            "95 % CI: Student t over the runs' differences):\n\n" + "\n".join(lines) + "\n")  # fmt: skip


CSV_COLUMNS = ("method", "runs", "failed", "tests", "success_avg", "success_ci_low", "success_ci_high",
               "success_best", "success_worst", "success_sd", "pooled_wilson_low", "pooled_wilson_high",
               "collision_avg", "timeout_avg", "physics_error_avg", "spl_avg", "paper_avg", "paper_best",
               "paper_worst")  # fmt: skip


def csv_table(summary: dict) -> str:
    """One row per method, rates as fractions (empty where undefined)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for name, s in summary["methods"].items():
        paper = s["paper"] or {}
        ci, wil = s.get("ci", [None, None]), s.get("wilson", [None, None])
        values = [name, s["runs"], s["failed"], s.get("tests"), s.get("avg"), ci[0], ci[1], s.get("best"),
                  s.get("worst"), s.get("sd"), wil[0], wil[1], s.get("collision"), s.get("timeout"),
                  s.get("physics_error"), s.get("spl"), paper.get("avg"), paper.get("best"),
                  paper.get("worst")]  # fmt: skip
        writer.writerow(["" if v is None else (f"{v:.6g}" if isinstance(v, float) else v) for v in values])
    return buffer.getvalue()


def bar_chart(path: Path, summary: dict, title: str) -> Path:
    """Average success per method, one row each in the table's order, with its 95 % interval and its
    best and worst run; the paper's row beside it (hatched) where the experiment gives one."""
    from nirl_mj.inspect.canvas import subplots

    names = list(summary["methods"])
    paired = any((summary["methods"][n]["paper"] or {}).get("avg") is not None for n in names)
    fig, ax = subplots(figsize=(6.6, 0.36 * len(names) * (1.5 if paired else 1) + 1.6), dpi=110)
    height = 0.38 if paired else 0.6
    labels = {"this work": True, "paper (Table I)": True, "best, worst run": True}

    def label(text: str) -> str | None:
        """Each legend entry once."""
        first, labels[text] = labels[text], False
        return text if first else None

    for i, name in enumerate(names):
        s = summary["methods"][name]
        paper = s["paper"] or {}
        offset = height / 2 if "avg" in paper else 0.0  # a row without the paper's keeps its bar centred
        if s["runs"]:
            ci = s["ci"]
            err = None if ci[0] is None else [[100 * (s["avg"] - ci[0])], [100 * (ci[1] - s["avg"])]]
            ax.barh(i - offset, 100 * s["avg"], height, color="tab:blue", xerr=err, capsize=3,
                    label=label("this work"))  # fmt: skip
            _extremes(ax, i - offset, s, "tab:red", label("best, worst run"))
        if "avg" in paper:
            ax.barh(i + offset, 100 * paper["avg"], height, color="white", edgecolor="tab:gray", hatch="//",
                    label=label("paper (Table I)"))  # fmt: skip
            if "best" in paper and "worst" in paper:
                _extremes(ax, i + offset, paper, "white", None)
    ax.set_yticks(range(len(names)), names, fontsize=9)
    ax.invert_yaxis()  # the table's first row on top
    ax.set_xlabel("success (%)")
    ax.set_xlim(0, 102)
    ax.set_xticks(range(0, 101, 10))
    ax.set_title("\n".join(textwrap.wrap(title, 72)), fontsize=9, pad=20)  # a long title keeps in the frame
    ax.grid(axis="x", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:  # none when every cell failed
        ax.legend(fontsize=8, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=3, frameon=False)
    fig.tight_layout()
    write_figure(path, fig)
    return path


def _extremes(ax, y: float, row: dict, face: str, label: str | None) -> None:
    """The best and worst run as two diamonds on row ``y`` (percent)."""
    ax.plot([100 * row["worst"], 100 * row["best"]], [y, y], linestyle="none", marker="D", ms=3.5,
            markerfacecolor=face, markeredgecolor="tab:red", label=label)  # fmt: skip


def chart_title(name: str, runs: int, tests: int, summary: dict) -> str:
    """The title of ``table.png``: the experiment, its size, a partial report's finished runs."""
    title = f"{name}: {runs} runs x {tests} tests"
    if summary.get("unfinished"):
        done = sorted({str(s["runs"]) for s in summary["methods"].values()}, key=int)
        title += f" (partial: {'-'.join(dict.fromkeys([done[0], done[-1]]))} runs finished)"
    return title + " (bars: mean with its 95 % CI)"


def demos_text(experiment: Experiment) -> str:
    """Which demonstrations the runs learn from, for a report."""
    if experiment.demos_per_run:
        return (
            f"{experiment.demos} demonstrations of its own (run r's seeded seed + r, shared by its methods)"
        )
    return f"the same {experiment.demos} demonstrations"


def write_outputs(out: Path, experiment: Experiment, summary: dict, results: dict) -> list[Path]:
    """table.md, table.csv, rows.csv, table.png and results.json in ``out``."""
    bar_chart(
        out / "table.png", summary, chart_title(experiment.name, experiment.runs, experiment.tests, summary)
    )
    text = f"""# {experiment.name}{" (quick)" if experiment.quick else ""}: {experiment.description}

{experiment.runs} runs per method, each trained with its own seed on {demos_text(experiment)}
({experiment.expert} expert) and tested on {experiment.tests} held-out arenas
({experiment.test_domain} domain) of
`{experiment.test_task.name}` ({experiment.test_task.arena.static_obstacles} static and
{experiment.test_task.arena.moving_obstacles} moving obstacles, {experiment.test_task.control.speed:g} m/s,
{experiment.test_task.robot.drive} drive); the runs of one seed share their test arenas. Rates in percent;
95 % CI: Student t over the runs' success rates (training seeds and test sampling both inside it).

{markdown_table(summary)}

{terms_section()}

![success per method](table.png)

*Figure. Success (y, percent of a run's {experiment.tests} tests that reached the target) per method (x):
the bar is the mean over the runs with its 95 % CI, the red diamonds the best and the worst run; the
hatched bar beside it, where there is one, is the success the NIRL paper reports in its Table I.*
{runs_section(summary)}{paired_section(summary)}{failed_section(summary)}"""
    write_text(out / "table.md", text)
    write_text(out / "table.csv", csv_table(summary))
    write_text(out / "rows.csv", tidy.csv_text(tidy_rows(experiment, results)))
    write_text(out / "results.json", json.dumps({**summary, "cells": results}, indent=1))
    return [out / "table.md", out / "table.csv", out / "rows.csv", out / "table.png", out / "results.json"]


def tidy_rows(experiment: Experiment, results: dict) -> list[dict]:
    """One tidy row per finished (method, run) (``nirl_mj.experiments.tidy``; no axis)."""
    return [tidy.row(experiment.name, "", "", m.name, r, results[cell_id(m.name, r)])
            for m in experiment.methods for r in range(experiment.runs)
            if cell_id(m.name, r) in results]  # fmt: skip


def write_strip(out: Path, experiment: Experiment, jobs: dict, log: Callable[[str], None]) -> Path | None:
    """OUT/strip.png: the strip method's first run (finished) on its first test arena (Fig. 8);
    None (logged) if nothing can render here."""
    strip = experiment.strip
    job = jobs[strip.method, 0]
    try:
        from nirl_mj.inspect.video import RenderError, snapshot_strip
    except ImportError as exc:  # written by another module; absent in an old checkout
        log(f"strip: nirl_mj.inspect.video.snapshot_strip is not available ({exc})")
        return None
    try:
        policy = policy_of(job)  # a finished run: loads it
        # the experiment's own figure, drawn again on every report
        frame = (strip.snapshots, strip.camera, strip.width, strip.height)
        path = snapshot_strip(experiment.test_task, policy, job.test_seeds[0], out / "strip.png", *frame,
                              overwrite=True)  # fmt: skip
    except (RenderError, OSError, RuntimeError, ValueError) as exc:
        log(f"strip: not written: {exc}")
        return None
    log(f"strip: {path}")
    return path
