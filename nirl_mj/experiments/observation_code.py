"""What the Stable-Baselines3 rows' networks see of phi(s) (``settings.inputs``): phi over its upper
bounds, or NIRL's bearing code. One module that the RL runs (``experiments.rl``) and the
discriminators' loader (``experiments.adversarial``) both read, so neither imports the other."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from nirl_mj.sim.observations import feature_bounds

_SCALE = 1.0 / feature_bounds()[1]  # phi / its upper bounds: every input in [0, 1]


def scaled(phi: np.ndarray) -> np.ndarray:
    """phi(s) (..., 16) as the networks see it, float32 in [0, 1]."""
    return (np.asarray(phi, dtype=np.float32) * _SCALE).astype(np.float32)


def observation_code(config: dict) -> tuple[Callable[[np.ndarray], np.ndarray], Any]:
    """What a run's networks see of phi(s) (..., 16), float32, and its bounds as a Gymnasium
    ``Box``: :func:`scaled`, or with ``inputs = "bearing"`` NIRL's default code, V's sector centre
    as (cos, sin) (17 values in [-1, 1])."""
    import gymnasium

    if config.get("inputs", "scaled") == "scaled":
        return scaled, gymnasium.spaces.Box(0.0, 1.0, (len(_SCALE),), np.float32)
    from nirl_mj.learn.inputs import NetworkInputs

    code = NetworkInputs(scaled=True, bearing=True)
    return (lambda phi: code(phi).astype(np.float32)), gymnasium.spaces.Box(
        -1.0, 1.0, (code.size,), np.float32
    )
