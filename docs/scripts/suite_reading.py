"""The reading of the suites (docs/RESULTS.md, "Suites"), rendered from their stored tidy rows.

Answers, from docs/results/suites/{demos,quality,transfer}.csv (or the files given), with paired
95 % t intervals over the runs (a run's test arenas are the same at every point and for every
method):

- from how few demonstrations each learner reaches 90 % of its own 30-demonstration success (none
  where that success is under 10 %);
- how much of its clean-demonstration success each keeps with each flawed demonstrator;
- how much of the sensor expert's success each keeps where it was never trained;
- where the learners differ, paired: each learner but the NIRL-MAP rows against behaviour cloning,
  NIRL against each other learner, and each NIRL-MAP row against NIRL (a MAP pretreatment on minus
  off), one table per axis.

    python docs/scripts/suite_reading.py [DIR]
        DIR: where the CSVs are (default docs/results/suites). docs/RESULTS.md holds the reading in a
        generated block (``suite-reading``), rewritten by ``python docs/scripts/render_docs.py``
"""

from __future__ import annotations

import sys
from pathlib import Path

from nirl_mj.experiments.stats import paired
from nirl_mj.experiments.tidy import read

REFERENCES = ("expert", "rule", "forward", "PPO-reward", "DQN-reward", "DAgger")
LEARNER, CLONE, MAP = "NIRL", "BC", "NIRL-MAP"
FULL = 5  # runs per point that the issue asks for; other counts are marked with n


def success(rows: list[dict], axis: str, value: str, method: str) -> dict[int, float]:
    return {
        r["run"]: r["success"] for r in rows if (r["axis"], r["value"], r["method"]) == (axis, value, method)
    }


def mean(by_run: dict[int, float]) -> float:
    return sum(by_run.values()) / len(by_run) if by_run else float("nan")


def interval(a: dict[int, float], b: dict[int, float]) -> str:
    """a - b paired by run: mean [95 % interval] in points, over the runs both have (n when not 5)."""
    runs = sorted(set(a) & set(b))
    n = f" (n = {len(runs)})" if len(runs) != FULL else ""
    if not runs:
        return "-"
    if len(runs) == 1:
        return f"{100 * (a[runs[0]] - b[runs[0]]):+.1f}{n}"
    d = paired([a[r] for r in runs], [b[r] for r in runs])
    return f"{100 * d['mean']:+.1f} [{100 * d['ci'][0]:+.1f}, {100 * d['ci'][1]:+.1f}]{n}"


MIN_WHOLE = 0.1
"""The least success (a fraction) that a share is taken of."""


def share(part: dict[int, float], whole: dict[int, float]) -> str:
    """The mean of ``part`` as a share of the mean of ``whole``, over the runs both have (n in brackets
    when not 5); none of a ``whole`` under :data:`MIN_WHOLE` (a share of almost nothing says nothing)."""
    runs = sorted(set(part) & set(whole))
    total = sum(whole[r] for r in runs)
    if not runs or total <= 0:
        return "-"
    if total / len(runs) < MIN_WHOLE:
        return f"- ({100 * sum(part[r] for r in runs) / len(runs):.1f} % of {100 * total / len(runs):.1f} %)"
    n = f" (n = {len(runs)})" if len(runs) != FULL else ""
    return f"{100 * sum(part[r] for r in runs) / total:.0f} %{n}"


def values(rows: list[dict], axis: str) -> list[str]:
    return list(dict.fromkeys(r["value"] for r in rows if r["axis"] == axis))


def learners(rows: list[dict]) -> list[str]:
    return [m for m in dict.fromkeys(r["method"] for r in rows) if m not in REFERENCES]


def demos_reading(rows: list[dict]) -> list[str]:
    out = ["### Number of demonstrations", "",
           "| method | 30-demonstration success | 90 % of it first reached at | 3 minus 30 demonstrations |",
           "|---|---|---|---|"]  # fmt: skip
    for m in learners(rows):
        full = success(rows, "demonstrations", "30", m)
        if not full:
            continue
        enough = [v for v in values(rows, "demonstrations")
                  if mean(success(rows, "demonstrations", v, m)) >= 0.9 * mean(full)]  # fmt: skip
        reached = f"- (under {100 * MIN_WHOLE:.0f} %)" if mean(full) < MIN_WHOLE else (enough or ["-"])[0]
        three = success(rows, "demonstrations", "3", m)
        out.append(f"| {m} | {100 * mean(full):.1f} | {reached} | {interval(three, full)} |")
    return out


def quality_reading(rows: list[dict]) -> list[str]:
    flawed = [v for v in values(rows, "demonstrator") if v != "sensor"]
    out = ["### Demonstrator", "", "Success with each demonstrator as a share of the success with the clean "
           "sensor expert (the demonstrator's own success in the `expert` row; where the clean success is "
           "under 10 %, the two successes instead):", "",
           "| method | " + " | ".join(flawed) + " |", "|---|" + "---|" * len(flawed)]  # fmt: skip
    for m in [*learners(rows), "expert"]:
        clean = success(rows, "demonstrator", "sensor", m)
        cells = [share(success(rows, "demonstrator", v, m), clean) for v in flawed]
        out.append(f"| {m} | " + " | ".join(cells) + " |")
    return out


def transfer_reading(rows: list[dict]) -> list[str]:
    points = [(a, v) for a in dict.fromkeys(r["axis"] for r in rows) for v in values(rows, a)]
    out = [
        "### Undemonstrated states",
        "",
        "Success as a share of the sensor expert's on the same arenas:",
        "",
        "| method | " + " | ".join(f"{a} = {v}" for a, v in points) + " |",
        "|---|" + "---|" * len(points),
    ]
    for m in learners(rows):
        cells = [share(success(rows, a, v, m), success(rows, a, v, "expert")) for a, v in points]
        out.append(f"| {m} | " + " | ".join(cells) + " |")
    return out


def pairs(rows: list[dict]) -> list[tuple[str, str]]:
    """The paired differences read in every suite: NIRL minus BC, each other learner minus BC and NIRL
    minus each, and each NIRL-MAP row minus NIRL (a MAP pretreatment on minus off)."""
    maps = [m for m in learners(rows) if m.startswith(MAP)]
    others = [m for m in learners(rows) if m not in (LEARNER, CLONE, *maps)]
    return [(LEARNER, CLONE), *((m, CLONE) for m in others), *((LEARNER, m) for m in others),
            *((m, LEARNER) for m in maps)]  # fmt: skip


def versus(name: str, rows: list[dict]) -> list[str]:
    """One table per axis: a row per pair of :func:`pairs`, first minus second at each point, paired
    by run; a pair with no common point on the axis is left out."""
    out = []
    for axis in dict.fromkeys(r["axis"] for r in rows):
        points = values(rows, axis)
        lines = []
        for first, second in pairs(rows):
            cells = [interval(success(rows, axis, v, first), success(rows, axis, v, second)) for v in points]
            if any(c != "-" for c in cells):
                lines.append(f"| {first} minus {second} | " + " | ".join(cells) + " |")
        if lines:
            head = f"| {axis} | " + " | ".join(points) + " |"
            caption = f"Paired by run ({name}), points [95 % interval] over {FULL} runs unless n is given:"
            out += [caption, "", head, "|---|" + "---|" * len(points), *lines, ""]
    return out


def render(folder: Path) -> str:
    parts = []
    readers = {"demos": demos_reading, "quality": quality_reading, "transfer": transfer_reading}
    for name, reading in readers.items():
        path = folder / f"{name}.csv"
        if not path.is_file():
            parts.append(f"({name}: not computed yet)\n")
            continue
        rows = read(path)
        parts.append("\n".join([*reading(rows), "", *versus(name, rows)]))
    return "\n".join(parts)


def main() -> None:
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parents[1] / "results" / "suites"
    print(render(folder))


if __name__ == "__main__":
    main()
