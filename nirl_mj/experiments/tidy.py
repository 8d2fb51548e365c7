"""Tidy result rows: one row per (axis, value, method, run), the one format every compare and suite
writes (``rows.csv``, ``suite.csv``) and ``nirl-mj leaderboard`` merges.

Rates are fractions (0..1); ``axis`` and ``value`` are empty for a comparison (no axis); ``sct`` is
empty for a cell computed before it existed.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

COLUMNS = ("suite", "axis", "value", "method", "run", "tests", "success", "collision", "timeout", "spl",
           "sct")  # fmt: skip
RATES = ("success", "collision", "timeout", "spl", "sct")


class TidyError(ValueError):
    """A tidy CSV that cannot be read: the message names the file, the row and the column."""


def row(suite: str, axis: str, value: str, method: str, run: int, metrics: dict) -> dict[str, Any]:
    """A tidy row from a cell's metrics (``evaluate_policy``'s keys)."""
    return {"suite": suite, "axis": axis, "value": value, "method": method, "run": run,
            "tests": metrics["tests"], "success": metrics["success_rate"],
            "collision": metrics["collision_rate"], "timeout": metrics["timeout_rate"],
            "spl": metrics["spl"], "sct": metrics.get("sct")}  # fmt: skip


def as_metrics(r: dict) -> dict:
    """A tidy row as ``stats.summarise_runs`` reads a cell."""
    out = {"success_rate": r["success"], "collision_rate": r["collision"], "timeout_rate": r["timeout"],
           "physics_error_rate": 0.0, "spl": r["spl"], "tests": r["tests"]}  # fmt: skip
    if r["sct"] is not None:
        out["sct"] = r["sct"]
    return out


def csv_text(rows: Iterable[dict]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(COLUMNS)
    for r in rows:
        writer.writerow(["" if r[k] is None else (f"{r[k]:.6g}" if isinstance(r[k], float) else r[k])
                         for k in COLUMNS])  # fmt: skip
    return buffer.getvalue()


def read(path: str | Path) -> list[dict]:
    """The rows of a tidy CSV, typed and checked (rates in [0, 1], runs and tests whole numbers)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TidyError(f"{path}: cannot be read ({exc})") from None
    reader = csv.DictReader(io.StringIO(text))
    if tuple(reader.fieldnames or ()) != COLUMNS:
        raise TidyError(f"{path}: columns {reader.fieldnames}: expected {', '.join(COLUMNS)}")
    rows = []
    for line, raw in enumerate(reader, start=2):
        r: dict[str, Any] = {k: raw[k] for k in ("suite", "axis", "value", "method")}
        try:
            r["run"], r["tests"] = int(raw["run"]), int(raw["tests"])
            for k in RATES:
                r[k] = None if raw[k] == "" and k == "sct" else float(raw[k])
        except (TypeError, ValueError) as exc:
            raise TidyError(f"{path}: line {line}: {exc}") from None
        bad = [k for k in RATES if r[k] is not None and not (math.isfinite(r[k]) and 0.0 <= r[k] <= 1.0)]
        if bad or r["run"] < 0 or r["tests"] < 1:
            raise TidyError(f"{path}: line {line}: {', '.join(bad) or 'run/tests'} out of range")
        rows.append(r)
    return rows
