"""Cost of the suites (tasks/suites/*.toml): core time of their finished cells, projected to whole suites.

Reads the cell times of ``nirl-mj suite`` output directories (finished or partial): the core time
per method and cell, the whole suite's projected core time (each method's mean cell time times its
cells in the full suite: every value and run of a training axis, or every run of test axes, with the
methods that read no demonstrations once per run), and the machines of ``--cores`` cores that would
finish it within an hour, every cell independent, at ``--efficiency`` scaling per worker
(bench/bench_executors.py). A method with no finished cell in a suite is estimated from its mean
cell time in ``--table`` (a Table I directory: a training on 30 demonstrations and 100 tests; of
several, the first that timed the method) times the suite's median ratio of its measured methods'
cells to their Table I cells (the transfer suite's cells test 16 points of 50 arenas), and marked so.
Writes its section of docs/PERFORMANCE.md.

    python bench/bench_suites.py runs/demos runs/quality runs/transfer [--table runs/table1_fair ...]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
from pathlib import Path

from nirl_mj.experiments.definition import Experiment, load_experiment
from nirl_mj.experiments.suite_cells import reads_demonstrations

try:
    from report import markdown_table, write_section
except ImportError:  # run as a module
    from bench.report import markdown_table, write_section


def cell_seconds(out: Path) -> dict[str, list[float]]:
    """Seconds of every finished cell, by method (the id's part between the value's "." and "-run")."""
    times: dict[str, list[float]] = {}
    for path in sorted((out / "cells").glob("*.json")):
        record = json.loads(path.read_text())
        if "seconds" in record:
            method = record["id"].rsplit("-run", 1)[0].rsplit(".", 1)[-1]
            times.setdefault(method, []).append(float(record["seconds"]))
    return times


def cells_per_method(experiment: Experiment) -> dict[str, int]:
    """How many cells each method has in the whole suite."""
    (axis, *_) = experiment.axes
    if not axis.trains:
        return {m.name: experiment.runs for m in experiment.methods}
    return {m.name: experiment.runs * (len(axis.values) if reads_demonstrations(m, axis) else 1)
            for m in experiment.methods}  # fmt: skip


def report(dirs: list[Path], efficiency: float, cores: int, tables: list[Path] | None = None) -> str:
    lines, total = [], 0.0
    table_times: dict[str, list[float]] = {}
    for table in tables or []:  # each method's times from the first directory that timed it
        for method, seconds in cell_seconds(table).items():
            table_times.setdefault(method, seconds)
    for out in dirs:
        saved = json.loads((out / "experiment.json").read_text())
        name = out.name
        experiment = load_experiment(f"suites/{name}")
        if saved.get("axes") != experiment.identity()["axes"]:
            raise SystemExit(f"{out} does not hold the axes of tasks/suites/{name}.toml")
        times, counts = cell_seconds(out), cells_per_method(experiment)
        rows, projected, missing = [], 0.0, []
        # a suite's cell against the same method's Table I cell (the transfer suite tests 16 points)
        both = [m for m in times if table_times.get(m)]
        ratio = (
            statistics.median(statistics.mean(times[m]) / statistics.mean(table_times[m]) for m in both)
            if both
            else 1.0
        )
        for method, n in counts.items():
            t = times.get(method)
            if not t and table_times.get(method):
                estimate = statistics.mean(table_times[method]) * ratio * n / 3600
                projected += estimate
                median = f"({statistics.median(table_times[method]):.0f}, Table I)"
                rows.append([method, f"0 of {n}", median, "0", f"{estimate:.2f} (estimated, x{ratio:.1f})"])
                continue
            if not t:
                missing.append(method)
                continue
            projected += statistics.mean(t) * n / 3600
            rows.append([method, f"{len(t)} of {n}", f"{statistics.median(t):.0f}",
                         f"{sum(t) / 3600:.2f}", f"{statistics.mean(t) * n / 3600:.2f}"])  # fmt: skip
        total += projected
        done = sum(sum(t) for t in times.values()) / 3600
        lines += [f"**{name}** (`{out}`): {done:.1f} core-hours in its {sum(len(t) for t in times.values())} "
                  f"finished cells; the whole suite: **{projected:.1f} core-hours**"
                  + (f" (not measured: {', '.join(missing)})" if missing else ""), "",
                  markdown_table(["method", "cells finished", "median (s)", "core-hours so far",
                                  "core-hours, whole suite"], rows), ""]  # fmt: skip
    machines = math.ceil(total / (cores * efficiency))
    lines += [f"All {len(dirs)} suites: **{total:.1f} core-hours** (target: 24; methods neither measured "
              "nor in a Table I directory are not in it); machines of "
              f"{cores} cores to finish them within an hour at {efficiency:.0%} scaling per worker: "
              f"**{machines}**. Cell times as they ran: the cells shared the 2 cores with other work, so "
              "they err long."]  # fmt: skip
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dirs", nargs="+", type=Path)
    parser.add_argument("--efficiency", type=float, default=0.964)
    parser.add_argument("--cores", type=int, default=2)
    parser.add_argument(
        "--table",
        type=Path,
        action="append",
        help="a Table I output directory (repeat it: each method's cell times from the first that has them)",
    )
    args = parser.parse_args()
    body = report(args.dirs, args.efficiency, args.cores, args.table)
    print(body)
    write_section("Suites (bench/bench_suites.py)", body)


if __name__ == "__main__":
    main()
