"""The neural policy representation of NIRL (paper section III-B, III-C, IV-C).

A three-layer sigmoid network G maps the network's inputs (phi(s)'s 16 values in the
paper; the default's bearing code has 17, ``learn/inputs.py``) to the six action values
Q(s, u_1..u_6) in (0, 1) (eq. 6-7). Bias units are part of the input and hidden layers and
equal 1, so each weight matrix has one extra column 0 holding the bias weights:

- ``W1``: (n_hidden, n_in + 1), input layer -> hidden layer;
- ``W2``: (n_out, n_hidden + 1), hidden layer -> output layer.

The policy is Boltzmann in the action values (eq. 8, parameter eta, 1/Q-unit)
while learning and greedy once trained (eq. 9). The network is fitted to value targets (SARSA
in the paper, n-step Q-learning in the default: ``learn/sarsa.py``) by gradient descent on the
cross-entropy cost with L2 regularisation of the non-bias weights (eq. 15). Everything is float64.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.special import expit

__all__ = [
    "QNetwork",
    "q_values",
    "boltzmann_probabilities",
    "sample_action",
    "greedy_actions",
    "policy_entropy",
    "cross_entropy_cost",
    "gradient_step",
    "minibatch_epochs",
    "get_weights",
    "set_weights",
]

_DTYPE = torch.float64


class QNetwork(torch.nn.Module):
    """G_Omega: phi(s) (n_in) -> [Q(s, u_1), ..., Q(s, u_n_out)] in (0, 1) (eq. 6-7).

    Parameters ``W1`` (n_hidden, n_in + 1) and ``W2`` (n_out, n_hidden + 1), float64,
    column 0 the bias weights. Initialised uniformly in [-0.5, 0.5] from a
    ``torch.Generator`` seeded with ``seed`` (W1 drawn first, then W2), so equal
    seeds give equal networks.
    """

    def __init__(self, n_in: int = 16, n_hidden: int = 10, n_out: int = 6, seed: int = 0) -> None:
        super().__init__()
        self.n_in = int(n_in)
        self.n_hidden = int(n_hidden)
        self.n_out = int(n_out)
        gen = torch.Generator().manual_seed(int(seed))
        w1 = torch.rand((self.n_hidden, self.n_in + 1), generator=gen, dtype=_DTYPE) - 0.5
        w2 = torch.rand((self.n_out, self.n_hidden + 1), generator=gen, dtype=_DTYPE) - 0.5
        self.W1 = torch.nn.Parameter(w1)
        self.W2 = torch.nn.Parameter(w2)

    def logits(self, x: torch.Tensor | np.ndarray) -> torch.Tensor:
        """Output pre-activations y = W2 [1; sig(W1 [1; x])], shape (N, n_out), for x (N, n_in).

        ``forward`` is ``sigmoid(logits)``; the cost (eq. 15) uses the logits for
        numerically stable logarithms.
        """
        x = torch.as_tensor(x, dtype=_DTYPE)
        if x.ndim == 1:
            x = x.unsqueeze(0)
        # eq. 7: z = W1 . x with x = [1; phi_t]  (bias weights in column 0)
        z = self.W1[:, 0] + x @ self.W1[:, 1:].T
        # eq. 7: h = sig(z)
        h = torch.sigmoid(z)
        # eq. 7 (inside the output sigmoid): W2 . [1; h]
        return self.W2[:, 0] + h @ self.W2[:, 1:].T

    def forward(self, x: torch.Tensor | np.ndarray) -> torch.Tensor:
        """Q = G_Omega(x), shape (N, n_out) in (0, 1), for x of shape (N, n_in) (or (n_in,) -> (1, n_out))."""
        # eq. 7: G_Omega(s_t) = sig(W2 . [1; h]); eq. 6: row = [Q(s_t, u_1) ... Q(s_t, u_n)]
        return torch.sigmoid(self.logits(x))


def q_values(
    net: QNetwork, phi: np.ndarray, weights: tuple[np.ndarray, np.ndarray] | None = None
) -> np.ndarray:
    """Action values Q(s, .) = G(s) (eq. 6-7) in plain numpy, no autograd.

    phi: (N, n_in) state features (or (n_in,), treated as N = 1); ``weights``:
    ``(W1, W2)`` as numpy arrays if the caller already holds them (a policy
    acting many times between two updates), else read from ``net``.
    Returns (N, n_out) float64 in (0, 1), equal to ``net(phi)`` up to rounding
    (same operations in the same order; the fast path for per-decision calls).
    """
    x = np.asarray(phi, dtype=np.float64)
    if x.ndim == 1:
        x = x[None, :]
    w1, w2 = weights if weights is not None else (net.W1.detach().numpy(), net.W2.detach().numpy())
    # eq. 7: z = W1 [1; phi], h = sig(z), G = sig(W2 [1; h])
    h = expit(w1[:, 0] + x @ w1[:, 1:].T)
    return expit(w2[:, 0] + h @ w2[:, 1:].T)


def _log_boltzmann(q: np.ndarray, eta: float) -> np.ndarray:
    """log pi(s, a) of eq. 8 for every row of q (..., A), computed stably (max subtracted)."""
    a = float(eta) * np.asarray(q, dtype=np.float64)
    a = a - a.max(axis=-1, keepdims=True)
    return a - np.log(np.exp(a).sum(axis=-1, keepdims=True))


def boltzmann_probabilities(q: np.ndarray, eta: float) -> np.ndarray:
    """Boltzmann policy pi(s, a) = exp(eta Q(s, a)) / sum_u exp(eta Q(s, u)) (eq. 8).

    q: (N, A) or (A,) action values; eta: Boltzmann parameter (1 / unit of Q),
    larger is greedier. Returns probabilities of the same shape, rows summing
    to 1; the row maximum is subtracted before exponentiating, so any finite
    eta (e.g. 1e4) is safe.
    """
    # eq. 8: P(a_t | s_t; Omega) = exp(eta G(s_t, a_t)) / sum_u exp(eta G(s_t, u))
    a = float(eta) * np.asarray(q, dtype=np.float64)
    e = np.exp(a - a.max(axis=-1, keepdims=True))
    return e / e.sum(axis=-1, keepdims=True)


def sample_action(q_row: np.ndarray, eta: float, rng: np.random.Generator) -> int:
    """One action index drawn from the Boltzmann policy of eq. 8 for one state.

    q_row: (A,) action values; consumes exactly one ``rng.random()`` draw
    (inverse-CDF sampling), so it is deterministic given the generator state.
    """
    return draw_action(boltzmann_cdf(q_row, eta), rng)


def boltzmann_cdf(q_row: np.ndarray, eta: float) -> np.ndarray:
    """The cumulative sums (A,) of the eq. 8 probabilities of one state's action values (A,)."""
    return np.cumsum(boltzmann_probabilities(np.asarray(q_row, dtype=np.float64).reshape(-1), eta))


def draw_action(cdf: np.ndarray, rng: np.random.Generator) -> int:
    """One action index from a :func:`boltzmann_cdf` (A,), by one ``rng.random()`` draw (inverse CDF)."""
    return int(draw_actions(np.asarray(cdf)[None], rng)[0])


def draw_actions(cdf: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One action index per row of CDFs (N, A) -> (N,) int64, one ``rng.random()`` per row in row
    order (inverse CDF), so N rows spend the generator as N calls of :func:`draw_action` would."""
    u = rng.random(len(cdf)) * cdf[:, -1]
    # the count of entries <= u is np.searchsorted(row, u, side="right") on a non-decreasing row
    return np.minimum((cdf <= u[:, None]).sum(axis=1), cdf.shape[1] - 1).astype(np.int64)


def greedy_actions(q: np.ndarray) -> np.ndarray:
    """Greedy actions a = argmax_u G(s)_u (eq. 9), lowest index on ties.

    q: (N, A) -> (N,) int64 indices (q (A,) -> a numpy int64 scalar).
    """
    # eq. 9: a_t = argmax_{u in A} G(s_t)   (np.argmax returns the first maximum)
    return np.argmax(np.asarray(q), axis=-1)


def policy_entropy(q: np.ndarray, eta: float) -> float:
    """Mean entropy (nats) of the eq. 8 distribution over the rows of q (N, A) (or (A,))."""
    log_p = _log_boltzmann(np.atleast_2d(q), eta)
    # H = -sum_a pi(s, a) log pi(s, a)
    return float(np.mean(-np.sum(np.exp(log_p) * log_p, axis=-1)))


def _as_batch(
    phi: np.ndarray | torch.Tensor, actions: np.ndarray | torch.Tensor, targets: np.ndarray | torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    x = (
        phi.to(_DTYPE)
        if isinstance(phi, torch.Tensor)
        else torch.as_tensor(np.asarray(phi, dtype=np.float64))
    )
    if x.ndim == 1:
        x = x.unsqueeze(0)
    a = torch.as_tensor(np.asarray(actions), dtype=torch.long).reshape(-1)
    y = torch.as_tensor(np.asarray(targets, dtype=np.float64), dtype=_DTYPE).reshape(-1)
    if not (x.shape[0] == a.shape[0] == y.shape[0]):
        shapes = f"phi {tuple(x.shape)}, actions {tuple(a.shape)}, targets {tuple(y.shape)}"
        raise ValueError(f"batch sizes differ: {shapes}")
    if x.shape[0] == 0:
        raise ValueError("empty batch")
    return x, a, y


def _cost(
    net: QNetwork, x: torch.Tensor, a: torch.Tensor, y: torch.Tensor, l2: float, w: torch.Tensor | None = None
) -> torch.Tensor:
    n = x.shape[0]
    # Output of the TAKEN action only: Q_t = G_Omega(s_t, a_t), as a logit y_t (Q_t = sig(y_t)).
    logit = net.logits(x).gather(1, a.unsqueeze(1)).squeeze(1)
    # log Q_t = -softplus(-y_t) and log(1 - Q_t) = -softplus(y_t): exact and finite for any y_t.
    log_q = -torch.nn.functional.softplus(-logit)
    log_1mq = -torch.nn.functional.softplus(logit)
    # eq. 15, first term: -(1/N) sum_t [Qhat_t log Q_t + (1 - Qhat_t) log(1 - Q_t)]
    per_row = -(y * log_q + (1.0 - y) * log_1mq)
    data = (per_row if w is None else w * per_row).sum() / n
    # eq. 15, second term: lambda_2 / (2N) sum_l sum_{i >= 1} sum_j (w_ji^(l))^2  (bias column 0 excluded)
    reg = (float(l2) / (2.0 * n)) * ((net.W1[:, 1:] ** 2).sum() + (net.W2[:, 1:] ** 2).sum())
    return data + reg


def cross_entropy_cost(
    net: QNetwork,
    phi: np.ndarray,
    actions: np.ndarray,
    targets: np.ndarray,
    l2: float,
    weights: np.ndarray | None = None,
) -> torch.Tensor:
    """Cross-entropy cost J(Omega) with L2 regularisation (eq. 15), differentiable (0-d tensor).

    phi: (N, n_in) state features; actions: (N,) ints, the taken actions a_t (only
    their outputs Q_t = G(s_t, a_t) enter the cost); targets: (N,) SARSA targets
    Qhat_t in [0, 1] (eq. 14); l2: lambda_2 >= 0. The regulariser covers the
    non-bias weights of W1 and W2 (columns 1: of each). ``weights`` (N,) multiply each pair's
    cross-entropy term (behaviour cloning's class balance, ``learn/bc.py``); none: 1 each.
    """
    x, a, y = _as_batch(phi, actions, targets)
    w = None if weights is None else torch.as_tensor(np.asarray(weights, dtype=np.float64), dtype=_DTYPE)
    return _cost(net, x, a, y, l2, w)


def _gradients(
    w1: np.ndarray,
    w2: np.ndarray,
    x: np.ndarray,
    a: np.ndarray,
    y: np.ndarray,
    l2: float,
    weights: np.ndarray | None = None,
) -> tuple[float, np.ndarray, np.ndarray]:
    """eq. 15's cost J and its gradients dJ/dW1, dJ/dW2 by explicit backpropagation.

    The same numbers as torch's autograd on :func:`cross_entropy_cost` (a test
    checks it) at a tenth of the cost: on a 16-10-6 network the per-operation
    bookkeeping of autograd, and of torch itself, dominates the arithmetic. ``weights`` (N,)
    multiply each row's cross-entropy (none: 1 each), as in :func:`cross_entropy_cost`.
    """
    n = x.shape[0]
    h = expit(w1[:, 0] + x @ w1[:, 1:].T)  # eq. 7, hidden layer (N, n_hidden)
    w2a = w2[a]  # output weights of the taken actions (N, n_hidden + 1)
    logit = w2a[:, 0] + np.einsum("nh,nh->n", h, w2a[:, 1:])
    reg = (float(l2) / (2.0 * n)) * (np.sum(w1[:, 1:] ** 2) + np.sum(w2[:, 1:] ** 2))
    # -log Q = softplus(-y), -log(1 - Q) = softplus(y), written with logaddexp to stay finite
    w = np.ones(n) if weights is None else weights
    per_row = y * np.logaddexp(0.0, -logit) + (1.0 - y) * np.logaddexp(0.0, logit)
    cost = float(np.sum(w * per_row) / n + reg)
    # dJ/dlogit_t = w_t (Q_t - Qhat_t) / N for the (weighted) cross-entropy of a sigmoid output
    d = w * (expit(logit) - y) / n
    g2 = np.zeros_like(w2)
    np.add.at(g2, a, np.column_stack([d, d[:, None] * h]))
    dz = d[:, None] * w2a[:, 1:] * h * (1.0 - h)  # back through the hidden sigmoid
    g1 = np.column_stack([dz.sum(axis=0), dz.T @ x])
    g1[:, 1:] += (float(l2) / n) * w1[:, 1:]  # the L2 term spares the bias column
    g2[:, 1:] += (float(l2) / n) * w2[:, 1:]
    return cost, g1, g2


def _step(
    net: QNetwork,
    x: np.ndarray,
    a: np.ndarray,
    y: np.ndarray,
    l2: float,
    step: float,
    weights: np.ndarray | None = None,
) -> float:
    # numpy views of the parameters' storage: the update below is the network's own
    w1, w2 = net.W1.detach().numpy(), net.W2.detach().numpy()
    cost, g1, g2 = _gradients(w1, w2, x, a, y, l2, weights)
    # W^(l) <- W^(l) - sigma_2 dJ/dW^(l)   (gradient descent on eq. 15)
    w1 -= float(step) * g1
    w2 -= float(step) * g2
    return cost


def _as_arrays(
    phi: np.ndarray, actions: np.ndarray, targets: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x, a, y = _as_batch(phi, actions, targets)
    return x.numpy(), a.numpy(), y.numpy()


def gradient_step(
    net: QNetwork, phi: np.ndarray, actions: np.ndarray, targets: np.ndarray, l2: float, step: float
) -> float:
    """One full-batch gradient-descent step on eq. 15: W <- W - step * dJ/dW (paper: sigma_2 = 0.4).

    Arguments as in :func:`cross_entropy_cost`; updates ``net`` in place and
    returns the cost J(Omega) before the step (nats per pair, incl. the L2 term).
    """
    return _step(net, *_as_arrays(phi, actions, targets), l2, step)


def minibatch_epochs(
    net: QNetwork,
    phi: np.ndarray,
    actions: np.ndarray,
    targets: np.ndarray,
    l2: float,
    step: float,
    epochs: int,
    batch_size: int,
    rng: np.random.Generator,
    weights: np.ndarray | None = None,
) -> float:
    """Plain minibatch SGD on eq. 15 (the experience-replay variant); ``weights`` (N,) as in
    :func:`cross_entropy_cost`.

    Each epoch shuffles the N pairs with ``rng.permutation(N)`` and takes one
    gradient step per consecutive slice of ``batch_size`` pairs (the last one may
    be smaller), the eq. 15 cost evaluated on that minibatch (N = batch size in
    eq. 15, also in the L2 term). Deterministic given ``rng`` and ``net``.
    Returns the mean over all steps of the minibatch cost before each step,
    weighted by minibatch size (nats per pair); 0.0 if epochs == 0.
    """
    if batch_size < 1:
        raise ValueError("batch_size must be >= 1")
    x, a, y = _as_arrays(phi, actions, targets)
    n = x.shape[0]
    total, count = 0.0, 0
    for _ in range(int(epochs)):
        perm = rng.permutation(n)
        for start in range(0, n, int(batch_size)):
            idx = perm[start : start + int(batch_size)]
            cost = _step(net, x[idx], a[idx], y[idx], l2, step, None if weights is None else weights[idx])
            total += cost * idx.shape[0]
            count += idx.shape[0]
    return total / count if count else 0.0


def get_weights(net: QNetwork) -> dict[str, np.ndarray]:
    """Copies of the weights: {"W1": (n_hidden, n_in + 1), "W2": (n_out, n_hidden + 1)}, float64."""
    return {"W1": net.W1.detach().numpy().copy(), "W2": net.W2.detach().numpy().copy()}


def set_weights(net: QNetwork, weights: dict[str, np.ndarray]) -> None:
    """Writes ``weights`` (as from :func:`get_weights`) into ``net`` in place; shapes must match exactly."""
    for name in ("W1", "W2"):
        param = getattr(net, name)
        value = torch.as_tensor(np.asarray(weights[name], dtype=np.float64))
        if tuple(value.shape) != tuple(param.shape):
            raise ValueError(f"{name}: shape {tuple(value.shape)} != network's {tuple(param.shape)}")
        with torch.no_grad():
            param.copy_(value)
