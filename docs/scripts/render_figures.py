"""The comparisons' bar charts (``table.png``) and the sweeps' line plots (``sweep.png``) of
docs/results, drawn again from their stored ``results.json`` by the code that draws them in a run
(``nirl_mj.experiments.compare.bar_chart``, ``nirl_mj.experiments.sweep.line_plot``; a sweep's
experiment is its file under tasks/, which tests/test_experiments.py keeps at the recorded settings).

    python docs/scripts/render_figures.py            # redraw every docs/results/*/table.png, sweep.png
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
from nirl_mj.experiments.definition import load_experiment
from nirl_mj.experiments.sweep import line_plot

ROOT = Path(__file__).resolve().parents[2]


def charts() -> list[tuple[Path, Path]]:
    """(results.json, figure) of every stored comparison and sweep that has its figure."""
    figures = [
        *(ROOT / "docs" / "results").glob("*/table.png"),
        *(ROOT / "docs" / "results").glob("*/sweep.png"),
    ]
    return [(p.parent / "results.json", p) for p in sorted(figures) if (p.parent / "results.json").is_file()]


def draw(results: Path, out: Path) -> None:
    """``out`` drawn from ``results``: a compare ``results.json`` (``table.png``) or a sweep's
    (``sweep.png``), as its name says."""
    summary = json.loads(results.read_text())
    if out.name == "sweep.png":
        line_plot(out, summary, load_experiment(summary["experiment"], kind="sweep"))
    else:
        bar_chart(
            out, summary, chart_title(summary["experiment"], summary["runs"], summary["tests"], summary)
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 if a chart differs")
    args = parser.parse_args()
    differ = []
    with tempfile.TemporaryDirectory() as tmp:
        for results, png in charts():
            fresh = Path(tmp) / png.name
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
