"""Summaries of repeated runs: average / best / worst and 95 % confidence intervals.

Two intervals, for two questions:

- :func:`t_interval` over the runs' rates (Student t, n - 1 degrees of freedom):
  where the *average over runs* of this method lies. A run is one training seed
  and its own test arenas, so this interval holds both the spread between
  training seeds and the test-sampling noise. This is the one the tables show.
- :func:`wilson` on the pooled tests (all runs' successes over all their tests):
  the binomial interval of the pooled rate. It treats every test as independent,
  which holds for a fixed policy (the references) but not across training seeds,
  where it is too narrow; it is given in the CSV for the references' sake.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def t_interval(
    values: Sequence[float], confidence: float = 0.95, low: float = 0.0, high: float = 1.0
) -> tuple[float, float]:
    """Student-t interval of the mean of ``values``, clipped to [low, high] (rates cannot leave
    [0, 1]; with few runs the raw interval does); (nan, nan) for fewer than 2 values."""
    x = np.asarray(values, dtype=np.float64)
    if len(x) < 2:
        return math.nan, math.nan
    from scipy.stats import t

    half = float(t.ppf(0.5 + confidence / 2, len(x) - 1) * x.std(ddof=1) / math.sqrt(len(x)))
    return max(low, float(x.mean()) - half), min(high, float(x.mean()) + half)


def wilson(successes: float, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion ``successes / n``; (nan, nan) for n = 0."""
    if n <= 0:
        return math.nan, math.nan
    from scipy.stats import norm

    z = float(norm.ppf(0.5 + confidence / 2))
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def summarise_runs(rows: Sequence[dict]) -> dict:
    """Average / best / worst success over runs (fractions), with both intervals and the mean
    collision, timeout and physics-error rates and SPL. ``rows``: ``evaluate`` metrics, one per run.
    Undefined values (an interval of one run) are None, so the summary is standard JSON."""
    if not rows:
        return {"runs": 0}
    success = [r["success_rate"] for r in rows]
    tests = sum(r["tests"] for r in rows)
    pooled = sum(r["success_rate"] * r["tests"] for r in rows)

    def mean(key: str) -> float:
        return float(np.mean([r[key] for r in rows]))

    return {
        "runs": len(rows),
        "tests": tests,
        "avg": mean("success_rate"),
        "best": float(max(success)),
        "worst": float(min(success)),
        "sd": _finite(float(np.std(success, ddof=1))) if len(rows) > 1 else None,
        "ci": [_finite(v) for v in t_interval(success)],
        "wilson": [_finite(v) for v in wilson(round(pooled), tests)],
        "collision": mean("collision_rate"),
        "timeout": mean("timeout_rate"),
        "physics_error": mean("physics_error_rate"),
        "spl": mean("spl"),
        "sct": mean("sct") if all("sct" in r for r in rows) else None,  # cells before 2026-11-26 lack it
        "per_run": success,
    }


def paired(reference: Sequence[float], other: Sequence[float]) -> dict:
    """The reference's success minus the other's, paired by run (the same training seed and test
    arenas): mean difference, its standard error and 95 % t interval (fractions, None with fewer than
    2 runs), and the runs the reference is better / worse / equal in."""
    d = np.asarray(reference, dtype=np.float64) - np.asarray(other, dtype=np.float64)
    if not len(d):
        return {"runs": 0}
    se = float(d.std(ddof=1) / math.sqrt(len(d))) if len(d) > 1 else math.nan
    return {
        "runs": len(d),
        "mean": float(d.mean()),
        "se": _finite(se),
        "ci": [_finite(v) for v in t_interval(d, low=-1.0, high=1.0)],
        "better": int((d > 0).sum()),
        "worse": int((d < 0).sum()),
        "equal": int((d == 0).sum()),
    }


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None
