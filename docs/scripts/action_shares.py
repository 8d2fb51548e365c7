"""How a Stable-Baselines3 row's selected policies drive: each run's policy, driven as its tests drive it
(sampled or by its mode, as the run's settings say), on ``--arenas`` arenas of the validation domain of
its own seed (a diagnostic: never a test arena, and no selection reads it), with its success and the
share of its decisions that took each action:

    python docs/scripts/action_shares.py OUT METHOD [METHOD ...] [--runs N] [--arenas 20] [--write FILE]

OUT is a compare experiment's ``--out`` (its runs OUT/runs/METHOD/SEED, run r of seed ``experiment
seed + r``); runs still training are skipped. ``--write`` stores the lines atomically (with the
command as the first line).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from rl_free_actions import emit, finished_runs  # docs/scripts, beside this file

from nirl_mj.data.features import ACTION_NAMES


def lines(out: Path, method: str, runs: int | None, arenas: int) -> list[str]:
    """One line per finished run of ``method`` in ``out``: its success and action shares (percent)."""
    from nirl_mj.experiments.evaluation import evaluate
    from nirl_mj.experiments.rl import load_rl_policy
    from nirl_mj.experiments.seeds import domain_seeds
    from nirl_mj.sim import spec as specs
    from nirl_mj.sim.task import make_env

    found = []
    for run, run_dir, record in finished_runs(out, method, runs):
        run_seed = int(run_dir.name)
        policy, _ = load_rl_policy(run_dir, seed=run_seed)
        env = make_env(specs.from_dict(record["task"], str(run_dir / "run.json")))
        metrics, episodes = evaluate(env, policy, domain_seeds("validation", run_seed, arenas))
        actions = np.concatenate([t.actions for t in episodes])
        shares = 100 * np.bincount(actions, minlength=len(ACTION_NAMES)) / len(actions)
        reached = round(metrics["success_rate"] * arenas)
        per_action = "  ".join(f"{n} {v:4.1f}" for n, v in zip(ACTION_NAMES, shares, strict=True))
        found.append(f"{method}  run {run:2d}  success {reached:2d}/{arenas}  {per_action}")
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("methods", nargs="+", metavar="METHOD")
    parser.add_argument("--runs", type=int, default=None, help="runs 0..N-1 (default: all finished)")
    parser.add_argument("--arenas", type=int, default=20, help="validation arenas per run (default 20)")
    parser.add_argument("--write", type=Path, default=None, help="store the lines in this file")
    args = parser.parse_args()
    if args.arenas < 1:
        raise SystemExit(f"--arenas {args.arenas}: must be >= 1")
    header = [f"# python docs/scripts/action_shares.py {' '.join(sys.argv[1:])}",
              "# method, run, successes on the validation arenas of its seed, "
              "percent of decisions per action"]  # fmt: skip
    body = [line for method in args.methods for line in lines(args.out, method, args.runs, args.arenas)]
    emit(header, body, args.write, f"{args.out}: no finished RL run of {', '.join(args.methods)}")


if __name__ == "__main__":
    main()
