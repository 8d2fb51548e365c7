"""One method's success in two stored suite CSVs, paired by (axis, value, run): for every point both
hold, the first CSV's success minus the second's in points, with its 95 % interval (Student t over
the runs' differences, ``stats.paired``, as the suite tables use). For two computations of the same
suite that differ in one setting (for example docs/results/suites against
docs/results/suites_decaying_step: the same seeds, demonstrations and test arenas).

    python docs/scripts/suite_versus.py FIRST.csv SECOND.csv METHOD     # FIRST minus SECOND
"""

from __future__ import annotations

import argparse
import runpy
from pathlib import Path

from nirl_mj.experiments import tidy
from nirl_mj.experiments.stats import paired

describe = runpy.run_path(str(Path(__file__).with_name("paired_runs.py")))["describe"]  # its wording


def successes(path: Path, method: str) -> dict[tuple[str, str], dict[int, float]]:
    """{(axis, value): {run: success}} of ``method``'s rows in a suite CSV (read by ``tidy.read``)."""
    try:
        rows = tidy.read(path)
    except tidy.TidyError as error:
        raise SystemExit(f"error: cannot read {path}, or it is not a suite CSV: {error}") from None
    points: dict[tuple[str, str], dict[int, float]] = {}
    for row in rows:
        if row["method"] == method:
            points.setdefault((row["axis"], row["value"]), {})[row["run"]] = row["success"]
    return points


def versus(first: Path, second: Path, method: str) -> dict[tuple[str, str], dict]:
    """{(axis, value): stats.paired of first minus second} over the points and runs both CSVs hold.

    A file that cannot be read, or is not a suite CSV, or holds no point of ``method`` that the other
    holds, exits with one ``error:`` line."""
    a, b = (successes(path, method) for path in (first, second))
    if not set(a) & set(b):
        raise SystemExit(f"error: no point of {method!r} in both {first} and {second}")
    pairs = {}
    for point in (p for p in a if p in b):
        runs = sorted(set(a[point]) & set(b[point]))
        if runs:  # a point the two computed on other runs has nothing to pair
            pairs[point] = paired([a[point][r] for r in runs], [b[point][r] for r in runs])
    return pairs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("first", type=Path)
    parser.add_argument("second", type=Path)
    parser.add_argument("method")
    args = parser.parse_args()
    for (axis, value), p in versus(args.first, args.second, args.method).items():
        print(f"{axis} = {value}: {describe(p)}")


if __name__ == "__main__":
    main()
