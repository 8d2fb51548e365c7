"""Cost of the Table I protocol (tasks/table1.toml): wall time, and core time per method.

Runs the protocol as ``nirl-mj compare`` does, but with ``--runs`` runs (default 2)
instead of 25, on the local executor with ``--workers`` processes, in a temporary
directory (demonstrations included), and projects the 25-run wall time from it:
demonstrations + cells' wall x 25 / runs. The cells of a run are independent and
the experiment has 19 x 25 of them; the short run's tail (a worker idle while the
last cell finishes) is multiplied too, so the projection errs on the long side.
With ``--existing DIR``, it also reads the cell times of a finished
(or partial) ``nirl-mj compare`` directory: the core time the real protocol took.
Target (issue #6): the full protocol within 90 minutes on a 2-core machine; issue 31 set 5 hours for
its fair protocol (more methods, 50,000-decision reinforcement learners). ``--section`` names the
section written, so that another machine's figures can stand beside the first.
With ``--existing-only`` it times nothing new and reports the existing directory's cells alone,
with the core-minutes per run of each method and how many 2-core machines would bring the
25-run protocol under 15 minutes: every cell is independent, so with M machines the wall time is
at least max(total core time / (2 M efficiency), the longest cell); ``--efficiency`` is the
executor's measured scaling (bench/bench_executors.py: a local 2-worker Ray cluster, warm).
Writes docs/PERFORMANCE.md.

    python bench/bench_table1.py [--runs 2] [--workers 2] [--existing runs/table1] [--quick]
    python bench/bench_table1.py --existing runs/table1 --existing-only [--efficiency 1.0]
    python bench/bench_table1.py --existing runs/table1 --existing-only --window-until ISO [--window-dir DIR]
    python bench/bench_table1.py --existing runs/t1 --existing-only --section "Table I protocol, runs 0-1"
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import math
import statistics
import tempfile
import time
from pathlib import Path

from nirl_mj.experiments.compare import run_compare
from nirl_mj.experiments.definition import load_experiment
from nirl_mj.experiments.protocol import Execution, prepare

try:
    from report import markdown_table, write_section
except ImportError:  # run as a module
    from bench.report import markdown_table, write_section

TARGET_MIN = 90.0
SECTION = "Table I protocol"


def cell_seconds(out: Path) -> dict[str, list[float]]:
    """Seconds of every finished cell in ``out``/cells that was timed, by method (a cell restored
    from published results, docs/scripts/restore_cells.py, has no time)."""
    times: dict[str, list[float]] = {}
    for path in sorted((out / "cells").glob("*.json")):
        record = json.loads(path.read_text())
        if "seconds" not in record:
            continue
        method = record["id"].rsplit("-run", 1)[0]
        times.setdefault(method, []).append(float(record["seconds"]))
    return times


def method_rows(times: dict[str, list[float]]) -> list[list[str]]:
    """Per method: cells, median and total core seconds."""
    rows = [[m, str(len(t)), f"{statistics.median(t):.0f}", f"{sum(t) / 60:.1f}"] for m, t in times.items()]
    total = sum(sum(t) for t in times.values())
    per_run = sum(statistics.median(t) for t in times.values())
    rows.append(["all (one run: sum of medians)", "", f"{per_run:.0f}", f"{total / 60:.1f}"])
    return rows


def window_efficiency(out: Path, workers: int, until: str) -> tuple[float, str]:
    """The executor's measured scaling: the core time of the cells ``out`` computed itself (not
    reused) and finished by ``until`` (ISO time, UTC), over ``workers`` x the window from the first
    such cell's start to the last one's end (file times). A cell still running at the window's end
    is not counted, so this errs low; a directory resumed after a pause, or copied without its file
    times, gives a meaningless figure. Returns the efficiency and a sentence saying how it was measured."""
    limit_time = datetime.datetime.fromisoformat(until)
    if limit_time.tzinfo is None:
        limit_time = limit_time.replace(tzinfo=datetime.UTC)
    limit = limit_time.timestamp()
    spans = []
    for path in (out / "cells").glob("*.json"):
        record, end = json.loads(path.read_text()), path.stat().st_mtime
        if "reused_from" not in record and "seconds" in record and end <= limit:
            spans.append((end - float(record["seconds"]), end, float(record["seconds"])))
    if not spans:
        raise SystemExit(f"--window-until {until}: no cell of {out} finished by then")
    start, end = min(s[0] for s in spans), max(s[1] for s in spans)
    busy = sum(s[2] for s in spans)
    efficiency = busy / (workers * (end - start))
    when = f"{datetime.datetime.fromtimestamp(start, datetime.UTC):%Y-%m-%d %H:%M} UTC"
    text = (f"Scaling measured on the cells `{out}` computed itself: {len(spans)} cells, "
            f"{busy / 60:.1f} core-minutes of cells in a {(end - start) / 60:.1f}-minute window from {when} "
            f"on {workers} workers: "
            f"**{efficiency:.1%}** (cells still running at the window's end not counted).")  # fmt: skip
    return efficiency, text


def existing_report(out: Path, runs: int, efficiency: float, minutes: float = 15.0, cores: int = 2) -> str:
    """Core-minutes per run of each method in ``out``'s cells, the protocol's projected core time and
    the 2-core machines it needs to finish within ``minutes``."""
    times = cell_seconds(out)
    if not times:
        raise SystemExit(f"{out}: no cell there records its time (restored and published cells carry "
                         "none): give the output of a `nirl-mj compare` that computed its cells")  # fmt: skip
    rows = [[m, str(len(t)), f"{statistics.median(t):.0f}", f"{statistics.mean(t) / 60:.1f}",
             f"{max(t) / 60:.1f}"] for m, t in times.items()]  # fmt: skip
    per_run = sum(statistics.mean(t) for t in times.values()) / 60
    longest = max(max(t) for t in times.values()) / 60
    protocol = per_run * runs
    machines = math.ceil(protocol / (minutes * cores * efficiency))
    lines = [
        f"The cells of `{out}` ({sum(len(t) for t in times.values())} cells of {len(times)} methods; core "
        "time of each cell as it ran, 2 workers on 2 cores, so each cell shared the machine with one other):",
        "",
        markdown_table(["method", "cells", "median (s)", "core-min per run (mean)", "longest (min)"], rows),
        "",
        f"One run of every method: **{per_run:.0f} core-minutes**; the {runs}-run protocol: "
        f"**{protocol:.0f} core-minutes**, {protocol / cores:.0f} min on one {cores}-core machine "
        f"(issue 31's target, 5 hours, is {'met' if protocol / cores <= 300 else 'not met'}).",
        f"Machines of {cores} cores to finish within {minutes:.0f} minutes, every cell independent, at "
        f"{efficiency:.0%} scaling per worker: **{machines}** (the longest cell, {longest:.1f} min, "
        f"{'fits' if longest <= minutes else 'does not fit'} in {minutes:.0f} minutes).",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=2, help="runs to time (the protocol has 25)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--existing", type=Path, help="a `nirl-mj compare` directory to read cell times from")
    parser.add_argument("--quick", action="store_true", help="the protocol's [quick] version (a smoke test)")
    parser.add_argument("--no-write", action="store_true", help="print only")
    parser.add_argument("--existing-only", action="store_true", help="report --existing alone (time nothing)")
    parser.add_argument("--efficiency", type=float, default=1.0,
                        help="the executor's scaling per worker, for the machine estimate")  # fmt: skip
    parser.add_argument("--window-until", metavar="ISO", default=None,
                        help="with --existing-only: measure the scaling on the cells of --window-dir "
                        "(default --existing) finished by then (UTC), instead of --efficiency")  # fmt: skip
    parser.add_argument("--window-dir", type=Path, default=None, help="see --window-until")
    parser.add_argument("--section", default=SECTION, metavar="TITLE",
                        help="the section of docs/PERFORMANCE.md to write (another machine's figures "
                             "beside the first, say)")  # fmt: skip
    args = parser.parse_args()
    if args.runs < 1 or args.workers < 1:
        parser.error(f"--runs {args.runs} --workers {args.workers}: both must be at least 1")
    if args.existing and not (args.existing / "cells").is_dir():
        parser.error(f"--existing {args.existing}: not a `nirl-mj compare` directory (no cells/ in it)")

    if args.existing_only:
        if not args.existing:
            parser.error("--existing-only needs --existing DIR")
        efficiency, measured = args.efficiency, ""
        if args.window_until:
            window_dir = args.window_dir or args.existing
            efficiency, measured = window_efficiency(window_dir, args.workers, args.window_until)
        body = existing_report(args.existing, load_experiment("table1").runs, efficiency)
        body += f"\n\n{measured}" if measured else ""
        print(body)
        if not args.no_write:
            write_section(f"{args.section} (bench/bench_table1.py)", body)
        return

    full = load_experiment("table1", quick=args.quick)
    experiment = dataclasses.replace(full, runs=args.runs)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "table1"
        execution = Execution("local", args.workers)
        t0 = time.perf_counter()
        prepare(experiment, out, execution, log=lambda _: None)  # the demonstrations, made once
        demos = time.perf_counter() - t0
        run_compare(experiment, out, execution, log=lambda _: None)
        wall = time.perf_counter() - t0
        times = cell_seconds(out)
    cells_wall = wall - demos
    projected = demos + cells_wall * full.runs / args.runs
    # Perfect packing: every worker busy until the end (the limit for many cells).
    packed = demos + sum(map(sum, times.values())) * full.runs / args.runs / args.workers
    verdict = "met" if projected / 60 <= TARGET_MIN else "not met"
    lines = [
        f"{args.runs} runs of the {len(full.methods)} methods ({len(full.methods) * args.runs} cells of "
        f"{full.tests} tests), local executor, {args.workers} workers, from an empty directory: "
        f"**{wall / 60:.1f} min wall**. Projected to the protocol's {full.runs} runs: "
        f"**{projected / 60:.0f} min** from the wall time, {packed / 60:.0f} min from the cells' core "
        f"time with every worker busy"
        + ("." if args.quick else f" (target {TARGET_MIN:.0f} min: {verdict})."),
        "",
        "Core time per cell (s) and in all (min), this run:",
        "",
        markdown_table(["method", "cells", "median (s)", "total (min)"], method_rows(times)),
    ]
    if args.existing:
        existing = cell_seconds(args.existing)
        n = sum(len(t) for t in existing.values())
        total = sum(sum(t) for t in existing.values())
        lines += [
            "",
            f"The cells of `{args.existing}` ({n} cells, run in several sessions on a machine shared with "
            f"other work): {total / 60:.0f} core-minutes, {total / 60 / args.workers:.0f} min on "
            f"{args.workers} fully used cores.",
            "",
            markdown_table(["method", "cells", "median (s)", "total (min)"], method_rows(existing)),
        ]
    body = "\n".join(lines)
    print(body)
    if not (args.no_write or args.quick):
        write_section(f"{args.section} (bench/bench_table1.py)", body)


if __name__ == "__main__":
    main()
