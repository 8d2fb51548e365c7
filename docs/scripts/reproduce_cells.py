"""Cells of a ``nirl-mj compare`` directory computed again, against the published ones: for each cell
DIRECTORY finished itself (not restored, not reused) and the published file holds, whether its
result equals the published cell's key for key; where it does not, the success (percent) and SPL of
both and, for a run of the IRL loop, its selected iteration and how many iterations shared its score
(the tie rule acts only then). A key only the new cell has (SCT, which cells computed before it
lack) is named but is no difference; a key only the published cell has is one. The cells left out
are counted; with none compared it exits with an error. It ends with the platforms (the vendor and
torch's CPU capability, ``nirl_mj.experiments.machine``) the compared cells recorded (cells stored
before 2026-11-29 record none) and the one running it. Writes nothing but ``--out`` (the report, after a
line with the command, date and commit).

    python docs/scripts/reproduce_cells.py DIRECTORY PUBLISHED_RESULTS_JSON [--out FILE]
    (e.g. runs/t1_time docs/results/table1_fair/results.json)
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import torch

from nirl_mj.data.atomic import write_text
from nirl_mj.experiments.machine import platform_key

SELECTION_METRIC = {"demo_balanced": "demo_balanced_accuracy"}
"""The metrics.jsonl key of each selection rule whose ties the report counts."""


def compare_cell(new: dict, published: dict) -> tuple[str, list[str]]:
    """("identical" | "differs", the keys that differ) for one cell's results: a key the published
    cell lacks is listed as ``key (not published)`` and alone does not make the cell differ; a key
    only the published cell holds does (``key (not computed)``)."""
    unpublished = [f"{k} (not published)" for k in new if k not in published]
    uncomputed = [f"{k} (not computed)" for k in published if k not in new]
    differs = [k for k in new if k in published and new[k] != published[k]] + uncomputed
    return ("differs" if differs else "identical"), differs + unpublished


def selection_text(run: Path) -> str:
    """``selected iteration I, one of N at its score`` for a run of the IRL loop, else ``""``."""
    try:
        record = json.loads((run / "run.json").read_text())
        metric = SELECTION_METRIC[record["selection"]["rule"]]
        rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines() if line]
        chosen = record["selected_iteration"]
    except (OSError, KeyError, TypeError, ValueError):
        return ""
    best = next((row.get(metric) for row in rows if row.get("episode") == chosen), None)
    if best is None:
        return ""
    ties = sum(row.get(metric) == best for row in rows)
    return f"; selected iteration {chosen}, one of {ties} at its score"


def rates(result: dict) -> str:
    """``success S %, SPL P`` (nan for a missing key)."""
    success, spl = result.get("success_rate", float("nan")), result.get("spl", float("nan"))
    return f"success {100 * success:.0f} %, SPL {spl:.2f}"


def report(directory: Path, published: dict) -> str:
    """One line per recomputed cell of ``directory``, then the counts and the platforms."""
    lines, counts, platforms = [], {"identical": 0, "differs": 0}, set()
    left_out = {"restored or reused": 0, "not published": 0}
    for path in sorted((directory / "cells").glob("*.json")):
        cell = json.loads(path.read_text())
        if "restored_from" in cell or "reused_from" in cell:
            left_out["restored or reused"] += 1
            continue
        if cell["id"] not in published:
            left_out["not published"] += 1
            continue
        new, old = cell["result"], published[cell["id"]]
        platforms.add(cell.get("platform", "(not recorded)"))
        verdict, keys = compare_cell(new, old)
        counts[verdict] += 1
        line = f"{cell['id']}: {verdict}"
        if verdict == "differs":
            run = directory / "runs" / new.get("method", "") / str(new.get("run", ""))
            line += f" ({rates(new)} against the published {rates(old)}{selection_text(run)})"
        lines.append(line + (f"; keys: {', '.join(keys)}" if keys else ""))
    if not lines:
        raise SystemExit(f"{directory}: no cell to compare ({left_out['restored or reused']} restored or "
                         f"reused, {left_out['not published']} not in the published file)")  # fmt: skip
    lines.append(
        f"{counts['identical']} identical, {counts['differs']} differ; left out: "
        f"{left_out['restored or reused']} restored or reused, {left_out['not published']} not published; "
        f"computed on {', '.join(sorted(platforms))}; run on {platform_key()}, torch {torch.__version__}"
    )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path, help="the compare directory that computed the cells again")
    parser.add_argument("published", type=Path, help="the published results.json")
    parser.add_argument("--out", type=Path, help="also write the report here (atomically)")
    args = parser.parse_args()
    if not (args.directory / "cells").is_dir():
        parser.error(f"{args.directory}: not a `nirl-mj compare` directory (no cells/ in it)")
    try:
        published = json.loads(args.published.read_text())["cells"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        parser.error(f"{args.published}: not a published results.json with cells ({exc!r})")
    text = report(args.directory, published)
    print(text)
    if args.out:
        commit = subprocess.run(["git", "describe", "--always", "--dirty=+uncommitted"],
                                capture_output=True, text=True).stdout.strip()  # fmt: skip
        stamp = f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, commit {commit or 'unknown'}"
        write_text(args.out, f"# {shlex.join(['python', *sys.argv])}   ({stamp})\n{text}\n")


if __name__ == "__main__":
    main()
