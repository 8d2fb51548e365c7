"""One method minus another, paired by run, from a ``nirl-mj compare`` results.json: the
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
    """``first`` minus ``second`` over the runs both finished (``stats.paired``, as the tables use),
    from each method's success per run (``by_run``)."""
    missing = [name for name in (first, second) if name not in results["methods"]]
    if missing:
        raise SystemExit(f"error: no method {missing[0]!r} (methods: {', '.join(results['methods'])})")
    a, b = (results["methods"][name]["by_run"] for name in (first, second))
    both = sorted(set(a) & set(b), key=int)
    return paired_runs([a[r] for r in both], [b[r] for r in both])


def describe(p: dict) -> str:
    """A ``stats.paired`` result in points: "+1.2 [-0.3, +2.7] over 5 runs (3 better / 1 worse / 1 equal)"
    (no interval with fewer than 2 runs)."""
    interval = "" if p["ci"][0] is None else " [{:+.1f}, {:+.1f}]".format(*(100 * v for v in p["ci"]))
    return (
        f"{100 * p['mean']:+.1f}{interval} over {p['runs']} runs "
        f"({p['better']} better / {p['worse']} worse / {p['equal']} equal)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path)
    parser.add_argument("first")
    parser.add_argument("second")
    args = parser.parse_args()
    p = paired(json.loads(args.results.read_text(encoding="utf-8")), args.first, args.second)
    print(f"{args.first} minus {args.second}: {describe(p)}")


if __name__ == "__main__":
    main()
