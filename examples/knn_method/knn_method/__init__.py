"""k-nearest-neighbour behaviour cloning on phi(s): a method written outside nirl-mj.

Nothing here imports nirl-mj: the protocol hands ``train`` the demonstrations as NumPy arrays and
takes back a function from an observation (phi(s), float32 (16,)) to an action in 0..5
(docs/EXTENDING.md in nirl-mj). This method never drives the environment, so it reads only the
demonstrations and the features.
"""

from __future__ import annotations

import numpy as np


class KNN:
    """Majority vote of the ``k`` demonstrated states nearest in standardised phi(s); a tie goes to
    the nearest neighbour's action if it is among the tied ones, else to the lowest tied action."""

    reads = ("demonstrations", "features")
    observation = "features"

    def __init__(self, k: int = 5) -> None:
        if isinstance(k, bool) or not isinstance(k, int) or k < 1:
            raise TypeError(f"k = {k!r}: a whole number >= 1")
        self.k = k

    def train(self, demonstrations, make_env, budget, seed, workdir):
        x = np.asarray(demonstrations["observations"], np.float64)
        y = np.asarray(demonstrations["actions"], np.int64)
        mean, scale = x.mean(axis=0), x.std(axis=0) + 1e-6
        points = (x - mean) / scale
        k = min(self.k, len(y))

        def policy(observation: np.ndarray) -> int:
            d = np.sum(((np.asarray(observation, np.float64) - mean) / scale - points) ** 2, axis=1)
            nearest = np.argsort(d, kind="stable")[:k]
            votes = np.bincount(y[nearest], minlength=6)
            best = np.flatnonzero(votes == votes.max())
            return int(y[nearest[0]]) if y[nearest[0]] in best else int(best[0])

        return policy
