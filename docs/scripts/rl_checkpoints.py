"""The selected and the last checkpoint of a compare experiment's Stable-Baselines3 rows, each on
its run's own test arenas (the experiment's, as its cells drew them): does the selection help?

    python docs/scripts/rl_checkpoints.py TASK OUT METHOD [METHOD ...] [--runs N] [--workers 2] [--mode]

TASK is the experiment file and OUT its ``--out``; every run must be finished. The selected
checkpoint's success must equal its cell's (checked: the same arenas and the same seeded sampling);
prints, per method, each run's selected and last success (percent), both driven as the run's tests
drive it (its ``act`` setting), and their averages. ``--mode`` adds the selected checkpoint driven by
its policy's mode.
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from nirl_mj.experiments.compare import cell_id
from nirl_mj.experiments.definition import load_experiment
from nirl_mj.experiments.protocol import demos_path, evaluate_policy, run_jobs


def _rates(task_file: str, out: str, method: str, run: int, mode: bool = False) -> tuple[float | int, ...]:
    """(run, the cell's success, the selected checkpoint's, the last's[, the selected one's mode's])
    of ``method``'s run ``run``."""
    from nirl_mj.experiments.rl import load_rl_policy

    experiment = load_experiment(task_file)
    job = run_jobs(experiment, Path(out), {run: demos_path(Path(out), experiment, run)})[method, run]
    cell = json.loads((Path(out) / "cells" / f"{cell_id(method, run)}.json").read_text())["result"]
    rates = [cell["success_rate"]]
    for which, sampled in (("selected", None), ("last", None), *((("selected", False),) if mode else ())):
        policy, _ = load_rl_policy(job.run_dir, policy=which, sampled=sampled)
        rates.append(evaluate_policy(policy, job.task, job.test_seeds, method)["success_rate"])
    return (run, *rates)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task")
    parser.add_argument("out")
    parser.add_argument("methods", nargs="+")
    parser.add_argument("--runs", type=int, default=None, help="runs 0..N-1 (default: the experiment's)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--mode", action="store_true", help="also the selected checkpoint's mode (greedy)")
    args = parser.parse_args()
    runs = range(args.runs or load_experiment(args.task).runs)
    with ProcessPoolExecutor(args.workers) as pool:
        for method in args.methods:
            jobs = [(args.task, args.out, method, r, args.mode) for r in runs]
            rows = sorted(pool.map(_rates, *zip(*jobs, strict=True)))
            for run, cell, selected, *_ in rows:
                if selected != cell:
                    raise SystemExit(f"{method} run {run}: the selected checkpoint scores {selected}, its "
                                     f"cell {cell}: not the experiment's arenas or checkpoint")  # fmt: skip
            columns = (("selected", 2), ("last", 3), *((("selected mode", 4),) if args.mode else ()))
            for label, column in columns:
                values = [round(100 * row[column]) for row in rows]
                print(f"{method} {label}: {' '.join(map(str, values))} -> average "
                      f"{sum(100 * row[column] for row in rows) / len(rows):.1f} %")  # fmt: skip


if __name__ == "__main__":
    main()
