"""Cells of a ``nirl-mj compare`` directory computed again, against the published ones: for each cell
OUT finished itself (not restored, not reused), whether its result equals the published cell's key
for key, and where it does not, the success (percent) and SPL of both. A published cell computed
before a metric existed (SCT) lacks it: that key is reported as missing, not as a difference.
Ends with the machine and torch's CPU capability, which the bits were seen to depend on
(``nirl_mj.experiments.machine``). Writes nothing but ``--out`` (the report, after a line with the
command, date and commit).

    python docs/scripts/reproduce_cells.py OUT PUBLISHED_RESULTS_JSON [--out FILE]
    (e.g. runs/t1 docs/results/table1_fair/results.json)
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import torch

from nirl_mj.data.atomic import write_text
from nirl_mj.experiments.machine import platform_key


def compare_cell(new: dict, published: dict) -> tuple[str, list[str]]:
    """("identical" | "differs", the keys that differ) for one cell's results; a key the published
    cell lacks is listed as ``key (not published)`` and alone does not make the cell differ."""
    missing = [f"{k} (not published)" for k in new if k not in published]
    differs = [k for k in new if k in published and new[k] != published[k]]
    return ("differs" if differs else "identical"), differs + missing


def report(out: Path, published: dict) -> str:
    """One line per recomputed cell of ``out``, then a count and the platform."""
    lines, counts = [], {"identical": 0, "differs": 0}
    for path in sorted((out / "cells").glob("*.json")):
        cell = json.loads(path.read_text())
        if "restored_from" in cell or "reused_from" in cell or cell["id"] not in published:
            continue
        new, old = cell["result"], published[cell["id"]]
        verdict, keys = compare_cell(new, old)
        counts[verdict] += 1
        line = f"{cell['id']}: {verdict}"
        if verdict == "differs":
            line += (
                f" (success {100 * new['success_rate']:.0f} % against the published "
                f"{100 * old['success_rate']:.0f} %, SPL {new['spl']:.2f} against {old['spl']:.2f})"
            )
        lines.append(line + (f"; keys: {', '.join(keys)}" if keys else ""))
    lines.append(
        f"{counts['identical']} identical, {counts['differs']} differ; platform {platform_key()}, "
        f"torch {torch.__version__}"
    )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="the compare directory that computed the cells again")
    parser.add_argument("published", type=Path, help="the published results.json")
    parser.add_argument("--out", dest="file", type=Path, help="also write the report here (atomically)")
    args = parser.parse_args()
    if not (args.out / "cells").is_dir():
        parser.error(f"{args.out}: not a `nirl-mj compare` directory (no cells/ in it)")
    text = report(args.out, json.loads(args.published.read_text())["cells"])
    print(text)
    if args.file:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
        stamp = f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, commit {commit.stdout.strip() or 'unknown'}"
        write_text(args.file, f"# python {' '.join(sys.argv)}   ({stamp})\n{text}\n")


if __name__ == "__main__":
    main()
