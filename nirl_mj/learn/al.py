"""Apprenticeship learning, projection method (Abbeel & Ng 2004, section 3.1), as a reward step.

The paper's algorithm; its step numbers are used in the comments below:

1. Pick some policy pi^(0) at random, estimate mu^(0) = mu(pi^(0)) by rollouts; mu_bar^(0) = mu^(0),
   w^(1) = mu_E - mu_bar^(0), i = 1.
2. (i >= 2) Projection: with d = mu^(i-1) - mu_bar^(i-2),
   mu_bar^(i-1) = mu_bar^(i-2) + [d^T (mu_E - mu_bar^(i-2)) / ||d||^2] d;
   w^(i) = mu_E - mu_bar^(i-1), t^(i) = ||w^(i)||_2.
3. If t^(i) <= epsilon, terminate.
4. Compute the optimal policy pi^(i) for the reward R = (w^(i))^T f (an RL step).
5. Estimate mu^(i) = mu(pi^(i)) by rollouts; i <- i + 1; go to step 2.

Model-free reading in the shared loop (:class:`nirl_mj.learn.loop.IrlLoop`): the loop's iteration i
rolls out the learner's current Boltzmann policy (eq. 8). At i = 0 that is the random initial
network at the schedule's low eta (nearly uniform): step 1's random policy. Afterwards it is
pi^(i), so each update does step 5 for the policy the previous update's reward produced, then
steps 2-3. Step 4 is the loop's ONE iteration of SARSA targets and backpropagation (eq. 14-15)
on r = theta^T f with the network warm-started, not an RL solve to optimality: the policy whose
mu is measured next has only partly adapted to w^(i). The loop's stopping rule (step 3) is
``LoopConfig.epsilon`` (default None: run the episode budget), and the policy reported is chosen
by the loop's ``LoopConfig.selection`` (by default balanced accuracy on the demonstrations), as
for every method, not the paper's "best t or a mixture".

Feature expectations (``ApprenticeshipConfig.al_expectations``): ``"trajectory"`` is the papers' mu (eq. 11):
each trajectory's discounted feature sum from its first pair, averaged over trajectories. With
the paper's gamma = 0.65 that weighs about the first three decisions of each trajectory, in open
space near the start (about ten at the default's 0.9; docs/ALGORITHM.md, "The baselines").
``"suffix"`` averages the discounted suffix sum of every visited pair instead, so every state
counts, but it matches state-action frequencies: measured to
collapse to "prefer forward", the action the expert takes ~91 % of the time.

``"state"`` (the default) is the per-state reading of NIRL's classifier margin
(``learn/mmp.py``, ``matching = "occupancy"``, ``future_mix = 0``): in every demonstrated state s_n
the expert's discounted suffix mu_E(s_n, a_n) = f(s_n, a_n) + gamma mu_E(next_n) is compared with
what the learner's policy pi^(i) does in the same state, sum_a pi^(i)(a | s_n) f(s_n, a) followed by
the same continuation gamma mu_E(next_n). Averaged over the N demonstrated pairs,

    mu_E = (1/N) sum_n f(s_n, a_n) + C,   mu^(i) = (1/N) sum_n sum_a pi^(i)(a | s_n) f(s_n, a) + C,

and the continuation C cancels in every difference the projection takes (step 2), so it is left out.
pi^(i) is the Boltzmann policy (eq. 8) of the network that drove the iteration's rollouts
(``RolloutContext``): step 5 measures the policy that was run, in the states the expert visits,
rather than by the states its own rollouts reach.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from nirl_mj.data.features import N_ACTIONS
from nirl_mj.learn.config import ApprenticeshipConfig, LoopConfig
from nirl_mj.learn.mmp import discounted_suffix_sums, feature_expectations
from nirl_mj.learn.reward import trajectory_pair_features

__all__ = ["expectations", "state_expectations", "project", "ProjectionStep"]


def expectations(fs: Sequence[np.ndarray], gamma: float, kind: str) -> np.ndarray:
    """Feature expectations mu (D,) of trajectories given by their pair features fs[i] (L_i, D).

    ``"trajectory"``: (1/N_T) sum_i sum_t gamma^(t-1) f(s_t^i, a_t^i) (eq. 11). ``"suffix"``: the mean
    over all M pairs of mu_hat(s_t, a_t) = sum_{k >= t} gamma^(k-t) f_k (Monte-Carlo eq. 3); zeros if
    there is no pair. Units: those of f, summed over ~1 / (1 - gamma) decisions.
    """
    if kind not in ("trajectory", "suffix"):
        raise ValueError(f"unknown expectations {kind!r}; accepted: trajectory, suffix")
    if kind == "trajectory":
        return feature_expectations(fs, gamma)
    sums = [discounted_suffix_sums(f, gamma) for f in fs if len(f)]
    if not sums:
        return np.zeros(np.shape(fs[0])[-1])
    return np.concatenate(sums).mean(axis=0)


def state_expectations(per_action: np.ndarray, probabilities: np.ndarray) -> np.ndarray:
    """The per-state reading's mu (D,) without the shared continuation: (1/N) sum_n sum_a p[n, a] f(s_n, a).

    per_action: (N, 6, D) f(s_n, a) in the demonstrated states; probabilities: (N, 6), a policy's
    pi(a | s_n) (the expert's: one-hot rows of its actions).
    """
    per_action = np.asarray(per_action, dtype=np.float64)
    return np.einsum("na,nad->d", np.asarray(probabilities, dtype=np.float64), per_action) / len(per_action)


def project(mu_bar: np.ndarray, mu: np.ndarray, mu_e: np.ndarray) -> np.ndarray:
    """Step 2: the point of the segment [mu_bar, mu] closest to mu_E, as the new mu_bar (D,).

    Abbeel & Ng project mu_E onto the LINE through mu_bar and mu: coefficient
    c = (mu - mu_bar)^T (mu_E - mu_bar) / ||mu - mu_bar||^2. The coefficient is clipped to [0, 1]
    here (a reading): mu_bar then stays the feature expectation of a mixture of the policies seen,
    and t = ||mu_E - mu_bar|| never grows. With an exact RL step c is in [0, 1] anyway; with one
    SARSA iteration per AL iteration (this loop) the new policy can be worse for w than mu_bar,
    and the unclipped line would extrapolate past every policy. mu == mu_bar leaves mu_bar as is.
    """
    mu_bar = np.asarray(mu_bar, dtype=np.float64)
    d = np.asarray(mu, dtype=np.float64) - mu_bar
    dd = float(d @ d)
    if dd == 0.0:
        return mu_bar.copy()
    # step 2: c = (mu - mu_bar)^T (mu_E - mu_bar) / ||mu - mu_bar||^2, kept in [0, 1]
    c = float(d @ (np.asarray(mu_e, dtype=np.float64) - mu_bar)) / dd
    return mu_bar + min(max(c, 0.0), 1.0) * d


class ProjectionStep:
    """AL's reward step: theta = w / ||w||, w = mu_E - mu_bar after the projection (steps 1-3).

    ``loop`` and ``own`` are the loop's config and this step's (``nirl_mj.learn.config``;
    reads ``gamma``, ``reward_features``,
    ``al_expectations``). theta is w scaled to unit norm: the loop maps rewards affinely into
    [0, 1 - gamma], so the scale of w does not change the learner; the unit norm keeps theta
    comparable with NIRL's ||theta|| <= 1. The convergence measure is t = ||w||_2.
    """

    def __init__(self, loop: LoopConfig, own: ApprenticeshipConfig, demos: Sequence) -> None:
        self.gamma = float(loop.gamma)
        self.kind = own.al_expectations
        self.features = loop.reward_features
        if self.kind == "state":
            from nirl_mj.data.trajectory import stack_pairs
            from nirl_mj.learn.reward import all_action_features

            self.demo_phi, actions = stack_pairs(demos)
            self.per_action = all_action_features(self.demo_phi, self.features)  # (N, 6, D)
            self.mu_e = state_expectations(self.per_action, np.eye(N_ACTIONS)[actions.astype(int)])
        else:  # mu_E from the demonstrations (eq. 11, or the suffix mean)
            self.mu_e = expectations(trajectory_pair_features(demos, self.features), self.gamma, self.kind)
        self.mu_bar: np.ndarray | None = None  # None until step 1 has seen the first rollouts

    def update(
        self,
        theta: np.ndarray,
        trajectories: Sequence,
        iteration: int,
        greedy_on_demos: np.ndarray,
        context: object = None,
    ) -> tuple[np.ndarray, float]:
        """Steps 5 and 2-3 (or step 1 at the first call) on this iteration's rollouts -> (theta, t)."""
        # step 5 (step 1 at the first call): mu of the policy that produced these rollouts
        if self.kind == "state":
            if context is None:
                raise ValueError("AL's per-state reading needs the rollouts' policy (RolloutContext)")
            mu = state_expectations(self.per_action, context.action_probabilities(self.demo_phi))
        else:
            mu = expectations(trajectory_pair_features(trajectories, self.features), self.gamma, self.kind)
        if self.mu_bar is None:
            self.mu_bar = mu  # step 1: mu_bar^(0) = mu^(0)
        else:
            self.mu_bar = project(self.mu_bar, mu, self.mu_e)  # step 2
        w = self.mu_e - self.mu_bar  # w^(i) = mu_E - mu_bar^(i-1)
        t = float(np.linalg.norm(w))  # t^(i) = ||w^(i)||_2; the loop applies step 3
        return (w / t if t > 0.0 else w), t

    def state(self) -> dict[str, np.ndarray]:
        return {"mu_bar": np.zeros(0) if self.mu_bar is None else self.mu_bar.copy()}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        mu_bar = np.asarray(state["mu_bar"], dtype=np.float64)
        self.mu_bar = mu_bar.copy() if mu_bar.size else None
