"""SCIRL, structured classification for IRL (Klein, Geist, Piot & Pietquin 2012), as a reward step.

SCIRL reads the expert's action-value function under r_theta = theta^T f, Q_theta(s, a) =
theta^T mu_E(s, a) (eq. 3), as the score function of a linearly parameterised multi-class
classifier, and trains it to predict the expert's actions. The algorithm, in the paper's order
(steps numbered in the comments below):

1. Estimate the expert's feature expectations at every demonstrated pair (s_i, a_i) by Monte-Carlo:
   mu_hat(s_i, a_i) = sum_{k >= t} gamma^(k-t) f(s_k, a_k) along the rest of its demonstration.
2. Heuristic for the actions the expert did not take: "a non-expert action only delays the
   expert's" (the paper: mu(s, a) = gamma mu_E(s, a_E) for state features). With our state-action
   features the delay collects f(s, a) first (../shared/docs/algorithms-notes.md, SCIRL):
   mu_hat(s, a != a_E) = f(s, a) + gamma mu_hat(s, a_E).
3. Score q_theta(s, a) = theta^T mu_hat(s, a); structured large-margin criterion
   J(theta) = (1/N) sum_i [max_a (q_theta(s_i, a) + L(s_i, a)) - q_theta(s_i, a_i)],
   L = 0 for the expert's action and l otherwise; minimised by subgradient descent,
   subgradient (1/N) sum_i [mu_hat(s_i, a*_i) - mu_hat(s_i, a_i)], a*_i the loss-augmented argmax.
   As the authors' code: theta_0 = 0, the subgradient normalised, step c / (k + 1) (c = 3), 40 steps.
4. r_theta = theta^T f; then any RL algorithm (here the shared loop's neural value learning).

Readings, each with its reason (docs/ALGORITHM.md, "The baselines"):

- l = ``LoopConfig.margin_loss`` (0.1, not the paper's 1) and theta kept in the ball ||theta|| <= 1
  (projection after each step) instead of the paper's lambda/2 ||theta||^2 term, its constrained
  form: the margin then has the meaning it has in the default NIRL (rewards in the units of the
  features, in [0, 1]). Without a constraint or lambda the criterion is homogeneous in (theta, l)
  and l would only set theta's scale against the step sizes.
- The iterate kept is the one with the lowest J (the authors' code keeps the smallest subgradient
  norm; inside a ball the subgradient need not vanish at the optimum, which lies on the boundary).
- SCIRL never reads the learner's rollouts: theta is computed at the first update and stays fixed;
  the loop then learns the policy on that reward by its value targets, the model-free RL of step 4.
- gamma is the loop's (``LoopConfig.gamma``). Step 2's margin weighs the pair itself by 1 - gamma,
  so the discount matters more here than elsewhere; the comparisons' SCIRL row runs the paper's 0.65,
  tuned on the development domain (``experiments/definition.py``, tasks/ablations/scirl_tuning.toml).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from nirl_mj.learn.config import LoopConfig, ScirlConfig
from nirl_mj.learn.mmp import discounted_suffix_sums, mmp_objective, projected_subgradient, structured_loss

__all__ = ["heuristic_expectations", "minimise_scirl", "ScirlStep"]


def heuristic_expectations(
    mu_taken: np.ndarray, f_all: np.ndarray, actions: np.ndarray, gamma: float
) -> np.ndarray:
    """Steps 1-2: mu_hat(s_i, a) for every action: (N, A, D).

    mu_taken: (N, D) Monte-Carlo mu_hat(s_i, a_i) at the expert's pairs (step 1); f_all: (N, A, D)
    f(s_i, a) for every action; actions: (N,) the expert's a_i. Row (i, a_i) is mu_taken[i]; every
    other action a gets f(s_i, a) + gamma mu_taken[i] (step 2).
    """
    mu_taken = np.asarray(mu_taken, dtype=np.float64)
    # step 2: a non-expert action collects f(s, a), then the expert's own expectation, one step later
    out = np.asarray(f_all, dtype=np.float64) + gamma * mu_taken[:, None, :]
    out[np.arange(len(mu_taken)), np.asarray(actions, dtype=int)] = mu_taken  # step 1
    return out


def minimise_scirl(
    mu_all: np.ndarray, mu_taken: np.ndarray, loss: np.ndarray, steps: int, step_size: float
) -> tuple[np.ndarray, float]:
    """Step 3: theta minimising J by normalised projected subgradient descent, and its J.

    mu_all: (N, A, D) mu_hat(s_i, a); mu_taken: (N, D) mu_hat(s_i, a_i); loss: (N, A) L(s_i, a).
    theta_0 = 0; theta_{k+1} = P(theta_k - step_size / (k + 1) g_k / ||g_k||), P the projection onto
    ||theta||_2 <= 1, k = 0..steps-1 (a zero subgradient stops: every margin is met). Returns the
    iterate with the lowest J (earliest on ties), theta_0 and the last iterate included.
    """
    return projected_subgradient(
        lambda theta: mmp_objective(theta, mu_taken, mu_all, loss, 0.0),
        np.zeros(mu_all.shape[-1]),
        steps,
        step_size,
        decay=1.0,
        normalise=True,
    )


class ScirlStep:
    """SCIRL's reward step: theta from the demonstrations alone, computed once, then fixed.

    ``loop`` and ``own`` are the loop's config and this step's (``nirl_mj.learn.config``;
    reads ``gamma``, ``reward_features``,
    ``margin_loss``, ``scirl_steps``, ``scirl_step_size``). The convergence measure is J at theta:
    the mean hinge of the expert's pairs (0 when every margin is met).
    """

    def __init__(self, loop: LoopConfig, own: ScirlConfig, demos: Sequence) -> None:
        self.loop, self.own = loop, own
        self.demos = list(demos)
        self.theta: np.ndarray | None = None
        self.j = float("nan")

    def fit(self) -> tuple[np.ndarray, float]:
        """Steps 1-3 on the demonstrations (deterministic: a resumed run recomputes the same theta)."""
        from nirl_mj.data.trajectory import stack_pairs
        from nirl_mj.learn.reward import all_action_features, trajectory_pair_features

        phi, actions = stack_pairs(self.demos)
        fs = trajectory_pair_features(self.demos, self.loop.reward_features)
        mu_taken = np.concatenate([discounted_suffix_sums(f, self.loop.gamma) for f in fs])  # step 1
        mu_all = heuristic_expectations(
            mu_taken, all_action_features(phi, self.loop.reward_features), actions, self.loop.gamma
        )
        loss = structured_loss(actions, self.loop.margin_loss)  # L(s, a_E) = 0
        return minimise_scirl(mu_all, mu_taken, loss, self.own.scirl_steps, self.own.scirl_step_size)

    def update(
        self,
        theta: np.ndarray,
        trajectories: Sequence,
        iteration: int,
        greedy_on_demos: np.ndarray,
        context: object = None,
    ) -> tuple[np.ndarray, float]:
        """The fixed theta (fitted at the first call; the rollouts are not used) and its J."""
        if self.theta is None:
            self.theta, self.j = self.fit()
        return self.theta.copy(), self.j

    def state(self) -> dict[str, np.ndarray]:
        return {}  # theta is a deterministic function of the demonstrations and the configuration

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        pass
