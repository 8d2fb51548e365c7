"""Every checkpoint's selection score of a compare experiment's Stable-Baselines3 rows, copied from
their run records into one JSON file (``checkpoint_scores.json`` of docs/results/*):

    python docs/scripts/rl_checkpoint_scores.py OUT OUTFILE [--methods A B ...]

OUT is the experiment's ``--out``; its runs are OUT/runs/METHOD/SEED/run.json, run r of seed
``experiment seed + r``. Writes ``{method: {run: {"selected": ..., "scores": [...]}}}`` (each score:
the decisions trained, the score, the episodes it is over; a validation cut short has a null score,
``at_most`` and ``driven``: ``nirl_mj.experiments.rl.SELECTIONS``), atomically.
A run still training is copied as far as it went; a method with no RL run is left out.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from nirl_mj.data.atomic import write_text


def checkpoint_scores(out: Path, methods: list[str] | None = None) -> dict[str, dict[str, dict]]:
    """``{method: {run index: {"selected", "scores"}}}`` of OUT's RL runs, runs in order."""
    seed = json.loads((out / "experiment.json").read_text())["seed"]
    table: dict[str, dict[str, dict]] = {}
    for folder in sorted((out / "runs").iterdir()):
        if methods and folder.name not in methods:
            continue
        runs = {}
        for record_file in sorted(folder.glob("*/run.json"), key=lambda p: int(p.parent.name)):
            record = json.loads(record_file.read_text())
            if record.get("kind") == "rl" and "scores" in record:
                run = int(record_file.parent.name) - seed
                runs[str(run)] = {"selected": record.get("selected"), "scores": record["scores"]}
        if runs:
            table[folder.name] = runs
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("outfile", type=Path)
    parser.add_argument("--methods", nargs="*", default=None)
    args = parser.parse_args()
    table = checkpoint_scores(args.out, args.methods)
    if not table:
        raise SystemExit(f"{args.out}: no Stable-Baselines3 run with checkpoint scores")
    write_text(args.outfile, json.dumps(table, indent=1) + "\n")
    print(f"wrote {args.outfile}: {', '.join(f'{m} ({len(r)} runs)' for m, r in table.items())}")


if __name__ == "__main__":
    main()
