"""How predictable a demonstrator's actions are from phi(s).

A learner that sees only the 16 features can imitate only what the features
explain: a demonstrator that turns for reasons phi(s) does not contain makes
learners collapse to "always forward" (../shared/docs/algorithms-notes.md).
The measure: a class-weighted multinomial logistic regression on phi(s),
trained on the first half of the trajectories and scored on the second half by
balanced accuracy (mean per-action recall), which a majority-class guess
cannot inflate.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import minimize

from nirl_mj.data.features import N_ACTIONS, N_SENSORS
from nirl_mj.data.trajectory import Trajectory, stack_pairs


def balanced_accuracy(y_true: np.ndarray, y_pred: np.ndarray) -> float:
    """Mean recall over the actions that occur in ``y_true``; nan if it is empty."""
    y_true, y_pred = np.asarray(y_true), np.asarray(y_pred)
    recalls = [np.mean(y_pred[y_true == a] == a) for a in np.unique(y_true)]
    return float(np.mean(recalls)) if recalls else float("nan")


def classifier_inputs(phi: np.ndarray) -> np.ndarray:
    """phi (N, 16) -> (N, 24): the target region V one-hot (it is a sector, not a
    quantity), the other 15 features as they are."""
    phi = np.asarray(phi, dtype=np.float64)
    region = np.eye(N_SENSORS)[phi[:, 7].astype(int) - 1]
    return np.concatenate([phi[:, :7], phi[:, 8:], region], axis=1)


class LogisticRegression:
    """Multinomial logistic regression with L2, fitted by L-BFGS on standardised inputs.

    With ``balanced`` each sample weighs n / (k * n_a) for its action a (k
    actions seen): the fit then aims at balanced accuracy instead of letting
    "forward", 90 % of the labels, drown the turns.
    """

    def __init__(self, l2: float = 1e-3, balanced: bool = True) -> None:
        self.l2 = l2
        self.balanced = balanced

    def fit(self, x: np.ndarray, y: np.ndarray) -> LogisticRegression:
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=int)
        self.mean_ = x.mean(axis=0)
        self.scale_ = np.where(x.std(axis=0) > 0, x.std(axis=0), 1.0)
        z = np.hstack([(x - self.mean_) / self.scale_, np.ones((len(x), 1))])
        onehot = np.eye(N_ACTIONS)[y]
        n, d = z.shape
        counts = np.bincount(y, minlength=N_ACTIONS)
        if self.balanced:
            onehot = onehot * (n / (np.count_nonzero(counts) * counts[y]))[:, None]

        def loss(w: np.ndarray) -> tuple[float, np.ndarray]:
            w = w.reshape(d, N_ACTIONS)
            logits = z @ w
            logits -= logits.max(axis=1, keepdims=True)
            logp = logits - np.log(np.exp(logits).sum(axis=1, keepdims=True))
            value = -np.sum(onehot * logp) / n + 0.5 * self.l2 * np.sum(w[:-1] ** 2)
            # onehot rows carry the sample weights, so the softmax term is weighted too.
            grad = z.T @ (np.exp(logp) * onehot.sum(axis=1, keepdims=True) - onehot) / n
            grad[:-1] += self.l2 * w[:-1]
            return value, grad.ravel()

        result = minimize(loss, np.zeros(d * N_ACTIONS), jac=True, method="L-BFGS-B")
        self.weights_ = result.x.reshape(d, N_ACTIONS)
        return self

    def predict(self, x: np.ndarray) -> np.ndarray:
        z = (np.asarray(x, dtype=np.float64) - self.mean_) / self.scale_
        return np.argmax(z @ self.weights_[:-1] + self.weights_[-1], axis=1)


def predictability(trajectories: Sequence[Trajectory]) -> dict:
    """Train on the first half of ``trajectories``, test on the rest (at least 2 needed).

    Returns balanced and plain accuracy on the test half, the share of the most
    frequent action (what always predicting it scores in plain accuracy), and
    the pair counts.
    """
    if len(trajectories) < 2:
        raise ValueError(f"predictability needs at least 2 trajectories, got {len(trajectories)}")
    half = len(trajectories) // 2
    x_train, y_train = stack_pairs(trajectories[:half])
    x_test, y_test = stack_pairs(trajectories[half:])
    if len(y_train) == 0 or len(y_test) == 0:
        raise ValueError("predictability needs at least one decision in each half")
    model = LogisticRegression().fit(classifier_inputs(x_train), y_train)
    predicted = model.predict(classifier_inputs(x_test))
    return {
        "balanced_accuracy": balanced_accuracy(y_test, predicted),
        "accuracy": float(np.mean(predicted == y_test)),
        "majority_share": float(np.bincount(y_test, minlength=N_ACTIONS).max() / len(y_test)),
        "train_pairs": int(len(y_train)),
        "test_pairs": int(len(y_test)),
    }
