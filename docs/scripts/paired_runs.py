"""One method minus another, paired by run, from a ``nirl-mj compare`` results.json: the
mean difference of success (points) with its 95 % interval (Student t over the runs' differences)
and how many runs were better, worse and equal. The tables' paired section takes the experiment's
first method as the reference; this takes any two.

    python docs/scripts/paired_runs.py RESULTS_JSON A B        # A minus B
    python docs/scripts/paired_runs.py RESULTS_JSON A B --second-from OLD_RESULTS_JSON
    (B's success per run read from another results.json of the same runs: a row now minus the row
    as an earlier commit stored it, e.g. ``git show COMMIT:docs/results/table1_fair/results.json``)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from nirl_mj.experiments.stats import paired as paired_runs


def paired(results: dict, first: str, second: str, second_results: dict | None = None) -> dict:
    """``first`` minus ``second`` over the runs both finished (``stats.paired``, as the tables use),
    from each method's success per run (``by_run``); ``second``'s from ``second_results`` if given."""
    sources = ((results, first), (second_results or results, second))
    for table, name in sources:
        if name not in table["methods"]:
            raise SystemExit(f"error: no method {name!r} (methods: {', '.join(table['methods'])})")
    a, b = (table["methods"][name]["by_run"] for table, name in sources)
    both = sorted(set(a) & set(b), key=int)
    return paired_runs([a[r] for r in both], [b[r] for r in both])


def read_results(path: Path) -> dict:
    """A results.json, read."""
    return json.loads(path.read_text(encoding="utf-8"))


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
    parser.add_argument("--second-from", type=Path, help="read the second method from this results.json")
    args = parser.parse_args()
    second = read_results(args.second_from) if args.second_from else None
    p = paired(read_results(args.results), args.first, args.second, second)
    label = f" ({args.second_from})" if args.second_from else ""
    print(f"{args.first} minus {args.second}{label}: {describe(p)}")


if __name__ == "__main__":
    main()
