"""The README's short form of a compare experiment's results: one row per method that finished a
run, with what it reads (a reference or a learner from demonstrations), its runs, average success
[95 % CI], worst run, SPL, and the first method minus it, paired by run [95 % CI] (all read from
``results.json``, as ``table.md`` is).

    python docs/scripts/summary_table.py docs/results/table1_fair/results.json
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from nirl_mj.experiments.reads import is_reference


def _pct(value: float | None, digits: int = 1) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{100 * value:.{digits}f}"


def _interval(ci: list | None, signed: bool = False) -> str:
    if not ci or ci[0] is None:
        return ""
    low, high = (f"{100 * v:+.1f}" if signed else _pct(v) for v in ci)
    return f" [{low}, {high}]"


def summary_table(results: dict) -> str:
    """The Markdown table of ``results`` (a compare ``results.json``)."""
    methods = results["methods"]
    first = next(iter(methods))
    head = f"| method | reads | runs | success avg [95 % CI] | worst | SPL | {first} minus it [95 % CI] |"
    lines = [head, "|---|---|---|---|---|---|---|"]
    for name, s in methods.items():
        if not s.get("runs"):
            continue
        reads = s.get("reads")
        kind = "?" if reads is None else ("reference" if is_reference(reads) else "from demonstrations")
        pair = s.get("paired") or {}
        paired = f"{100 * pair['mean']:+.1f}{_interval(pair.get('ci'), True)}" if pair.get("runs") else ""
        success, worst = f"{_pct(s['avg'])}{_interval(s.get('ci'))}", _pct(s["worst"], 0)
        lines.append(f"| {name} | {kind} | {s['runs']} | {success} | {worst} | {s['spl']:.2f} | {paired} |")
    return "\n".join(lines)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    print(summary_table(json.loads(Path(sys.argv[1]).read_text())))
