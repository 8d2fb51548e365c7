"""The recovered reward r_theta(s, a) = theta^T f(s, a) (paper eq. 2, 4-5), saved with names.

Three feature maps for the reward (the policy network always sees phi(s)):

- ``"paper"``: f(s, a) of eq. 4-5, phi(s) in the block of action a, 96 values;
- ``"extended"``: per action block [D/7 (7), V one-hot (9), I, U (7), 1] = 25
  values, 150 in all. Scaling D into [0, 1] makes ||theta|| <= 1 meaningful for
  every component; one-hot V lets a linear reward prefer "turn towards the
  target's sector"; the constant lets it prefer an action as such
  (../shared/docs/algorithms-notes.md, "Reward features");
- ``"bearing"``: the extended block with the target's bearing as (cos, sin) of its sector's
  centre after one-hot V, 27 values, 162 in all. One-hot V leaves a sector the expert never
  had behind it (V = 4..7: 10 of 3583 demonstrated pairs) without a learned reward; (cos, sin)
  carry "turn towards the target" learned in the sectors the expert did see over to them
  (docs/notebook/algorithm.md, "Bearing features").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from nirl_mj.data.features import ACTION_NAMES, FEATURE_NAMES, N_ACTIONS, N_SENSORS, sector_centre

REWARD_FEATURES = ("paper", "extended", "bearing")

_D, _V, _I, _U = slice(0, 7), 7, 8, slice(9, 16)


def state_reward_features(phi: np.ndarray, kind: str) -> np.ndarray:
    """phi (..., 16) -> per-action block (..., 16) for "paper", (..., 25) for "extended" or (..., 27)
    for "bearing"."""
    phi = np.asarray(phi, dtype=np.float64)
    if kind == "paper":
        return phi
    if kind not in REWARD_FEATURES:
        raise ValueError(f"unknown reward features {kind!r}; accepted: {', '.join(REWARD_FEATURES)}")
    region = np.eye(N_SENSORS)[phi[..., _V].astype(int) - 1]
    parts = [phi[..., _D] / 7.0, region]
    if kind == "bearing":
        centre = sector_centre(phi)
        parts += [np.cos(centre)[..., None], np.sin(centre)[..., None]]
    ones = np.ones((*phi.shape[:-1], 1))
    return np.concatenate([*parts, phi[..., _I, None], phi[..., _U], ones], axis=-1)


def block_names(kind: str) -> tuple[str, ...]:
    """Names of one action block's components."""
    if kind == "paper":
        return FEATURE_NAMES
    d = [n for n in FEATURE_NAMES if n.startswith("D_")]
    u = [n for n in FEATURE_NAMES if n.startswith("U_")]
    bearing = ("cos_V", "sin_V") if kind == "bearing" else ()
    return (*(f"{n}/7" for n in d), *(f"V={v}" for v in range(1, 10)), *bearing, "I", *u, "const")


def reward_feature_names(kind: str) -> tuple[str, ...]:
    """Names of all components of f(s, a): ``"<action>:<feature>"``."""
    return tuple(f"{a}:{n}" for a in ACTION_NAMES for n in block_names(kind))


def all_action_features(phi: np.ndarray, kind: str) -> np.ndarray:
    """f(s, a) for every action: phi (N, 16) -> (N, 6, 6 * block)."""
    block = state_reward_features(phi, kind)
    n, b = block.shape
    out = np.zeros((n, N_ACTIONS, N_ACTIONS * b))
    for a in range(N_ACTIONS):
        out[:, a, a * b : (a + 1) * b] = block
    return out


def pair_features(phi: np.ndarray, actions: np.ndarray, kind: str) -> np.ndarray:
    """f(s_t, a_t) for given pairs: phi (N, 16), actions (N,) -> (N, 6 * block): the state's block
    in the slot of its action, zeros elsewhere (a row of :func:`all_action_features`)."""
    block = state_reward_features(phi, kind)
    n, b = block.shape
    out = np.zeros((n, N_ACTIONS * b))
    slots = np.asarray(actions, dtype=int)[:, None] * b + np.arange(b)
    np.put_along_axis(out, slots, block, axis=1)
    return out


def trajectory_pair_features(trajectories: Sequence, kind: str, skip_empty: bool = False) -> list[np.ndarray]:
    """f(s_t, a_t) along each trajectory, (L_i, 6 * block) each; ``skip_empty`` drops those of no pair."""
    return [pair_features(t.features[:-1], t.actions, kind) for t in trajectories if len(t) or not skip_empty]


@dataclass(frozen=True)
class RewardModel:
    """theta (6 * block,) over the ``kind`` feature map; ``reward`` is r_theta(s, a)."""

    theta: np.ndarray
    kind: str = "extended"

    def __post_init__(self) -> None:
        expected = len(reward_feature_names(self.kind))
        if np.shape(self.theta) != (expected,):
            raise ValueError(
                f"theta has shape {np.shape(self.theta)}; {self.kind!r} features need ({expected},)"
            )

    def reward(self, phi: np.ndarray, action: int | np.ndarray) -> np.ndarray:
        """r_theta(s, a) for phi (N, 16) (or (16,), one state) and actions (N,) -> (N,); phi of more
        dimensions is flattened to rows, and the result with it."""
        phi = np.atleast_2d(phi)
        actions = np.broadcast_to(np.asarray(action), phi.shape[:-1]).ravel().astype(int)
        # theta^T f(s, a) = b(s) . theta_a: f is b(s) in action a's block (eq. 4-5)
        blocks = state_reward_features(phi.reshape(-1, phi.shape[-1]), self.kind)
        per_action = self.theta.reshape(N_ACTIONS, -1)
        return np.einsum("nb,nb->n", blocks, per_action[actions])

    def rewards_all_actions(self, phi: np.ndarray) -> np.ndarray:
        """r_theta(s, a) for every action: phi (N, 16) -> (N, 6)."""
        return state_reward_features(np.atleast_2d(phi), self.kind) @ self.theta.reshape(N_ACTIONS, -1).T

    def named(self) -> dict[str, float]:
        """theta by component name."""
        return dict(zip(reward_feature_names(self.kind), map(float, self.theta), strict=True))

    def to_dict(self) -> dict:
        """``{"kind", "theta": {name: value}}``: the reward file's content."""
        return {"kind": self.kind, "theta": self.named()}

    @classmethod
    def from_dict(cls, data: dict, where: str = "reward") -> RewardModel:
        """The inverse of :meth:`to_dict`; ``where`` names the source in errors."""
        try:
            kind, theta = data["kind"], data["theta"]
            names = reward_feature_names(kind)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: not a reward ({exc})") from None
        if set(theta) != set(names):
            raise ValueError(f"{where}: theta components do not match the {kind!r} reward features")
        return cls(np.array([theta[n] for n in names]), kind)
