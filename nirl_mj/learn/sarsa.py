"""Value targets for the neural policy iteration: on-policy SARSA (paper section IV-C, eq. 14),
and the n-step returns of the default variant (docs/notebook/algorithm.md, "The default's inner learner").

Q-values are the network's outputs in (0, 1) (eq. 7), so the targets are
clipped to [0, 1]; the share that needed clipping is returned so callers can
see when the reward scale does not fit (the rewards are scaled into [0, 1 - gamma] so that
they do, ``LoopConfig.reward_scaling``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["n_step_returns", "sarsa_targets"]


def n_step_returns(
    rewards: np.ndarray, future: np.ndarray, remaining: np.ndarray, gamma: float, n: int
) -> np.ndarray:
    """n-step returns G_t = sum_(k<m) gamma^k r_(t+k) + gamma^(m-1) future_(t+m-1), m = min(n, remaining_t).

    rows are consecutive pairs of trajectories; rewards: (N,); future: (N,) what follows each
    row's own step in a one-step target (gamma Q(s', a'), or the terminal value at the end of an
    episode); remaining: (N,) ints >= 1, the pairs from this row to the end of its trajectory
    (this one included), so the sum never crosses into the next trajectory. n = 1 gives
    r_t + future_t, eq. 14's one-step target. Returns (N,) float64.
    """
    rewards = np.asarray(rewards, dtype=np.float64)
    future = np.asarray(future, dtype=np.float64)
    remaining = np.asarray(remaining, dtype=np.int64)
    if n < 1:
        raise ValueError(f"n-step returns need n >= 1, got {n}")
    if rewards.size and remaining.min() < 1:
        raise ValueError("remaining counts the row itself: every entry must be >= 1")
    rows = np.arange(rewards.size)
    m = np.minimum(int(n), remaining)
    returns = np.zeros_like(rewards)
    for k in range(int(n)):
        ahead = np.minimum(rows + k, rewards.size - 1)
        returns += np.where(k < m, gamma**k * rewards[ahead], 0.0)
    return returns + gamma ** (m - 1) * future[rows + m - 1]


def sarsa_targets(
    q_sa: np.ndarray,
    rewards: np.ndarray,
    q_next: np.ndarray,
    terminal: np.ndarray,
    alpha: float,
    gamma: float,
    terminal_values: np.ndarray | None = None,
    remaining: np.ndarray | None = None,
    n_step: int = 1,
) -> tuple[np.ndarray, float]:
    """SARSA targets Qhat(s_t, a_t) (eq. 14), clipped to [0, 1].

    q_sa: (N,) Q(s_t, a_t) of the taken actions; rewards: (N,) r_theta(s_t, a_t)
    (eq. 2, Q units); q_next: (N,) Q(s_{t+1}, a_{t+1}) of the next pair taken by
    the policy (or max_a Q(s_{t+1}, a) for Q-learning targets; ignored, may be
    NaN, where terminal); terminal: (N,) bool, True where s_{t+1} ends the
    episode and there is no bootstrap; terminal_values: (N,) value used instead
    of gamma Q(s', a') at terminal pairs (default 0; read only where terminal).
    alpha: learning rate in [0, 1]; gamma: discount. n_step > 1 replaces
    r + gamma Q' by the n-step return (:func:`n_step_returns`), which needs
    ``remaining`` (N,), the pairs left in each row's trajectory.

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
    if n_step == 1:
        returns = rewards + future
    elif remaining is None:
        raise ValueError("n-step targets need `remaining`, the pairs left in each row's trajectory")
    else:
        returns = n_step_returns(rewards, future, remaining, gamma, n_step)
    # eq. 14: Qhat(s_t,a_t) = Q(s_t,a_t) + alpha [r_theta(s_t,a_t) + gamma Q(s_{t+1},a_{t+1}) - Q(s_t,a_t)]
    raw = q_sa + alpha * (returns - q_sa)
    clipped = (raw < 0.0) | (raw > 1.0)
    share = float(clipped.mean()) if raw.size else 0.0
    return np.clip(raw, 0.0, 1.0), share
