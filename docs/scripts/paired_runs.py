"""One method minus another, paired by run, from a ``nirl-mj compare`` results.json's cells: the
mean difference of success (points) with its 95 % interval (Student t over the runs' differences)
and how many runs were better, worse and equal. The tables' paired section takes the experiment's
first method as the reference; this takes any two.

    python docs/scripts/paired_runs.py RESULTS_JSON A B        # A minus B
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from nirl_mj.experiments.stats import paired as paired_runs


def paired(results: dict, first: str, second: str) -> dict:
    """``first`` minus ``second`` over the runs both finished (``stats.paired``, as the tables use)."""
    by_method: dict[str, dict[int, float]] = {first: {}, second: {}}
    for cell in results["cells"].values():
        if cell["method"] in by_method:
            by_method[cell["method"]][int(cell["run"])] = float(cell["success_rate"])
    for name, runs in by_method.items():
        if not runs:
            raise SystemExit(f"error: no cells of method {name!r} (methods: {', '.join(results['methods'])})")
    both = sorted(set(by_method[first]) & set(by_method[second]))
    return paired_runs([by_method[first][r] for r in both], [by_method[second][r] for r in both])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path)
    parser.add_argument("first")
    parser.add_argument("second")
    args = parser.parse_args()
    p = paired(json.loads(args.results.read_text(encoding="utf-8")), args.first, args.second)
    low, high = (f"{100 * v:+.1f}" for v in p["ci"])
    print(
        f"{args.first} minus {args.second}: {100 * p['mean']:+.1f} [{low}, {high}] over {p['runs']} runs "
        f"({p['better']} better / {p['worse']} worse / {p['equal']} equal)"
    )


if __name__ == "__main__":
    main()
