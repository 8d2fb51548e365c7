"""A running normaliser of the rewards a policy learner is given (GAIL and AIRL's ``-norm`` option).

The imitation library's scripts wrap the reward net in ``NormalizedRewardNet(RunningNorm)`` by
default, which reaches the policy's reward in its AIRL (its GAIL pays ``-log sigmoid`` of the
unnormalised logits): each reward handed to the policy learner is centred and scaled by the mean
and variance of all the rewards handed out so far, itself included. Centring the reward on its
running mean weakens the incentive to end episodes early (a reward negative on average) or to drag
them out (positive on average) that Kostrikov et al. (2019) call the termination bias.
"""

from __future__ import annotations

import numpy as np


class RunningNorm:
    """Mean and (population) variance of every value seen so far, merged batch by batch with Chan,
    Golub & LeVeque's (1979) pairwise update. Before any value: mean 0, variance 1 (the identity)."""

    def __init__(self, eps: float = 1e-5) -> None:
        self.eps = float(eps)
        self.mean, self.var, self.count = 0.0, 1.0, 0

    def __call__(self, values: np.ndarray) -> np.ndarray:
        """``values`` (N,) join the statistics, then are normalised by them (the order of the
        imitation library's RunningNorm in training mode). Its reward wrapper normalises first and
        updates after; with one environment that divides the second reward by the zero variance
        of the first (a z of hundreds), which this order cannot do."""
        values = np.asarray(values, dtype=np.float64)
        self.update(values)
        return (values - self.mean) / np.sqrt(self.var + self.eps)

    def update(self, values: np.ndarray) -> None:
        """Merges a batch (N,) into the statistics."""
        n = int(np.size(values))
        if n == 0:
            return
        batch_mean, batch_var = float(np.mean(values)), float(np.var(values))
        total = self.count + n
        delta = batch_mean - self.mean
        self.mean += delta * n / total
        self.var = (self.var * self.count + batch_var * n + delta**2 * self.count * n / total) / total
        self.count = total

    def state(self) -> np.ndarray:
        """(3,) float64: mean, variance, count (saved with a run, so a resume goes on with them)."""
        return np.array([self.mean, self.var, self.count], dtype=np.float64)

    def load_state(self, state: np.ndarray) -> None:
        self.mean, self.var, self.count = float(state[0]), float(state[1]), int(state[2])
