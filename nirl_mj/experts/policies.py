"""Reference policies on phi(s): the yardsticks every learner is shown next to.

A policy maps phi(s) (16,) to an action index 0..5. ``always_forward`` is what
a collapsed learner becomes; ``rule_policy`` is a hand-written rule on the same
16 features, showing how much of the task the features can carry.
"""

from __future__ import annotations

from collections.abc import Callable

import dm_env
import numpy as np

from nirl_mj.data import features

Policy = Callable[[np.ndarray], int]

# Heading change of actions 0..4 in degrees (5 is backward).
_TURNS = np.array([0.0, 30.0, 60.0, -30.0, -60.0])
_BACKWARD = 5
_RULED_OUT = 5.0  # danger level from which the rule rules an arc out


def always_forward(phi: np.ndarray) -> int:
    """Action 0 whatever the state."""
    return 0


def _angle_gap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| wrapped to [0, 180] degrees, broadcast over a[:, None] and b[None, :]."""
    return np.abs((a[:, None] - b[None, :] + 180.0) % 360.0 - 180.0)


# Directions (degrees) of the sensors in phi's danger block [S1, S2, S3, S4, S7, S8, S9].
_PHI_SENSOR_DEG = np.degrees(features.SENSOR_ANGLES[list(features.FEATURE_SENSORS)])
# Danger seen along action a from phi sensor j is danger_j - _FADE[a, j]: a sensor's level fades by
# two levels per 40 degrees away from its cone's centre, taken at the arc's chord (half its turn) and
# at its final heading.
_FADE = (2.0 / 40.0) * np.minimum(
    _angle_gap(_TURNS / 2.0, _PHI_SENSOR_DEG), _angle_gap(_TURNS, _PHI_SENSOR_DEG)
)
# Deviation of each action's heading change from the centre of target sector V = 1..9 (row V - 1),
# in units of 60 degrees.
_DEVIATION = _angle_gap(np.arange(features.N_SENSORS) * 40.0, _TURNS) / 60.0


def rule_scores(phi: np.ndarray) -> np.ndarray:
    """The rule's scores (..., 5) of the forward actions on phi(s) (..., 16): deviation from the
    target sector plus a penalty growing with danger (lower is better, ``inf`` ruled out)."""
    phi = np.asarray(phi, dtype=np.float64)
    danger = np.max(phi[..., None, 0:7] - _FADE, axis=-1)
    region = phi[..., 7].astype(np.int64)
    penalty = np.maximum(danger - 2.0, 0.0) ** 2 / 4.0
    return np.where(danger >= _RULED_OUT, np.inf, _DEVIATION[region - 1] + penalty)


def rule_actions(phi: np.ndarray) -> np.ndarray:
    """:func:`rule_policy` on a batch: phi(s) (n, 16) -> actions (n,), in one set of numpy calls."""
    scores = rule_scores(phi)
    return np.where(np.isinf(scores).all(axis=-1), _BACKWARD, np.argmin(scores, axis=-1))


def rule_policy(phi: np.ndarray) -> int:
    """Turn towards the target sector V along the safest way; back off when boxed in.

    Every action but backward travels about one metre along an arc, so an action
    is judged by the danger along its chord (half its turn) and at its final
    heading. Actions with danger 5 or more there (clearance under 2.3 m by
    default: two decisions of travel at 2 m/s) are ruled out; the rest are scored by their deviation
    from the target's bearing plus a penalty growing with danger. With no
    action left, backward.
    """
    return int(rule_actions(np.asarray(phi)[None])[0])


POLICIES: dict[str, Policy] = {"forward": always_forward, "rule": rule_policy}
"""Reference policies by name, as the CLI accepts them."""

BATCHED: dict[Policy, Callable[[np.ndarray], np.ndarray]] = {
    always_forward: lambda phi: np.zeros(len(phi), dtype=np.int64),
    rule_policy: rule_actions,
}
"""The reference policies' batch forms: phi(s) (n, 16) -> actions (n,), the same choices."""


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

    def act_batch(self, phi: np.ndarray) -> np.ndarray:
        """Actions (n,) for the phi(s) (n, 16) of n worlds at once: one set of numpy calls where the
        policy has a batch form (:data:`BATCHED`), else the policy state by state."""
        batch = BATCHED.get(self.policy)
        if batch is not None:
            return batch(np.asarray(phi))
        return np.array([self.policy(p) for p in phi], dtype=np.int64)
