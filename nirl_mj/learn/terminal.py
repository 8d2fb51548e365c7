"""The value of an episode's end (an absorbing state) in the inner learner's targets.

An episode that ends (a terminal state, not a timeout's truncation) leaves the learner in an
absorbing state; the value targets of eq. 14 need that state's value. Two readings
(``LoopConfig.terminal_value``):

- ``"learned"`` (the default): the absorbing state's reward is learned from the demonstrations
  and the learner's own rollouts, reading only phi(s_T) and that the episode ended. Its weights
  are the feature-matching direction of apprenticeship learning (Abbeel & Ng 2004) on the
  absorbing component, w = mu_E^end - mu_pi^end, the mean reward block b(s_T) of the expert's
  episode ends minus the learner's (``learn/reward.py``); the absorbing value of an end s_T is
  w . b(s_T) mapped so that the expert's mean end is worth 1 and the learner's worst end in the
  batch 0 (clipped to [0, 1]: what the best scaled reward, 1 - gamma a step, earns forever).
  The scale is relative to the batch of ends it is given (the replay window): when the window
  mixes arrivals and collisions, the learner's arrivals end where the expert's do and come out
  near 1, its collisions (danger 7 in their blocks) near 0; the learner's worst end is
  worth 0, even in a window of arrivals only, and a window of one end gives it 0; unless the
  learner's mean end block is the expert's (w = 0: nothing tells them apart), when every end is
  worth 1 (tests/test_information_budget.py pins these cases). As DAC's absorbing state does for GAIL
  (Kostrikov et al. 2019), this makes an episode's end neither free nor fixed in value, without a
  task signal.
- ``"outcome"``: ``terminal_arrival_value`` for an arrival, 0 for any other end. It reads the
  task's outcome (``task_outcome`` in ``nirl_mj.experiments.reads``): the oracle row. With an
  arrival value of 0 (the paper preset) every end is worth 0 and nothing is read.
"""

from __future__ import annotations

import numpy as np

from nirl_mj.learn.reward import state_reward_features


def absorbing_values(expert_ends: np.ndarray, learner_ends: np.ndarray, kind: str) -> np.ndarray:
    """The learned absorbing value of each of the learner's episode ends, in [0, 1].

    expert_ends: (M, 16) phi(s_T) where the expert's demonstrations ended (terminal ones);
    learner_ends: (K, 16) phi(s_T) where the learner's episodes ended; ``kind`` the reward
    features (``learn/reward.py``). Returns (K,) float64. With no expert end (every demonstration
    truncated) or no learner end there is nothing to match: every value is 0.
    """
    learner_ends = np.asarray(learner_ends, dtype=np.float64).reshape(-1, 16)
    expert_ends = np.asarray(expert_ends, dtype=np.float64).reshape(-1, 16)
    if len(learner_ends) == 0 or len(expert_ends) == 0:
        return np.zeros(len(learner_ends))
    mine = state_reward_features(learner_ends, kind)
    w = state_reward_features(expert_ends, kind).mean(axis=0) - mine.mean(axis=0)
    scores = mine @ w
    # (mu_E - mu_pi) . w = |w|^2 > 0, so the expert's mean end scores above the learner's mean end,
    # and so above the learner's worst: the span below is positive unless w = 0 (the ends match).
    top = float(state_reward_features(expert_ends, kind).mean(axis=0) @ w)
    low = float(scores.min())
    if top - low <= 1e-12:  # w = 0: the learner's mean end is the expert's, no end is told apart
        return np.ones(len(learner_ends))
    return np.clip((scores - low) / (top - low), 0.0, 1.0)
