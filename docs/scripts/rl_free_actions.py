"""What a Stable-Baselines3 row's policies do in free space: the greedy action (its mode) of each run's
selected and last checkpoint in the 18 states with nothing within sensing range (every D and U 0), by
the target's sector V (1..9: ahead, then 40-degree steps counter-clockwise) and the flag I:

    python docs/scripts/rl_free_actions.py OUT METHOD [--runs N] [--write FILE]

OUT is a compare experiment's ``--out`` (its runs OUT/runs/METHOD/SEED, run r of seed ``experiment
seed + r``); runs still training are skipped. Each line: a run, a checkpoint, its decisions, and the
action per V, I = 0 then I = 1, by letter: F forward, l left30, L left60, r right30, R right60, B
backward. ``--write`` stores the lines atomically (with the command as the first line).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from nirl_mj.data.atomic import write_text
from nirl_mj.data.features import N_FEATURES

LETTERS = "FlLrRB"  # the six actions in index order (data.features.ACTION_NAMES)
_V, _I = 7, 8


def free_states() -> np.ndarray:
    """The 18 free-space phi(s), shape (18, 16): V = 1..9 with I = 0, then with I = 1."""
    phi = np.zeros((18, N_FEATURES), dtype=np.float32)
    phi[:, _V] = np.tile(np.arange(1, 10), 2)
    phi[9:, _I] = 1.0
    return phi


def actions_line(policy) -> str:
    """The policy's action in each free state, as letters: 'V1..V9 | V1..V9' (I = 0 | I = 1)."""
    letters = "".join(LETTERS[int(policy(phi))] for phi in free_states())
    return f"{letters[:9]} | {letters[9:]}"


def finished_runs(out: Path, method: str, runs: int | None) -> list[tuple[int, Path, dict]]:
    """(run r, its directory, its record) of every finished RL run of ``method`` in the compare
    experiment ``out`` (its runs OUT/runs/METHOD/SEED, run r of seed ``experiment seed + r``), runs
    0..``runs``-1 only if given."""
    seed = json.loads((out / "experiment.json").read_text())["seed"]
    found = []
    for record_file in sorted((out / "runs" / method).glob("*/run.json"), key=lambda p: int(p.parent.name)):
        record = json.loads(record_file.read_text())
        run = int(record_file.parent.name) - seed
        if (runs is None or run < runs) and record.get("steps_done", 0) >= record["steps"]:
            found.append((run, record_file.parent, record))
    return found


def emit(header: list[str], body: list[str], write: Path | None, nothing: str) -> None:
    """Prints the header and body lines, and stores them atomically in ``write`` if given; exits
    with ``nothing`` when there is no body line."""
    if not body:
        raise SystemExit(nothing)
    text = "\n".join([*header, *body]) + "\n"
    if write:
        write_text(write, text)
    print(text, end="")


def lines(out: Path, method: str, runs: int | None) -> list[str]:
    """One line per finished run and checkpoint (selected, last) of ``method`` in ``out``."""
    from nirl_mj.experiments.rl import load_rl_policy

    found = []
    for run, run_dir, record in finished_runs(out, method, runs):
        for which in ("selected", "last"):
            policy, _ = load_rl_policy(run_dir, sampled=False, policy=which)
            steps = record["selected"]["steps"] if which == "selected" else record["steps_done"]
            found.append(f"run {run:2d} {which:8s} {steps:6d}  {actions_line(policy)}")
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("method")
    parser.add_argument("--runs", type=int, default=None, help="runs 0..N-1 (default: all finished)")
    parser.add_argument("--write", type=Path, default=None, help="store the lines in this file")
    args = parser.parse_args()
    header = [f"# python docs/scripts/rl_free_actions.py {' '.join(sys.argv[1:])}",
              "# run, checkpoint, decisions; the mode's action at V = 1..9, I = 0 | I = 1 "
              "(F forward, l left30, L left60, r right30, R right60, B backward)"]  # fmt: skip
    body = lines(args.out, args.method, args.runs)
    emit(header, body, args.write, f"{args.out}: no finished RL run of {args.method}")


if __name__ == "__main__":
    main()
