"""The comparisons' bar charts (``table.png``) of docs/results, drawn again from their stored
``results.json`` by the code that draws them in a run (``nirl_mj.experiments.compare.bar_chart``).

    python docs/scripts/render_figures.py            # redraw every docs/results/*/table.png
    python docs/scripts/render_figures.py --check    # change nothing; exit 1 naming each that differs

Byte for byte: the same matplotlib build draws the same PNG (it stores no date); another build may
differ in its pixels, so ``--check`` is not part of the tests.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from nirl_mj.experiments.compare import bar_chart, chart_title

ROOT = Path(__file__).resolve().parents[2]


def charts() -> list[tuple[Path, Path]]:
    """(results.json, table.png) of every stored comparison that has a chart."""
    return [(p.parent / "results.json", p) for p in sorted((ROOT / "docs" / "results").glob("*/table.png"))
            if (p.parent / "results.json").is_file()]  # fmt: skip


def draw(results: Path, out: Path) -> None:
    """``out`` drawn from ``results`` (a compare ``results.json``)."""
    summary = json.loads(results.read_text())
    bar_chart(out, summary, chart_title(summary["experiment"], summary["runs"], summary["tests"], summary))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 if a chart differs")
    args = parser.parse_args()
    differ = []
    with tempfile.TemporaryDirectory() as tmp:
        for results, png in charts():
            fresh = Path(tmp) / "table.png"
            draw(results, fresh)
            if fresh.read_bytes() != png.read_bytes():
                differ.append(png)
                if not args.check:
                    draw(results, png)  # written atomically (nirl_mj.data.atomic.write_figure)
    for png in differ:
        print(f"{'differs' if args.check else 'redrew'}: {png.relative_to(ROOT)}")
    print(f"{len(charts())} charts, {len(differ)} {'differ' if args.check else 'redrawn'}")
    sys.exit(1 if args.check and differ else 0)


if __name__ == "__main__":
    main()
