"""On-policy SARSA targets for the neural policy iteration (paper section IV-C, eq. 14).

Q-values are the network's outputs in (0, 1) (eq. 7), so the targets are
clipped to [0, 1]; the share that needed clipping is returned so callers can
see when the reward scale does not fit (see docs: rewards of +-3 clipped 93 %).
"""

from __future__ import annotations

import numpy as np

__all__ = ["sarsa_targets"]


def sarsa_targets(
    q_sa: np.ndarray,
    rewards: np.ndarray,
    q_next: np.ndarray,
    terminal: np.ndarray,
    alpha: float,
    gamma: float,
    terminal_values: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """SARSA targets Qhat(s_t, a_t) (eq. 14), clipped to [0, 1].

    q_sa: (N,) Q(s_t, a_t) of the taken actions; rewards: (N,) r_theta(s_t, a_t)
    (eq. 2, Q units); q_next: (N,) Q(s_{t+1}, a_{t+1}) of the next pair taken by
    the policy (ignored, may be NaN, where terminal); terminal: (N,) bool, True
    where s_{t+1} ends the episode and there is no bootstrap; terminal_values:
    (N,) value used instead of gamma Q(s', a') at terminal pairs (default 0;
    read only where terminal). alpha: learning rate in [0, 1]; gamma: discount.

    Returns (targets (N,) float64 in [0, 1], share of the N raw targets outside
    [0, 1] that were clipped; 0.0 for N = 0).
    """
    q_sa = np.asarray(q_sa, dtype=np.float64)
    rewards = np.asarray(rewards, dtype=np.float64)
    q_next = np.asarray(q_next, dtype=np.float64)
    terminal = np.asarray(terminal, dtype=bool)
    if terminal_values is None:
        tv = np.zeros_like(q_sa)
    else:
        tv = np.broadcast_to(np.asarray(terminal_values, dtype=np.float64), q_sa.shape)
    # Bootstrap term: gamma Q(s_{t+1}, a_{t+1}), or the terminal value where the episode ended.
    future = np.where(terminal, tv, gamma * np.where(terminal, 0.0, q_next))
    # eq. 14: Qhat(s_t,a_t) = Q(s_t,a_t) + alpha [r_theta(s_t,a_t) + gamma Q(s_{t+1},a_{t+1}) - Q(s_t,a_t)]
    raw = q_sa + alpha * (rewards + future - q_sa)
    clipped = (raw < 0.0) | (raw > 1.0)
    share = float(clipped.mean()) if raw.size else 0.0
    return np.clip(raw, 0.0, 1.0), share
