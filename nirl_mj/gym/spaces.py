"""dm_env specs -> Gymnasium spaces, bounds and dtypes kept."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from dm_env import specs
from gymnasium import spaces


def space_of(spec: specs.Array) -> spaces.Space:
    """``DiscreteArray`` -> ``Discrete``; ``BoundedArray`` -> ``Box`` with its bounds and dtype.

    An unbounded ``Array`` is refused: every observation and action of the task is bounded
    (``nirl_mj.sim.observations``), and a ``Box(-inf, inf)`` is what this adapter exists to avoid.
    """
    if isinstance(spec, specs.DiscreteArray):
        return spaces.Discrete(spec.num_values)
    if isinstance(spec, specs.BoundedArray):
        low = np.broadcast_to(spec.minimum, spec.shape).astype(spec.dtype)
        high = np.broadcast_to(spec.maximum, spec.shape).astype(spec.dtype)
        return spaces.Box(low, high, spec.shape, spec.dtype)
    raise TypeError(f"spec {spec.name!r} is an unbounded {type(spec).__name__}: give it bounds")


def dict_space(observation_spec: Mapping[str, specs.Array], keys: tuple[str, ...]) -> spaces.Dict:
    """A ``Dict`` of the observations ``keys`` (in that order)."""
    return spaces.Dict({key: space_of(observation_spec[key]) for key in keys})
