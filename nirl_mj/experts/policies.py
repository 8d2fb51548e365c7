"""Reference policies on phi(s): the yardsticks every learner is shown next to.

A policy maps phi(s) (16,) to an action index 0..5. ``always_forward`` is what
a collapsed learner becomes; ``rule_policy`` is a hand-written rule on the same
16 features, showing how much of the task the features can carry.
"""

from __future__ import annotations

from collections.abc import Callable

import dm_env
import numpy as np

Policy = Callable[[np.ndarray], int]

# Heading change of actions 0..4 in degrees (5 is backward).
_TURNS = np.array([0.0, 30.0, 60.0, -30.0, -60.0])


def always_forward(phi: np.ndarray) -> int:
    """Action 0 whatever the state."""
    return 0


# Directions of the phi danger block [S1, S2, S3, S4, S7, S8, S9], degrees.
_SENSOR_DEGREES = np.array([0.0, 40.0, 80.0, 120.0, -120.0, -80.0, -40.0])


def _danger_at(danger7: np.ndarray, degrees: np.ndarray) -> np.ndarray:
    """Danger expected in each direction (degrees from the front): a sensor's level,
    fading by two levels per 40 degrees away from its cone's centre."""
    gap = np.abs(((degrees[:, None] - _SENSOR_DEGREES[None, :]) + 180.0) % 360.0 - 180.0)
    return np.max(danger7[None, :] - 2.0 * gap / 40.0, axis=1)


def rule_policy(phi: np.ndarray) -> int:
    """Turn towards the target sector V along the safest way; back off when boxed in.

    Every action but backward travels about one metre along an arc, so an action
    is judged by the danger along its chord (half its turn) and at its final
    heading. Actions with danger 5 or more there (clearance under 2.3 m by
    default: two decisions of travel at 2 m/s) are ruled out; the rest are scored by their deviation
    from the target's bearing plus a penalty growing with danger. With no
    action left, backward.
    """
    phi = np.asarray(phi, dtype=np.float64)
    danger7 = phi[0:7]
    region = int(phi[7])
    danger = np.maximum(_danger_at(danger7, _TURNS / 2), _danger_at(danger7, _TURNS))
    if np.all(danger >= 5):
        return 5
    bearing = ((region - 1) * 40.0 + 180.0) % 360.0 - 180.0  # (-180, 180]
    deviation = np.abs(((bearing - _TURNS) + 180.0) % 360.0 - 180.0) / 60.0
    score = deviation + np.where(danger >= 5, np.inf, np.maximum(danger - 2.0, 0.0) ** 2 / 4.0)
    return int(np.argmin(score))


POLICIES: dict[str, Policy] = {"forward": always_forward, "rule": rule_policy}
"""Reference policies by name, as the CLI accepts them."""


class PolicyAgent:
    """A policy on phi(s) behind the :class:`~nirl_mj.sim.episode.Agent` interface."""

    acts_on_features = True  # reads phi(s) alone: one agent can drive many worlds at once

    def __init__(self, policy: Policy, kind: str) -> None:
        self.policy = policy
        self.kind = kind

    @classmethod
    def named(cls, name: str) -> PolicyAgent:
        """One of the reference policies in :data:`POLICIES`."""
        return cls(POLICIES[name], name)

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        pass

    def act(self, timestep: dm_env.TimeStep) -> int:
        return self.policy(timestep.observation["features"])
