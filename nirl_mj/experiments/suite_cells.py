"""A suite's cells, named: which methods a training axis trains again at each value, and the ids
of a suite's cells and points in its output directory (``nirl_mj.experiments.suite`` computes them,
``nirl_mj.experiments.suite_restore`` takes them back from a publication)."""

from __future__ import annotations

from typing import Any

from nirl_mj.experiments.compare import cell_id
from nirl_mj.experiments.definition import Axis, MethodSpec, value_name

ANY = "any"  # the value of a cell that does not depend on a training axis


def reads_demonstrations(method: MethodSpec, axis: Axis) -> bool:
    """Whether ``method``'s result depends on a training axis's value: it learns from the
    demonstrations, queries the demonstrator (DAgger), or is the demonstrator (``expert``, on the
    demonstrator axis)."""
    from nirl_mj.experiments.rl import ADVERSARIAL

    if method.kind in ("irl", "bc", "dagger"):
        return True
    if method.kind == "rl":
        return method.algo in ADVERSARIAL
    if method.kind == "plugin":
        return "demonstrations" in method.declared_reads
    return method.kind == "expert" and axis.name == "demonstrator"


def training_cell_id(axis: str, value: str, method: str, run: int) -> str:
    # "." appears in no method name (definition._NAME), so the id names one (value, method) only
    return f"{axis}-{value}.{method}-run{run:03d}"


test_cell_id = cell_id  # a test axis's cell: one per (method, run), as a comparison's


def point_key(axis: str, value: Any) -> str:
    return f"{axis}={value_name(value)}"
