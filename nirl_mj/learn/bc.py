"""Behaviour cloning with the same network: the reference that imitates without a reward.

The network of eq. 6-7 is fitted to state-action pairs with the cross-entropy
cost of eq. 15, every output at once: 1 for the demonstrated action, 0 for
the others. Plain SGD as in NIRL's network step, so the two differ only in
where the targets come from. :func:`clone_pairs` fits any labelled pairs (DAgger's
aggregated data set, ``nirl_mj.experiments.dagger``); :func:`behaviour_cloning`
the demonstrations.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from nirl_mj.data.features import N_ACTIONS
from nirl_mj.data.trajectory import Trajectory
from nirl_mj.learn import network
from nirl_mj.learn.inputs import NetworkInputs
from nirl_mj.learn.loop import demonstrated_pairs, greedy_policy


def clone_pairs(
    phi: np.ndarray,
    actions: np.ndarray,
    seed: int = 0,
    epochs: int = 30,
    step: float = 0.4,
    l2: float = 1e-3,
    scaled: bool = True,
) -> Callable[[np.ndarray], int]:
    """The greedy policy on phi(s) of a network trained to predict ``actions`` (N,) from ``phi`` (N, 16)."""
    inputs = NetworkInputs(scaled)
    x = np.repeat(inputs(np.asarray(phi)), N_ACTIONS, axis=0)
    outputs = np.tile(np.arange(N_ACTIONS), len(actions))
    targets = (outputs == np.repeat(np.asarray(actions), N_ACTIONS)).astype(np.float64)
    net = network.QNetwork(seed=seed)
    network.minibatch_epochs(net, x, outputs, targets, l2, step, epochs, 64, np.random.default_rng(seed))
    return greedy_policy(net, inputs)


def behaviour_cloning(demos: list[Trajectory], seed: int = 0, **fit) -> Callable[[np.ndarray], int]:
    """Returns the greedy policy on phi(s) of a network trained to predict the demonstrated actions
    (``fit``: :func:`clone_pairs`'s settings)."""
    phi, actions = demonstrated_pairs(demos)
    return clone_pairs(phi, actions, seed=seed, **fit)
