"""Relative entropy IRL, model-free (Boularias, Kober & Peters 2011), as a reward step.

RE-IRL finds the trajectory distribution P closest in relative entropy to a baseline distribution
Q (the uniform policy's, under the unknown dynamics) whose feature counts match the expert's within
epsilon_i per component. Its dual is maximised by (sub)gradient ascent on theta:

    g(theta) = theta^T f_hat - ln Z(theta) - sum_i epsilon_i |theta_i|,
    Z(theta) = sum_tau Q(tau) exp(theta^T f^tau).

The model-free algorithm, in the order of the paper (steps numbered in the comments below):

1. f_hat = mu_E: the expert's mean feature counts f^tau = sum_t gamma^(t-1) f(s_t, a_t) (eq. 11).
2. epsilon_i from Hoeffding's bound: range_i sqrt(-ln(1 - delta) / (2 N_T)) sum_{k<H} gamma^k, with
   range_i the range of one pair's f_i, N_T the demonstrations, H the pairs per sample.
3. Sample trajectories tau from a known policy pi; Z is estimated by importance sampling,
   Z ~ (1/M) sum_tau [U(tau) / pi(tau)] exp(theta^T f^tau): the dynamics cancel in U / pi, which is
   the product over the pairs of U(a_t | s_t) / pi(a_t | s_t), U = 1/6 (uniform over 6 actions).
4. Repeat: importance weights w_tau = softmax_tau(ln[U(tau) / pi(tau)] + theta^T f^tau) (log-sum-exp),
   (sub)gradient  dg/dtheta = f_hat - sum_tau w_tau f^tau - epsilon (.) sign(theta),
   theta <- theta + re_step * gradient (the paper; the proximal form below is the default).
5. Output r_theta = theta^T f; then RL on it.

Readings in the shared loop (:class:`nirl_mj.learn.loop.IrlLoop`), each with its reason:

- The samples (step 3) are the learner's own rollouts, not a uniform policy's: the uniform policy
  crashes within a few decisions in these arenas (the 2-D prototype: 95 % of near-uniform training
  trajectories crashed near the start), so its samples would never show what the expert's
  trajectories look like further on. pi(a_t | s_t) is the Boltzmann probability (eq. 8) of the
  logged action under the network and eta that produced the rollout (``RolloutContext``, a
  snapshot taken before the loop fits the network), and is stored with the sample.
- Samples of the last ``re_pool`` iterations are pooled, each with its own behaviour policy's
  ratio U / pi (each batch is an unbiased importance-sampling estimate of Z; their sum too).
- Each sample is the first H = ``re_horizon`` pairs of a trajectory, for f^tau and for U / pi alike,
  on the expert's side too (step 1, normalised the same way). gamma^H is 1e-3 at H = 16 and the
  paper's gamma = 0.65, so f^tau loses almost nothing there (0.19 at the default's 0.9), and the
  importance ratio of pairs that do not change f^tau is left out: over a whole trajectory
  (~100-300 decisions) it would put all weight on one sample.
- theta is warm-started from the previous iteration; ``re_steps`` ascent steps per iteration
  (the paper iterates to convergence on a fixed sample set; here the samples move with the
  learner, as its rollouts change).
- The L1 term is stepped by its proximal map (soft-thresholding, ``re_l1_step = "proximal"``), the
  same objective g: with the paper's subgradient and a fixed step, every theta_i whose data gradient
  stays within +-epsilon_i flips by +-re_step epsilon_i around 0 at every step instead of resting
  there. Measured (30 demonstrations, seed 0): 148 of 150 components chattered at |theta_i| ~ 0.32,
  a reward made mostly of noise, and the run collapsed to "always forward" (docs/ALGORITHM.md).
- ``re_expectations = "suffix"``: every visited pair starts a sample (its discounted suffix, H
  pairs, and that window's ratio), on both sides, instead of each trajectory's start only.
- ``re_expectations = "state"`` (the default since 2026-11-25): the per-state reading of NIRL's
  classifier margin (``matching = "occupancy"``, ``learn/mmp.py``; AL's in ``learn/al.py``). Every
  demonstrated state s_n is its own sample space: the expert's suffix mu_E(s_n, a_n) = f(s_n, a_n) +
  gamma mu_E(next_n) against the alternatives f(s_n, a) + gamma mu_E(next_n), the continuation
  shared, so it cancels in the dual. The importance-sampling estimate of Z_n over actions a ~ pi(. |
  s_n) has an exact expectation, E_pi[U(a) / pi(a | s_n) exp(theta^T f(s_n, a))] = sum_a U(a)
  exp(theta^T f(s_n, a)), whatever pi is; it is used as is (zero variance), so the learner's
  rollouts drop out of this reading, as they do for SCIRL. The dual becomes an L1-regularised
  conditional logit of the expert's actions, g(theta) = (1/N) sum_n [theta^T f(s_n, a_n) - ln sum_a
  U(a) exp(theta^T f(s_n, a))] - sum_i eps_i |theta_i|, with eps_i of step 2 for one pair (H = 1)
  and N_T demonstrations.

The convergence measure is the norm of the (proximal) gradient at the returned theta: 0 at the
maximum of g on the current samples.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.special import logsumexp

from nirl_mj.data.features import N_ACTIONS
from nirl_mj.learn.config import EXPECTATIONS, LoopConfig, RelativeEntropyConfig

__all__ = [
    "EXPECTATIONS",
    "windowed_sums",
    "log_importance_ratios",
    "hoeffding_widths",
    "importance_weights",
    "dual_gradient",
    "soft_threshold",
    "ascent_step",
    "state_data_gradient",
    "l1_step",
    "samples",
    "RelativeEntropyStep",
]

L1_STEPS = ("proximal", "subgradient")


def windowed_sums(f: np.ndarray, gamma: float, horizon: int) -> np.ndarray:
    """Discounted sums over H = ``horizon`` pairs from every start: f (T, D) -> (T, D) float64.

    Row t = sum_{k=0}^{min(H, T - t) - 1} gamma^k f_{t+k}; row 0 is a trajectory's truncated f^tau.
    """
    f = np.asarray(f, dtype=np.float64)
    out = np.empty_like(f)
    acc = np.zeros(f.shape[1:])
    drop = float(gamma) ** int(horizon)
    for t in range(f.shape[0] - 1, -1, -1):
        acc = f[t] + gamma * acc
        if t + horizon < f.shape[0]:
            acc = acc - drop * f[t + horizon]  # pair t + H left the window
        out[t] = acc
    return out


def log_importance_ratios(p_taken: np.ndarray, horizon: int) -> np.ndarray:
    """ln[U / pi] over H pairs from every start: p_taken (T,) = pi(a_t | s_t) -> (T,).

    Row t = sum_{k=t}^{min(t + H, T) - 1} [ln(1/6) - ln pi(a_k | s_k)] (step 3: the dynamics cancel).
    """
    per_pair = -np.log(N_ACTIONS) - np.log(np.asarray(p_taken, dtype=np.float64))
    cum = np.concatenate([[0.0], np.cumsum(per_pair)])
    t = np.arange(per_pair.size)
    return cum[np.minimum(t + horizon, per_pair.size)] - cum[t]


def hoeffding_widths(
    feature_range: np.ndarray, n_demos: int, gamma: float, horizon: int, confidence: float
) -> np.ndarray:
    """Step 2: epsilon_i = range_i sqrt(-ln(1 - delta) / (2 N_T)) sum_{k<H} gamma^k, shape of range.

    ``confidence`` delta in [0, 1); 0 gives epsilon = 0 (no L1 term). range_i: the range of one
    pair's feature f_i; sum_{k<H} gamma^k turns it into the range of a sample's f_i^tau.
    """
    if not 0.0 <= confidence < 1.0:
        raise ValueError(f"re_confidence must be in [0, 1), got {confidence}")
    horizon_sum = (1.0 - gamma**horizon) / (1.0 - gamma)
    return (
        np.asarray(feature_range, dtype=np.float64)
        * np.sqrt(-np.log1p(-confidence) / (2.0 * n_demos))
        * horizon_sum
    )


def importance_weights(theta: np.ndarray, f: np.ndarray, log_ratio: np.ndarray) -> np.ndarray:
    """Step 4: w_tau = [U/pi](tau) exp(theta^T f^tau) / sum_tau' (same), by log-sum-exp: (M,)."""
    logits = np.asarray(log_ratio, dtype=np.float64) + np.asarray(f, dtype=np.float64) @ theta
    return np.exp(logits - logsumexp(logits))


def dual_gradient(
    theta: np.ndarray, mu_e: np.ndarray, f: np.ndarray, log_ratio: np.ndarray, eps: np.ndarray
) -> np.ndarray:
    """Step 4: dg/dtheta = mu_E - sum_tau w_tau f^tau - eps (.) sign(theta), (D,).

    theta, mu_e, eps: (D,); f: (M, D) sample feature counts; log_ratio: (M,) ln[U(tau)/pi(tau)].
    sign(0) = 0: at theta_i = 0 the subgradient of -eps_i |theta_i| is taken as 0 (in [-eps_i, eps_i]).
    """
    theta = np.asarray(theta, dtype=np.float64)
    w = importance_weights(theta, f, log_ratio)
    return np.asarray(mu_e) - w @ np.asarray(f, dtype=np.float64) - np.asarray(eps) * np.sign(theta)


def soft_threshold(x: np.ndarray, width: np.ndarray) -> np.ndarray:
    """The proximal map of width_i |x_i|: sign(x) max(|x| - width, 0), elementwise."""
    return np.sign(x) * np.maximum(np.abs(x) - width, 0.0)


def state_data_gradient(theta: np.ndarray, mu_e: np.ndarray, per_action: np.ndarray) -> np.ndarray:
    """The per-state reading's smooth gradient, mu_E - (1/N) sum_n sum_a p_n(a) f(s_n, a), (D,).

    per_action: (N, 6, D) f(s_n, a) in the demonstrated states; p_n = softmax_a theta^T f(s_n, a)
    (the uniform baseline U cancels in the softmax); mu_e: (D,) the mean of f(s_n, a_n).
    """
    per_action = np.asarray(per_action, dtype=np.float64)
    logits = per_action @ np.asarray(theta, dtype=np.float64)  # (N, 6)
    p = np.exp(logits - logsumexp(logits, axis=1, keepdims=True))
    return np.asarray(mu_e) - np.einsum("na,nad->d", p, per_action) / len(per_action)


def l1_step(theta: np.ndarray, data: np.ndarray, eps: np.ndarray, step: float, proximal: bool) -> np.ndarray:
    """theta (D,) moved along the smooth gradient ``data`` of g with its L1 term -sum eps_i |theta_i|:
    the subgradient step theta + step (data - eps sign(theta)), or the proximal one (ISTA)
    soft_threshold(theta + step data, step eps)."""
    theta = np.asarray(theta, dtype=np.float64)
    if not proximal:
        return theta + step * (np.asarray(data) - np.asarray(eps) * np.sign(theta))
    return soft_threshold(theta + step * np.asarray(data), step * np.asarray(eps))


def ascent_step(
    theta: np.ndarray,
    mu_e: np.ndarray,
    f: np.ndarray,
    log_ratio: np.ndarray,
    eps: np.ndarray,
    step: float,
    proximal: bool,
) -> np.ndarray:
    """One step 4 update of theta (D,) on g, by subgradient or proximal gradient.

    Subgradient (the paper): theta + step dg/dtheta (:func:`dual_gradient`). Proximal (ISTA, the
    same objective): theta' = soft_threshold(theta + step (mu_E - sum w f), step eps); the smooth part
    takes the gradient step and the L1 term its exact proximal step, so a component whose data
    gradient stays within +-eps_i rests at exactly 0. With a fixed step the subgradient form never
    rests there: such a component flips by +-step eps_i every step.
    """
    data = np.asarray(mu_e) - importance_weights(theta, f, log_ratio) @ np.asarray(f, dtype=np.float64)
    return l1_step(theta, data, eps, step, proximal)


def samples(
    fs: Sequence[np.ndarray], p_taken: Sequence[np.ndarray], gamma: float, horizon: int, kind: str, dim: int
) -> tuple[np.ndarray, np.ndarray]:
    """Importance samples of trajectories: (f^tau (M, dim), ln[U/pi](tau) (M,)).

    fs[i]: pair features f(s_t, a_t) (L_i, dim) of trajectory i; p_taken[i]: pi(a_t | s_t) (L_i,).
    ``kind`` "trajectory": one sample per non-empty trajectory, its first H pairs; "suffix": one
    per pair, the H pairs from it.
    """
    if kind not in ("trajectory", "suffix"):
        raise ValueError(f"samples of re_expectations {kind!r}: accepted: trajectory, suffix")
    keep = slice(None) if kind == "suffix" else slice(0, 1)
    f_out, r_out = [np.zeros((0, dim))], [np.zeros(0)]
    for f, p in zip(fs, p_taken, strict=True):
        if len(f):
            f_out.append(windowed_sums(f, gamma, horizon)[keep])
            r_out.append(log_importance_ratios(p, horizon)[keep])
    return np.concatenate(f_out), np.concatenate(r_out)


class RelativeEntropyStep:
    """RE-IRL's reward step: ``re_steps`` ascent steps on g(theta) over the pooled samples.

    ``loop`` and ``own`` are the loop's config and this step's (``nirl_mj.learn.config``;
    reads ``gamma``, ``reward_features``,
    ``re_*``). ``update`` needs the ``context`` (the rollouts' policy) for pi(tau).
    """

    def __init__(self, loop: LoopConfig, own: RelativeEntropyConfig, demos: Sequence) -> None:
        from nirl_mj.data.trajectory import stack_pairs
        from nirl_mj.learn.reward import all_action_features, trajectory_pair_features

        self.loop, self.own = loop, own
        if self.own.re_horizon < 1 or self.own.re_pool < 1:
            raise ValueError("re_horizon and re_pool must be >= 1")
        if self.own.re_l1_step not in L1_STEPS:
            raise ValueError(f"unknown re_l1_step {self.own.re_l1_step!r}; accepted: {', '.join(L1_STEPS)}")
        phi, actions = stack_pairs(demos)
        per_action = all_action_features(phi, self.loop.reward_features)  # (N, 6, D)
        self.dim = per_action.shape[-1]
        self.per_state = self.own.re_expectations == "state"
        if self.per_state:  # every demonstrated state is a sample space of its own (module docstring)
            self.per_action = per_action
            self.mu_e = per_action[np.arange(len(actions)), actions.astype(int)].mean(axis=0)
        else:  # step 1: f_hat = mu_E, the expert's samples truncated and normalised as the learner's
            fs = trajectory_pair_features(demos, self.loop.reward_features)
            uniform = [np.full(len(f), 1.0 / N_ACTIONS) for f in fs]  # (the expert's ratios are not used)
            expert, _ = samples(
                fs, uniform, self.loop.gamma, self.own.re_horizon, self.own.re_expectations, self.dim
            )
            self.mu_e = expert.mean(axis=0)
        # step 2: range_i of one pair's f_i over the demonstrated states and every action (f_i is 0 in
        # the other actions' blocks, so 0 is in the range; "bearing" features can be negative)
        feature_range = per_action.max(axis=(0, 1)) - per_action.min(axis=(0, 1))
        horizon = 1 if self.per_state else self.own.re_horizon
        self.eps = hoeffding_widths(
            feature_range, len(demos), self.loop.gamma, horizon, self.own.re_confidence
        )
        self.pool: list[tuple[np.ndarray, np.ndarray]] = []  # per iteration: (f^tau (M_k, D), ln U/pi (M_k,))

    def update(
        self,
        theta: np.ndarray,
        trajectories: Sequence,
        iteration: int,
        greedy_on_demos: np.ndarray,
        context=None,
    ) -> tuple[np.ndarray, float]:
        """Step 3 on this iteration's rollouts, then step 4 -> (theta, ||gradient||)."""
        from nirl_mj.learn.reward import pair_features

        proximal = self.own.re_l1_step == "proximal"
        theta = np.array(theta, dtype=np.float64)
        if self.per_state:  # the rollouts drop out (module docstring): ascent on the fixed dual
            for _ in range(self.own.re_steps):
                data = state_data_gradient(theta, self.mu_e, self.per_action)
                theta = l1_step(theta, data, self.eps, self.own.re_step, proximal)
            data = state_data_gradient(theta, self.mu_e, self.per_action)
            after = l1_step(theta, data, self.eps, self.own.re_step, proximal)
            return theta, float(np.linalg.norm(after - theta) / self.own.re_step)
        if context is None:
            raise ValueError(
                "RE-IRL's importance weights need the rollouts' policy (the loop's RolloutContext)"
            )
        # step 3: the learner's rollouts as samples, with pi(a_t | s_t) of the policy that drove them
        fs, p_taken = [], []
        for t in trajectories:
            fs.append(pair_features(t.features[:-1], t.actions, self.loop.reward_features))
            probs = context.action_probabilities(t.features[:-1]) if len(t) else np.zeros((0, N_ACTIONS))
            p_taken.append(probs[np.arange(len(t)), np.asarray(t.actions, dtype=int)])
        fresh = samples(fs, p_taken, self.loop.gamma, self.own.re_horizon, self.own.re_expectations, self.dim)
        self.pool = [*self.pool, fresh][-self.own.re_pool :]
        f = np.concatenate([s[0] for s in self.pool])
        log_ratio = np.concatenate([s[1] for s in self.pool])
        if len(f) == 0:
            return theta, float("nan")
        # step 4: ascent on the dual, warm-started from the last theta
        for _ in range(self.own.re_steps):
            theta = ascent_step(theta, self.mu_e, f, log_ratio, self.eps, self.own.re_step, proximal)
        # convergence: the (proximal) gradient at theta, 0 at the maximum of g
        after = ascent_step(theta, self.mu_e, f, log_ratio, self.eps, self.own.re_step, proximal)
        return theta, float(np.linalg.norm(after - theta) / self.own.re_step)

    def state(self) -> dict[str, np.ndarray]:
        f = np.concatenate([s[0] for s in self.pool]) if self.pool else np.zeros((0, self.dim))
        r = np.concatenate([s[1] for s in self.pool]) if self.pool else np.zeros(0)
        return {"pool_f": f, "pool_log_ratio": r, "pool_sizes": np.array([len(s[1]) for s in self.pool])}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        f, r = np.asarray(state["pool_f"]), np.asarray(state["pool_log_ratio"])
        self.pool, start = [], 0
        for size in np.asarray(state["pool_sizes"], dtype=int):
            self.pool.append((f[start : start + size].copy(), r[start : start + size].copy()))
            start += size
