"""Behaviour cloning at its strongest: the default NIRL's inputs and width, a class-balanced loss,
early stopping on held-out demonstrations (learn/bc.py)."""

import numpy as np
import pytest
from helpers import random_trajectory

from nirl_mj.learn import network
from nirl_mj.learn.bc import (
    CloneSettings,
    behaviour_cloning,
    class_weights,
    clone_pairs,
    early_stopped,
    split_demonstrations,
)
from nirl_mj.learn.config import LearnerConfig
from nirl_mj.learn.inputs import NetworkInputs


def test_class_weights_by_hand():
    """Actions [0, 0, 0, 1]: N = 4, K = 2 actions present, n_0 = 3, n_1 = 1, so the weights are
    4 / (2 * 3) = 2/3 for each "forward" and 4 / (2 * 1) = 2 for the turn; each action sums to 2."""
    np.testing.assert_allclose(class_weights(np.array([0, 0, 0, 1])), [2 / 3, 2 / 3, 2 / 3, 2])
    w = class_weights(np.array([5, 0, 0, 2, 0, 2]))
    assert w.sum() == pytest.approx(6) and w[0] == pytest.approx(2) and w[1] == pytest.approx(2 / 3)


def test_the_balanced_cost_by_hand():
    """The weighted eq. 15 on two pairs equals the hand-written weighted mean of the two
    cross-entropies (no L2): -(1/N) sum_t w_t [y log Q + (1 - y) log(1 - Q)]."""
    net = network.QNetwork(16, 4, seed=0)
    phi, actions, targets = np.ones((2, 16)) * 0.1, np.array([0, 3]), np.array([1.0, 0.0])
    q = network.q_values(net, phi)[np.arange(2), actions]
    w = class_weights(np.array([0, 0, 0, 3]))[[0, 3]]  # 2/3 and 2
    by_hand = -(w[0] * np.log(q[0]) + w[1] * np.log(1 - q[1])) / 2
    got = float(network.cross_entropy_cost(net, phi, actions, targets, 0.0, w).detach())
    assert got == pytest.approx(by_hand, rel=1e-12)


def test_settings_give_nirls_inputs_and_width():
    loop = LearnerConfig.preset("default").loop
    s = CloneSettings.of("default")
    assert (s.hidden_units, s.inputs, s.balanced) == (loop.hidden_units, NetworkInputs.of(loop), True)
    assert s.held_out > 0
    paper = CloneSettings.of("paper")
    assert (paper.hidden_units, paper.balanced, paper.held_out, paper.epochs) == (10, False, 0, 30)


def test_split_holds_out_every_kth_trajectory():
    kept, held = split_demonstrations(list(range(11)), 5)
    assert held == [0, 5, 10] and kept == [1, 2, 3, 4, 6, 7, 8, 9]
    assert split_demonstrations([1], 5) == ([1], []) and split_demonstrations([1, 2], 0) == ([1, 2], [])


def _imbalanced(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """phi with D of S1 (the front) in 0..7: the label is "turn" (1) when it is 6 or more (about a
    quarter of the pairs), else forward (0)."""
    phi = np.zeros((n, 16))
    phi[:, 0] = rng.integers(0, 8, n)
    phi[:, 7] = 1
    return phi, (phi[:, 0] >= 6).astype(int)


def test_balanced_cloning_learns_the_rare_action_and_stops_on_held_out_pairs():
    rng = np.random.default_rng(0)
    phi, actions = _imbalanced(rng, 400)
    held = _imbalanced(rng, 100)
    settings = CloneSettings.of("default")
    net, epochs, scores = early_stopped((phi, actions), held, settings, seed=1)
    assert len(scores) == settings.epochs and scores[epochs - 1] == max(scores) == 1.0
    policy = clone_pairs(phi, actions, seed=1, settings=settings, held_out=held)
    test_phi, test_actions = _imbalanced(rng, 200)
    predicted = np.array([policy(p) for p in test_phi])
    assert np.mean(predicted == test_actions) == 1.0
    # unweighted, the paper's settings miss part of the rare action on the same pairs
    paper = clone_pairs(phi, actions, seed=1, settings=CloneSettings.of("paper"))
    assert np.mean(np.array([paper(p) for p in test_phi]) == test_actions) < 1.0


def test_behaviour_cloning_is_reproducible_from_its_seed():

    rng = np.random.default_rng(3)
    demos = [random_trajectory(rng, 15, "target") for _ in range(6)]
    probe = np.random.default_rng(4).integers(0, 8, size=(50, 16)).astype(float)
    probe[:, 7] = np.clip(probe[:, 7], 1, 9)

    def actions(seed, variant="default"):
        policy = behaviour_cloning(demos, seed=seed, settings=CloneSettings.of(variant))
        return [policy(p) for p in probe]

    assert actions(2) == actions(2) and actions(2, "paper") == actions(2, "paper")
    assert actions(2) != actions(3)  # the seed matters (initial weights, minibatch order)


def test_bc_paper_is_the_bc_of_before(tmp_path):
    """BC-paper computes what the BC row computed until 2026-11-26 (written out here as it was:
    the 16-10-6 network on D/7 and V/9, every output's target, 30 unweighted minibatch epochs)."""

    from nirl_mj.data.features import N_ACTIONS
    from nirl_mj.learn.loop import demonstrated_pairs, greedy_policy

    rng = np.random.default_rng(5)
    demos = [random_trajectory(rng, 12, "target") for _ in range(4)]
    phi, actions = demonstrated_pairs(demos)
    inputs = NetworkInputs(True)
    x = np.repeat(inputs(phi), N_ACTIONS, axis=0)
    outputs = np.tile(np.arange(N_ACTIONS), len(actions))
    targets = (outputs == np.repeat(actions, N_ACTIONS)).astype(np.float64)
    net = network.QNetwork(seed=7)
    network.minibatch_epochs(net, x, outputs, targets, 1e-3, 0.4, 30, 64, np.random.default_rng(7))
    before = greedy_policy(net, inputs)
    now = behaviour_cloning(demos, seed=7, settings=CloneSettings.of("paper"))
    probe = np.random.default_rng(8).integers(0, 8, size=(100, 16)).astype(float)
    probe[:, 7] = np.clip(probe[:, 7], 1, 9)
    assert [before(p) for p in probe] == [now(p) for p in probe]
