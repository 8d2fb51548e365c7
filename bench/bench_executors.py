"""Parallel efficiency of the experiment executors (nirl_mj/experiments/executors.py).

A fixed set of real cells (``nirl_mj.experiments.compare.compare_cell``: the rule policy
on ``--tests`` held-out arenas of tasks/navigate.toml, tyre drive, a different
set of arenas per cell; 40 tests take about 8 s, still shorter than an
experiment's cells, 10 s to a few minutes, so the start-up weighs more here)
runs on the serial executor, on 1 and 2 local processes, and on a local Ray
cluster of 1 and 2 CPUs. Each pool runs the cells twice: *cold* (including
starting its processes or Ray) and *warm* (the same executor again: what the
many cells of a long experiment see). Parallel efficiency from 1 to 2 workers
= T1 / (2 T2) (target: at least 85 %). Every executor must give the results of
the serial one. A pure-Python loop in 1 and 2 processes, before and after,
gives the machine's own ceiling at the time: on a shared machine no executor
can do better. Writes docs/PERFORMANCE.md.

    python bench/bench_executors.py [--cells 8] [--tests 40] [--no-ray]
"""

from __future__ import annotations

import argparse
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor

from nirl_mj.experiments.compare import compare_cell
from nirl_mj.experiments.definition import BUILTIN_METHODS
from nirl_mj.experiments.executors import Cell, Executor
from nirl_mj.experiments.protocol import RunJob
from nirl_mj.experiments.seeds import domain_seeds
from nirl_mj.sim.spec import load_task

try:
    from report import markdown_table, write_section
except ImportError:  # run as a module
    from bench.report import markdown_table, write_section


HEADER = ["executor", "workers", "cold wall (s)", "warm wall (s)", "efficiency (cold)", "efficiency (warm)"]


def cells(count: int, tests: int) -> list[Cell]:
    """``count`` cells of ``tests`` episodes each, on disjoint test arenas."""
    task = load_task("navigate")
    out = []
    for i in range(count):
        seeds = tuple(domain_seeds("test", 0, tests, start=i * tests))
        job = RunJob(BUILTIN_METHODS["rule"], i, 0, task, "", "", {}, seeds)
        out.append(Cell(f"bench-{i:02d}", compare_cell, (job, task)))
    return out


def spin(n: int) -> float:
    """Seconds of ``n`` iterations of a pure-Python loop (no memory traffic, no libraries)."""
    t0 = time.perf_counter()
    total = 0
    for i in range(n):
        total += i * i
    return time.perf_counter() - t0


def ceiling(n: int = 20_000_000) -> float:
    """Parallel efficiency of a perfectly parallel job on 2 processes right now: T1 / T2."""
    one = spin(n)
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        pool.submit(spin, 1).result()  # started
        two = max(pool.map(spin, [n, n]))
    return one / two


def timed(executor: str, workers: int, work: list[Cell]) -> tuple[float, float, dict]:
    """Wall seconds of a cold and of a warm run of ``work``, and the results."""
    with Executor(executor, workers, retries=0) as runner:
        t0 = time.perf_counter()
        first = runner.run(work)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        second = runner.run(work)
        warm = time.perf_counter() - t0
    if first.failures or second.failures:
        raise RuntimeError(f"{executor}: failed cells {list(first.failures) + list(second.failures)}")
    if first.results != second.results:
        raise RuntimeError(f"{executor}: a second run gave other results")
    return cold, warm, first.results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=8)
    parser.add_argument("--tests", type=int, default=40, help="episodes per cell")
    parser.add_argument("--no-ray", action="store_true", help="skip the Ray executor")
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args()
    work = cells(args.cells, args.tests)
    before = ceiling()
    print(f"machine ceiling (pure loop, 1 -> 2 processes): {before:.0%}")
    t0 = time.perf_counter()
    reference = Executor("serial").run(work).results
    serial = time.perf_counter() - t0
    print(f"serial: {serial:.1f} s")
    configs = [("local", 1), ("local", 2)] + ([] if args.no_ray else [("ray", 1), ("ray", 2)])
    times = {}
    for executor, workers in configs:
        cold, warm, results = timed(executor, workers, work)
        if results != reference:
            raise RuntimeError(f"{executor} with {workers} worker(s) gave other results than serial")
        times[executor, workers] = (cold, warm)
        print(f"{executor} x{workers}: cold {cold:.1f} s, warm {warm:.1f} s")

    after = ceiling()
    print(f"machine ceiling after: {after:.0%}")
    rows = [["serial (this process)", "1", f"{serial:.1f}", f"{serial:.1f}", "-", "-"]]
    for (executor, workers), (cold, warm) in times.items():
        if workers == 1:
            eff_cold = eff_warm = "-"
        else:
            one_cold, one_warm = times[executor, 1]
            eff_cold = f"{one_cold / (workers * cold):.0%}"
            eff_warm = f"{one_warm / (workers * warm):.0%}"
        rows.append([executor, str(workers), f"{cold:.1f}", f"{warm:.1f}", eff_cold, eff_warm])
    body = (
        f"{args.cells} cells, each the rule policy on {args.tests} held-out arenas of tasks/navigate.toml "
        "(tyre drive, 20 obstacles; `compare_cell`, as `nirl-mj compare` runs them). *Cold*: a fresh "
        "executor (process start-up, imports, Ray start); *warm*: the same executor again, as the many "
        "cells of a long experiment see it. Efficiency from 1 to N workers = T1 / (N TN) (target: at "
        "least 85 % from 1 to 2). Every executor gave the serial results. The machine's ceiling (a "
        f"pure-Python loop, 1 -> 2 processes): {before:.0%} before, {after:.0%} after.\n\n"
    )
    if min(before, after) < 0.9:
        body += (
            "The machine was shared during this run (ceiling under 90 %): these efficiencies measure its "
            "load as much as the executors; rerun on a quiet machine.\n\n"
        )
    body += markdown_table(HEADER, rows)
    print(body)
    if not args.no_write:
        write_section("Experiment executors (bench/bench_executors.py)", body)


if __name__ == "__main__":
    main()
