"""Which reward features a trained IRL row's selected reward uses, run by run.

    python docs/scripts/reward_support.py OUT METHOD [METHOD ...]
    (OUT: a compare experiment's --out)

Prints, per run: the test success of the run's cell, the number of non-zero components of theta
(of 162 with the "bearing" features), the largest ones, and the share of the experiment's
demonstrated pairs whose action the reward alone ranks first (argmax_a theta^T f(s, a); always
"forward" scores the expert's share of forward actions, 91.5 % for Table I's demonstrations).
Written to show that RE's Hoeffding L1 widths leave two components of theta in each of Table I's
runs whose training directory is kept (runs 16-24 at 41e1690; docs/notebook/algorithm.md,
"Why RE per-state is unsteady").
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from nirl_mj.data.dataset import load_dataset
from nirl_mj.data.trajectory import stack_pairs
from nirl_mj.learn.reward import RewardModel


def main(out: Path, methods: list[str]) -> None:
    phi, actions = stack_pairs(load_dataset(out / "demos.npz"))
    actions = actions.astype(int)
    print(f"{len(actions)} demonstrated pairs, {np.mean(actions == 0):.1%} of them forward")
    for method in methods:
        if not (out / "runs" / method).is_dir():
            trained = sorted(p.name for p in (out / "runs").glob("*") if p.is_dir())
            raise SystemExit(f"{method}: no training runs in {out / 'runs'} (it holds: {', '.join(trained)})")
        runs = sorted((out / "runs" / method).iterdir(), key=lambda p: int(p.name))
        for run in runs:
            if not (run / "reward.json").exists():  # still training
                continue
            cell = out / "cells" / f"{method}-run{int(run.name):03d}.json"
            result = json.loads(cell.read_text())["result"] if cell.exists() else {}
            success = result.get("success_rate", float("nan"))
            reward = RewardModel.from_dict(json.loads((run / "reward.json").read_text()))
            named = {k: v for k, v in reward.named().items() if abs(v) > 1e-9}
            ranked = np.argmax(reward.rewards_all_actions(phi), axis=1)
            top = sorted(named.items(), key=lambda kv: -abs(kv[1]))[:3]
            print(
                f"{method} run {run.name:>2}: success {success:5.0%}  non-zero {len(named):3d}  "
                f"demonstrated actions ranked first {np.mean(ranked == actions):.1%}  "
                + ", ".join(f"{k} {v:+.2f}" for k, v in top)
            )


if __name__ == "__main__":
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    main(Path(sys.argv[1]), sys.argv[2:])
