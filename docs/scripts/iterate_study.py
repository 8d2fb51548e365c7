"""Does selection or training limit a learner? Success of several kept iterates of training runs on
development arenas (the ``test`` domain, never the reported ``final`` one), beside the iterate that
the first best score picks (the loop's rule before commit 6c30c7d, which made every method keep the
latest of its best: ``nirl_mj.learn.selection``) and the one the latest best picks (the rule since).

For runs of the NIRL loop (they keep every iterate's weights in checkpoint.npz). Each run is tested
on ``--tests`` development arenas of its own seed, skipping every arena it has seen, so every
iterate of one run meets the same arenas and the rows are paired.

Usage: python docs/scripts/iterate_study.py RUN_DIR [RUN_DIR ...] [--tests 30] [--every 10] [--json F]
Prints one line per run: its scores' ties, the picked iterates and each tested iterate's success.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def picks(scores: np.ndarray) -> dict[str, int]:
    """The iterate the first best score picks (the loop's rule before 6c30c7d) and the one the last
    best picks (``latest_best``, the rule since)."""
    from nirl_mj.learn.selection import latest_best

    return {"first_best": int(np.argmax(scores)), "last_best": latest_best(scores.tolist())}


def study(run_dir: Path, tests: int, every: int) -> dict:
    from nirl_mj.data.rundir import RunDir
    from nirl_mj.experiments import seeds, training
    from nirl_mj.experiments.protocol import evaluate_policy

    missing = [name for name in ("run.json", "checkpoint.npz") if not (Path(run_dir) / name).is_file()]
    if missing:
        raise SystemExit(f"error: {run_dir}: not a training run of the IRL loop (no {' or '.join(missing)})")
    task, _config, _demos, seed = training.saved_settings(run_dir)
    record = RunDir(run_dir).read_record()
    scores = np.asarray(RunDir(run_dir).read_checkpoint()["scores"], dtype=float)
    chosen = picks(scores)
    arenas = tuple(seeds.held_out_seeds(seed, tests, seeds.seen_seeds(record), "test"))
    iterates = sorted({*range(every - 1, len(scores), every), 0, len(scores) - 1, *chosen.values()})
    success = {}
    for i in iterates:
        policy, _ = training.load_policy(run_dir, str(i))
        success[i] = evaluate_policy(policy, task, arenas, "nirl")["success_rate"]
    return {"run": str(run_dir), "ties": int((scores == scores.max()).sum()), **chosen, "success": success}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--tests", type=int, default=30)
    parser.add_argument("--every", type=int, default=10)
    parser.add_argument("--json", type=Path, help="also write the rows to this JSON file")
    args = parser.parse_args(argv)
    rows = []
    for run in args.runs:
        row = study(run, args.tests, args.every)
        rows.append(row)
        s = {i: round(100 * v) for i, v in row["success"].items()}
        tested = " ".join(f"{i}:{v}" for i, v in s.items())
        first, last = row["first_best"], row["last_best"]
        print(f"{run}  ties {row['ties']}  first-best {first} ({s[first]} %)  last-best {last} ({s[last]} %)"
              f"  best tested {max(s.values())} %  | {tested}", flush=True)  # fmt: skip
    if args.json:
        from nirl_mj.data.atomic import write_text

        write_text(args.json, json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
