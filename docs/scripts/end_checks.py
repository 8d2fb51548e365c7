"""What the end check saw in each training run of a compare directory's method: the rule's choice,
the candidates with their rule score and episodes ended, and the iterate kept.

    python docs/scripts/end_checks.py OUT METHOD [> FILE]
    (OUT: a ``nirl-mj compare`` output directory; METHOD: a row trained with ``end_check_arenas``)

Reads each ``OUT/runs/METHOD/SEED/run.json`` (``selection``, written by
``nirl_mj.experiments.training``); a run without the check, or not finished, is a one-line error.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def lines(records: dict[int, dict]) -> list[str]:
    """One line per run, by seed: the rule's choice, the kept iterate, each candidate's
    ``iteration:score/ended``, and whether the check changed the choice."""
    out = ["seed  rule's  kept  candidates (iteration: rule score, episodes ended of N)"]
    for seed, record in sorted(records.items()):
        s = record["selection"]
        n = s["end_check_arenas"]
        listed = ", ".join(f"{i}: {c['score']:.3f}, {c['ended']}/{n}" for i, c in s["candidates"].items())
        moved = "  changed" if s["iteration"] != s["first_round_best"] else ""
        out.append(f"{seed}  {s['first_round_best']:6d}  {s['iteration']:4d}  {listed}{moved}")
    changed = sum(r["selection"]["iteration"] != r["selection"]["first_round_best"] for r in records.values())
    out.append(f"{changed} of {len(records)} runs keep another iterate than the rule's")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("method")
    args = parser.parse_args()
    runs = sorted((args.out / "runs" / args.method).glob("*/run.json"))
    if not runs:
        sys.exit(f"end_checks.py: no run.json under {args.out / 'runs' / args.method}")
    records = {}
    for path in runs:
        record = json.loads(path.read_text())
        if "end_check_arenas" not in record.get("selection", {}):
            sys.exit(f"end_checks.py: {path} holds no end check (not finished, or trained without one)")
        records[int(path.parent.name)] = record
    print("\n".join(lines(records)))


if __name__ == "__main__":
    main()
