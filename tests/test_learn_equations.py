"""Hand-computed checks of the NIRL learning equations (eq. 6-9, 11, 13-15)."""

import math

import numpy as np
import pytest
import torch
from helpers import random_trajectory

from nirl_mj.learn.mmp import (
    discounted_suffix_sums,
    feature_expectations,
    minimise_mmp,
    mmp_objective,
    project_to_ball,
)
from nirl_mj.learn.network import (
    QNetwork,
    boltzmann_cdf,
    boltzmann_probabilities,
    cross_entropy_cost,
    draw_actions,
    get_weights,
    gradient_step,
    greedy_actions,
    minibatch_epochs,
    policy_entropy,
    q_values,
    sample_action,
    set_weights,
)
from nirl_mj.learn.sarsa import sarsa_targets

LN3 = math.log(3.0)


def _j(net: QNetwork, phi, actions, targets, l2: float) -> float:
    """eq. 15 as a plain float."""
    return float(cross_entropy_cost(net, phi, actions, targets, l2).detach())


def _tiny_net() -> QNetwork:
    """2 inputs, 2 hidden, 2 outputs; for x = [2, -1]: z = [0, ln 3], h = [1/2, 3/4], Q = [3/4, 1/2]."""
    net = QNetwork(n_in=2, n_hidden=2, n_out=2)
    set_weights(
        net,
        {
            # column 0: bias weights
            "W1": np.array([[0.0, 0.5, 1.0], [LN3, 0.0, 0.0]]),
            "W2": np.array([[0.0, 2 * LN3, 0.0], [-LN3, 0.0, 4 * LN3 / 3]]),
        },
    )
    return net


# --- eq. 6-7: forward pass ---------------------------------------------------------------------------------


def test_forward_eq7_by_hand():
    net = _tiny_net()
    x = np.array([[2.0, -1.0]])
    # z1 = 0 + 0.5*2 + 1*(-1) = 0 -> h1 = 1/2;  z2 = ln 3 -> h2 = 3/4
    # y1 = 0 + 2 ln3 * 1/2 = ln 3 -> Q1 = 3/4;  y2 = -ln3 + (4 ln3 / 3) * 3/4 = 0 -> Q2 = 1/2
    expected = np.array([[0.75, 0.5]])
    q = net(x)
    assert q.dtype == torch.float64
    np.testing.assert_allclose(q.detach().numpy(), expected, rtol=1e-14)
    np.testing.assert_allclose(q_values(net, x), expected, rtol=1e-14)
    np.testing.assert_allclose(q_values(net, x[0]), expected, rtol=1e-14)  # 1-D input -> (1, n_out)


def test_q_values_matches_forward():
    net = QNetwork(seed=3)
    phi = np.random.default_rng(0).uniform(0, 9, size=(50, 16))
    q = q_values(net, phi)
    assert q.shape == (50, 6) and q.dtype == np.float64
    assert np.all((q > 0) & (q < 1))
    np.testing.assert_allclose(q, net(phi).detach().numpy(), rtol=1e-13, atol=0)


def test_init_deterministic_and_in_range():
    a, b, c = QNetwork(seed=7), QNetwork(seed=7), QNetwork(seed=8)
    assert a.W1.shape == (10, 17) and a.W2.shape == (6, 11)
    assert a.W1.dtype == torch.float64 and a.W2.dtype == torch.float64
    assert torch.equal(a.W1, b.W1) and torch.equal(a.W2, b.W2)
    assert not torch.equal(a.W1, c.W1)
    for w in (a.W1, a.W2):
        assert float(w.detach().min()) >= -0.5 and float(w.detach().max()) <= 0.5


def test_weights_round_trip():
    a, b = QNetwork(seed=1), QNetwork(seed=2)
    w = get_weights(a)
    assert set(w) == {"W1", "W2"} and w["W1"].shape == (10, 17) and w["W2"].shape == (6, 11)
    set_weights(b, w)
    assert torch.equal(a.W1, b.W1) and torch.equal(a.W2, b.W2)
    np.testing.assert_array_equal(get_weights(b)["W1"], w["W1"])
    w["W1"][0, 0] = 123.0  # a copy: editing it does not touch the network
    assert float(a.W1.detach()[0, 0]) != 123.0
    with pytest.raises(ValueError):
        set_weights(b, {"W1": np.zeros((3, 3)), "W2": w["W2"]})


# --- eq. 8-9: Boltzmann and greedy --------------------------------------------------------------------------


def test_boltzmann_eq8_known_row():
    eta = 10 * math.log(2.0)
    q = np.array([0.1, 0.2, 0.3])  # exp(eta q) proportional to [1, 2, 4]
    np.testing.assert_allclose(boltzmann_probabilities(q, eta), [1 / 7, 2 / 7, 4 / 7], rtol=1e-12)
    p = boltzmann_probabilities(np.stack([q, np.zeros(3)]), eta)
    np.testing.assert_allclose(p[1], [1 / 3] * 3, rtol=1e-12)
    np.testing.assert_allclose(p.sum(axis=1), 1.0, rtol=1e-15)


def test_boltzmann_eq8_stable_for_large_eta():
    # eta q = [5000, 5001, 2000]: exp overflows unless the maximum is subtracted
    p = boltzmann_probabilities(np.array([0.5, 0.5001, 0.2]), 1e4)
    e = math.e
    np.testing.assert_allclose(p, [1 / (1 + e), e / (1 + e), 0.0], rtol=1e-9, atol=1e-300)
    assert np.all(np.isfinite(p))


def test_sample_action_frequencies_and_determinism():
    eta = 10 * math.log(2.0)
    q = np.array([0.1, 0.2, 0.3])
    rng = np.random.default_rng(0)
    draws = np.array([sample_action(q, eta, rng) for _ in range(20000)])
    freq = np.bincount(draws, minlength=3) / draws.size
    np.testing.assert_allclose(freq, [1 / 7, 2 / 7, 4 / 7], atol=0.015)
    r1, r2 = np.random.default_rng(5), np.random.default_rng(5)
    assert [sample_action(q, eta, r1) for _ in range(50)] == [sample_action(q, eta, r2) for _ in range(50)]
    assert sample_action(np.array([0.2, 0.9, 0.1]), 1e4, rng) == 1


def test_draw_actions_is_row_by_row_inverse_cdf_spending_one_draw_per_row():
    q = np.random.default_rng(1).normal(size=(200, 6))
    cdf = np.stack([boltzmann_cdf(row, 3.0) for row in q])
    cdf[0] = [0.0, 0.0, 0.5, 0.5, 1.0, 1.0]  # zero-probability actions and a plateau: never drawn
    at_once = draw_actions(cdf, np.random.default_rng(9))
    rng = np.random.default_rng(9)
    by_row = [int(np.searchsorted(row, rng.random() * row[-1], side="right")) for row in cdf]
    assert at_once.tolist() == [min(a, 5) for a in by_row]
    assert at_once[0] in (2, 4) and at_once.dtype == np.int64
    # N rows spend the generator as N single draws: the next draw is the same
    rng_batch, rng_rows = np.random.default_rng(9), np.random.default_rng(9)
    draw_actions(cdf, rng_batch)
    [rng_rows.random() for _ in cdf]
    assert rng_batch.random() == rng_rows.random()


def test_greedy_eq9_ties_lowest_index():
    q = np.array([[0.1, 0.7, 0.7, 0.2], [0.5, 0.5, 0.5, 0.5], [0.0, 0.0, 0.0, 0.3]])
    np.testing.assert_array_equal(greedy_actions(q), [1, 0, 3])


def test_policy_entropy():
    assert policy_entropy(np.zeros((4, 6)), 50.0) == pytest.approx(math.log(6))
    eta = 10 * math.log(2.0)
    p = np.array([1, 2, 4]) / 7
    h = -np.sum(p * np.log(p))
    assert policy_entropy(np.array([[0.1, 0.2, 0.3], [0.0, 0.0, 0.0]]), eta) == pytest.approx(
        (h + math.log(3)) / 2
    )
    assert policy_entropy(np.array([0.0, 1.0, 0.0]), 1e4) == pytest.approx(0.0, abs=1e-12)


# --- eq. 15: cost, gradient, descent ------------------------------------------------------------------------


def test_cost_eq15_by_hand():
    net = _tiny_net()
    phi = np.array([[2.0, -1.0], [2.0, -1.0]])
    actions = np.array([0, 1])  # Q_t = 3/4, 1/2
    targets = np.array([0.75, 0.2])
    l2 = 0.3
    ce = -(0.75 * math.log(0.75) + 0.25 * math.log(0.25)) - (0.2 * math.log(0.5) + 0.8 * math.log(0.5))
    # non-bias weights: W1[:, 1:] -> 0.25 + 1 ; W2[:, 1:] -> (2 ln3)^2 + (4 ln3 / 3)^2
    sq = 1.25 + 4 * LN3**2 + 16 / 9 * LN3**2
    expected = ce / 2 + l2 / (2 * 2) * sq
    assert _j(net, phi, actions, targets, l2) == pytest.approx(expected, rel=1e-13)


def test_cost_gradient_matches_finite_differences():
    rng = np.random.default_rng(1)
    net = QNetwork(seed=4)
    phi = rng.uniform(0, 3, size=(7, 16))
    actions = rng.integers(0, 6, size=7)
    targets = rng.uniform(0, 1, size=7)
    l2 = 0.3
    cost = cross_entropy_cost(net, phi, actions, targets, l2)
    g1, g2 = torch.autograd.grad(cost, (net.W1, net.W2))
    h = 1e-6
    for param, grad in ((net.W1, g1), (net.W2, g2)):
        numeric = np.zeros(tuple(param.shape))
        for idx in np.ndindex(*param.shape):
            old = float(param.detach()[idx])
            with torch.no_grad():
                param[idx] = old + h
                up = _j(net, phi, actions, targets, l2)
                param[idx] = old - h
                down = _j(net, phi, actions, targets, l2)
                param[idx] = old
            numeric[idx] = (up - down) / (2 * h)
        np.testing.assert_allclose(grad.numpy(), numeric, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("weighted", [False, True])
def test_explicit_backpropagation_equals_autograd(weighted):
    """The training step's hand-written backpropagation of eq. 15 against autograd (checked
    against finite differences above), with repeated actions in the batch; also with per-pair
    weights (behaviour cloning's class balance)."""
    from nirl_mj.learn.network import _as_arrays, _gradients

    rng = np.random.default_rng(5)
    net = QNetwork(seed=6)
    phi = rng.uniform(0, 3, size=(9, 16))
    actions = np.array([0, 0, 1, 5, 5, 5, 2, 3, 0])
    targets = rng.uniform(0, 1, size=9)
    w = rng.uniform(0.2, 3.0, size=9) if weighted else None
    cost = cross_entropy_cost(net, phi, actions, targets, 0.3, w)
    g1, g2 = torch.autograd.grad(cost, (net.W1, net.W2))
    weights = (net.W1.detach().numpy(), net.W2.detach().numpy())
    value, h1, h2 = _gradients(*weights, *_as_arrays(phi, actions, targets), 0.3, w)
    assert value == pytest.approx(float(cost.detach()), rel=1e-13)
    np.testing.assert_allclose(h1, g1.numpy(), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(h2, g2.numpy(), rtol=1e-12, atol=1e-15)


def test_gradient_step_lowers_cost():
    rng = np.random.default_rng(2)
    net = QNetwork(seed=0)
    phi = rng.uniform(0, 9, size=(20, 16))
    actions = rng.integers(0, 6, size=20)
    targets = rng.uniform(0, 1, size=20)
    before = _j(net, phi, actions, targets, 0.1)
    returned = gradient_step(net, phi, actions, targets, 0.1, 0.4)
    assert returned == pytest.approx(before, rel=1e-14)
    after = _j(net, phi, actions, targets, 0.1)
    assert after < before


def test_minibatch_epochs_deterministic_and_descending():
    rng = np.random.default_rng(3)
    phi = rng.uniform(0, 9, size=(40, 16))
    actions = rng.integers(0, 6, size=40)
    targets = rng.uniform(0, 1, size=40)
    a, b = QNetwork(seed=0), QNetwork(seed=0)
    before = _j(a, phi, actions, targets, 0.1)
    ca = minibatch_epochs(a, phi, actions, targets, 0.1, 0.4, 5, 8, np.random.default_rng(9))
    cb = minibatch_epochs(b, phi, actions, targets, 0.1, 0.4, 5, 8, np.random.default_rng(9))
    assert ca == cb
    assert torch.equal(a.W1, b.W1) and torch.equal(a.W2, b.W2)
    assert _j(a, phi, actions, targets, 0.1) < before


def test_minibatch_epochs_reports_the_pair_weighted_mean_of_its_minibatch_costs():
    """10 pairs in minibatches of 4, 4 and 2: the last, smaller minibatch weighs 2/10, not 1/3."""
    rng = np.random.default_rng(5)
    phi = rng.uniform(0, 9, size=(10, 16))
    actions = rng.integers(0, 6, size=10)
    targets = rng.uniform(0, 1, size=10)
    net = QNetwork(seed=1)
    # step 0 leaves the net as it is: sum_b (n_b / 10) mean_b(cost) = mean over all 10 pairs of eq. 15
    cost = minibatch_epochs(net, phi, actions, targets, 0.0, 0.0, 1, 4, np.random.default_rng(0))
    assert cost == pytest.approx(_j(net, phi, actions, targets, 0.0), rel=1e-12)


# --- eq. 3, 11: feature sums --------------------------------------------------------------------------------

TRAJ_1 = np.array([[1.0, 0.0], [0.0, 2.0], [4.0, 4.0]])
TRAJ_2 = np.array([[0.0, 2.0]])


def test_discounted_suffix_sums():
    # gamma = 1/2: row 2 = [4, 4]; row 1 = [0, 2] + [2, 2] = [2, 4]; row 0 = [1, 0] + [1, 2] = [2, 2]
    np.testing.assert_allclose(discounted_suffix_sums(TRAJ_1, 0.5), [[2, 2], [2, 4], [4, 4]], rtol=1e-15)
    assert discounted_suffix_sums(np.zeros((0, 2)), 0.5).shape == (0, 2)


def test_feature_expectations_eq11_two_trajectories():
    # traj 1: [1, 0] + 1/2 [0, 2] + 1/4 [4, 4] = [2, 2];  traj 2: [0, 2];  mean = [1, 2]
    np.testing.assert_allclose(feature_expectations([TRAJ_1, TRAJ_2], 0.5), [1.0, 2.0], rtol=1e-15)
    np.testing.assert_allclose(
        feature_expectations([TRAJ_1, TRAJ_2], 0.5),
        (discounted_suffix_sums(TRAJ_1, 0.5)[0] + discounted_suffix_sums(TRAJ_2, 0.5)[0]) / 2,
    )


# --- eq. 13: MMP ------------------------------------------------------------------------------------------


def test_project_to_ball():
    np.testing.assert_allclose(project_to_ball(np.array([3.0, 4.0])), [0.6, 0.8], rtol=1e-15)
    np.testing.assert_array_equal(project_to_ball(np.array([0.3, 0.4])), [0.3, 0.4])
    np.testing.assert_allclose(project_to_ball(np.array([3.0, 4.0]), radius=2.0), [1.2, 1.6], rtol=1e-15)


def test_mmp_objective_value_and_subgradient():
    theta = np.array([1.0, -1.0])
    expert = np.array([[1.0, 0.0], [0.0, 1.0]])
    learner = np.array([[[1.0, 0.0], [0.0, -1.0]], [[2.0, 1.0], [1.0, 1.0]]])
    loss = np.array([[0.0, 1.0], [1.0, 0.0]])
    # n=0: scores [1, 1+1] -> a*=1, term 2 - 1 = 1, g = [0,-1] - [1,0] = [-1,-1]
    # n=1: scores [1+1, 0] -> a*=0, term 2 - (-1) = 3, g = [2,1] - [0,1] = [2,0]
    # J = (1 + 3)/2 + 0.5/2 * 2 = 2.5;  g = [1/2, -1/2] + 0.5 [1, -1] = [1, -1]
    value, grad = mmp_objective(theta, expert, learner, loss, 0.5)
    assert value == pytest.approx(2.5, rel=1e-15)
    np.testing.assert_allclose(grad, [1.0, -1.0], rtol=1e-15)


def test_mmp_objective_ties_take_lowest_index():
    theta = np.array([1.0, 0.0])
    learner = np.array([[[1.0, 5.0], [1.0, -5.0]]])  # equal scores 1
    value, grad = mmp_objective(theta, np.zeros((1, 2)), learner, np.zeros((1, 2)), 0.0)
    assert value == pytest.approx(1.0)
    np.testing.assert_allclose(grad, [1.0, 5.0])


def test_minimise_mmp_one_projected_step():
    theta0 = np.array([0.6, 0.8])
    expert = np.array([[1.0, 0.0]])
    learner = np.zeros((1, 2, 2))
    loss = np.zeros((1, 2))
    # J(theta) = 0 - theta_1, g = [-1, 0]; J(theta0) = -0.6
    value0, grad0 = mmp_objective(theta0, expert, learner, loss, 0.0)
    assert value0 == pytest.approx(-0.6) and np.allclose(grad0, [-1.0, 0.0])
    # theta0 - 1.0 g = [1.6, 0.8], norm sqrt(3.2) > 1 -> projected back to [2, 1]/sqrt(5)
    theta, value = minimise_mmp(theta0, expert, learner, loss, 0.0, steps=1, step_size=1.0)
    np.testing.assert_allclose(theta, np.array([2.0, 1.0]) / math.sqrt(5), rtol=1e-14)
    assert np.linalg.norm(theta) == pytest.approx(1.0)
    assert value == pytest.approx(-2 / math.sqrt(5), rel=1e-14)
    # many decaying steps approach the constrained optimum theta = [1, 0], J = -1
    theta, value = minimise_mmp(theta0, expert, learner, loss, 0.0, steps=200, step_size=0.5, decay=0.1)
    assert value == pytest.approx(-1.0, abs=1e-3) and np.linalg.norm(theta) <= 1.0 + 1e-12


def test_block_objective_equals_the_general_one():
    """The default variant's fast path: the same J, subgradient and iterates as eq. 13 on the
    (N, A, D) array of f(s_n, a) + gamma mu(next_n)."""
    from nirl_mj.learn.mmp import minimise_mmp_blocks, mmp_objective_blocks
    from nirl_mj.learn.reward import all_action_features, state_reward_features

    rng = np.random.default_rng(8)
    phi = np.column_stack([rng.integers(1, 8, (40, 7)), rng.integers(1, 10, 40), rng.integers(0, 2, (40, 8))])
    blocks = state_reward_features(phi, "extended")
    expert, future = rng.random((40, 150)), rng.random((40, 150))
    learner = all_action_features(phi, "extended") + 0.65 * future[:, None, :]
    loss = np.full((40, 6), 0.1)
    loss[np.arange(40), rng.integers(0, 6, 40)] = 0.0
    theta = rng.normal(size=150) / 20
    offset = 0.65 * future - expert
    v1, g1 = mmp_objective(theta, expert, learner, loss, 0.01)
    v2, g2 = mmp_objective_blocks(theta, blocks, offset, loss, 0.01)
    assert v2 == pytest.approx(v1, rel=1e-12)
    np.testing.assert_allclose(g2, g1, rtol=1e-10, atol=1e-13)
    t1, j1 = minimise_mmp(theta, expert, learner, loss, 0.01, steps=20, step_size=0.5)
    t2, j2 = minimise_mmp_blocks(theta, blocks, offset, loss, 0.01, steps=20, step_size=0.5)
    assert j2 == pytest.approx(j1, rel=1e-10)
    np.testing.assert_allclose(t2, t1, rtol=1e-8, atol=1e-12)


def test_policy_objective_by_hand():
    """eq. 13 with the learner's policies as the alternatives: one state, two actions, B = 1.

    f(s, a) = e_a; the expert takes action 0, l = 0.1 for action 1; theta = (0.5, -0.5), so the
    loss-augmented values are (0.5, -0.4). Policy (0.5, 0.5) scores 0.05, policy (0.9, 0.1)
    scores 0.41: the second is the alternative. J = 0.41 - theta . f(s, 0) = -0.09, and the
    subgradient is (0.9, 0.1) - (1, 0) = (-0.1, 0.1)."""
    from nirl_mj.learn.mmp import mmp_objective_policies

    policies = np.array([[[0.5, 0.5]], [[0.9, 0.1]]])
    value, grad = mmp_objective_policies(
        np.array([0.5, -0.5]), np.ones((1, 1)), np.array([[-1.0, 0.0]]), np.array([[0.0, 0.1]]), policies, 0.0
    )
    assert value == pytest.approx(-0.09)
    np.testing.assert_allclose(grad, [-0.1, 0.1])
    # a policy that always takes the expert's action is no violation: J = 0, gradient 0
    value, grad = mmp_objective_policies(
        np.array([0.5, -0.5]), np.ones((1, 1)), np.array([[-1.0, 0.0]]), np.array([[0.0, 0.1]]),
        np.array([[[1.0, 0.0]]]), 0.0,
    )  # fmt: skip
    assert value == pytest.approx(0.0) and np.allclose(grad, 0.0)


def test_policy_objective_with_every_deterministic_policy_is_the_action_max():
    """With one one-hot policy per action the policies' max is the actions' max (the default)."""
    from nirl_mj.learn.mmp import mmp_objective_blocks, mmp_objective_policies

    rng = np.random.default_rng(3)
    blocks, offset, theta = rng.random((30, 4)), rng.random((30, 24)), rng.normal(size=24)
    loss = np.full((30, 6), 0.1)
    every_action = np.broadcast_to(np.eye(6)[:, None, :], (6, 30, 6))
    v1, g1 = mmp_objective_blocks(theta, blocks, offset, loss, 0.01)
    v2, g2 = mmp_objective_policies(theta, blocks, offset, loss, every_action, 0.01)
    assert v2 == pytest.approx(v1, rel=1e-12)
    np.testing.assert_allclose(g2, g1, rtol=1e-12)


def test_policy_objective_layout_is_bit_for_bit():
    """The (N, J, A) layout the optimiser uses picks the same alternatives, and sums them the same
    way, as the (J, N, A) reference: the J and subgradient are equal to the last bit, ties included."""
    from nirl_mj.learn.mmp import _action_values, _blocks_objective, mmp_objective_policies

    rng = np.random.default_rng(5)
    blocks, offset, theta = rng.random((200, 4)), rng.random((200, 24)), rng.normal(size=24)
    loss = np.full((200, 6), 0.1)
    policies = rng.dirichlet(np.ones(6), size=(9, 200))
    policies[4] = policies[2]  # exact ties between policies: the lowest j wins in both layouts
    values = _action_values(theta, blocks, loss)
    scores = np.einsum("jna,na->jn", policies, values)
    reference = _blocks_objective(
        theta,
        blocks,
        offset,
        offset.mean(axis=0),
        values,
        policies[np.argmax(scores, axis=0), np.arange(200)],
        0.01,
    )
    value, grad = mmp_objective_policies(theta, blocks, offset, loss, policies, 0.01)
    assert value == reference[0]
    assert np.array_equal(grad, reference[1])


def test_minimise_mmp_keeps_best_iterate():
    # A too-large step overshoots; theta0 is already optimal and must be returned.
    theta0 = np.array([1.0, 0.0])
    expert = np.array([[1.0, 0.0]])
    learner = np.zeros((1, 2, 2))
    theta, value = minimise_mmp(theta0, expert, learner, np.zeros((1, 2)), 1.0, steps=5, step_size=1.0)
    # J = -theta_1 + |theta|^2 / 2, minimum over the ball at [1, 0]: J = -1/2
    np.testing.assert_allclose(theta, [1.0, 0.0])
    assert value == pytest.approx(-0.5)


def test_minimise_mmp_keeps_the_earliest_of_equally_good_iterates():
    # J = max(theta_1, -theta_1) = |theta_1|: from [0.5, 0] (J 0.5, subgradient [1, 0]) a step of 1 goes
    # to [-0.5, 0], J 0.5 too; the tie keeps theta0
    learner = np.array([[[1.0, 0.0], [-1.0, 0.0]]])
    theta, value = minimise_mmp(np.array([0.5, 0.0]), np.zeros((1, 2)), learner, np.zeros((1, 2)), 0.0,
                                steps=1, step_size=1.0)  # fmt: skip
    np.testing.assert_array_equal(theta, [0.5, 0.0])
    assert value == 0.5


@pytest.mark.parametrize("mix", [1.0, 0.5])
def test_the_learners_future_mixes_its_own_mean_discounted_sum_with_the_experts_continuation(mix):
    """Per-pair readings (occupancy matching): what follows a demonstrated pair on the learner's side is
    future_mix x the learner's mean discounted sum over its rollouts' pairs (an empty rollout adds none)
    plus (1 - future_mix) x the expert's continuation from the next demonstrated pair (0 after the last)."""
    from nirl_mj.learn.config import LearnerConfig
    from nirl_mj.learn.mmp import MaxMarginStep
    from nirl_mj.learn.reward import pair_features

    rng = np.random.default_rng(6)
    demos = [random_trajectory(rng, n, "target") for n in (4, 3)]
    rollouts = [random_trajectory(rng, n, "collision") for n in (3, 0, 2)]
    config = LearnerConfig.preset("default", matching="occupancy", future_mix=mix)
    kind, gamma = config.loop.reward_features, config.loop.gamma

    def suffixes(t) -> np.ndarray:
        """mu(s_i, a_i) = f(s_i, a_i) + gamma mu(s_i+1, a_i+1) along ``t``, and a zero row after its end."""
        f = pair_features(t.features[:-1], t.actions, kind)
        mu = np.zeros((len(f) + 1, f.shape[1]))
        for i in reversed(range(len(f))):
            mu[i] = f[i] + gamma * mu[i + 1]
        return mu

    own = np.concatenate([suffixes(t)[:-1] for t in rollouts]).mean(axis=0)  # over the 5 rollout pairs
    expert_next = np.concatenate([suffixes(t)[1:] for t in demos])  # mu_E from the next pair, (7, D)
    future = MaxMarginStep(config.loop, config.step, demos).learner_future(rollouts)
    np.testing.assert_allclose(future, mix * own + (1 - mix) * expert_next, rtol=1e-12, atol=1e-12)


# --- eq. 14: SARSA ----------------------------------------------------------------------------------------


def test_sarsa_targets_eq14():
    alpha, gamma = 0.8, 0.65
    q_sa = np.array([0.5, 0.5, 0.5, 0.9, 0.1])
    rewards = np.array([0.1, 0.2, 0.2, 1.0, -1.0])
    q_next = np.array([0.6, np.nan, np.nan, 0.9, 0.3])
    terminal = np.array([False, True, True, False, True])
    tv = np.array([0.0, 0.3, 0.0, 0.0, 0.0])
    targets, share = sarsa_targets(q_sa, rewards, q_next, terminal, alpha, gamma, tv)
    # bootstrap: 0.5 + 0.8 (0.1 + 0.65*0.6 - 0.5) = 0.5 + 0.8 * (-0.01) = 0.492
    # terminal, value 0.3: 0.5 + 0.8 (0.2 + 0.3 - 0.5) = 0.5;  terminal, value 0: 0.5 + 0.8 (0.2 - 0.5) = 0.26
    # clipped: 0.9 + 0.8 (1 + 0.585 - 0.9) = 1.448 -> 1;  0.1 + 0.8 (-1 - 0.1) = -0.78 -> 0
    np.testing.assert_allclose(targets, [0.492, 0.5, 0.26, 1.0, 0.0], rtol=1e-14)
    assert share == pytest.approx(2 / 5)
    default, share0 = sarsa_targets(q_sa[:3], rewards[:3], q_next[:3], terminal[:3], alpha, gamma)
    np.testing.assert_allclose(default, [0.492, 0.26, 0.26], rtol=1e-14)
    assert share0 == 0.0


@pytest.mark.parametrize("kind", ["paper", "extended", "bearing"])
def test_reward_is_theta_dot_f_eq2(kind):
    """r_theta(s, a) = theta^T f(s, a) (eq. 2) with f of eq. 4-5 (or the extended map)."""
    from nirl_mj.learn.reward import RewardModel, all_action_features, pair_features

    rng = np.random.default_rng(9)
    phi = np.column_stack([rng.integers(1, 8, (12, 7)), rng.integers(1, 10, 12), rng.integers(0, 2, (12, 8))])
    actions = rng.integers(0, 6, 12)
    model = RewardModel(rng.normal(size=all_action_features(phi[:1], kind).shape[-1]), kind)
    np.testing.assert_allclose(model.reward(phi, actions), pair_features(phi, actions, kind) @ model.theta)
    np.testing.assert_allclose(model.rewards_all_actions(phi), all_action_features(phi, kind) @ model.theta)


def test_the_papers_pair_features_put_phi_in_the_taken_actions_block_eq4_5():
    """Eq. 4-5 by hand: f(s, a) is 96 values, phi(s) in block a (16 values from 16 a), zeros elsewhere;
    so r_theta(s, a) = theta_a . phi(s) (eq. 2)."""
    from nirl_mj.learn.reward import RewardModel, pair_features

    phi = np.arange(1.0, 17.0)
    f = pair_features(phi[None], np.array([2]), "paper")[0]
    expected = np.zeros(96)
    expected[32:48] = phi
    np.testing.assert_array_equal(f, expected)
    theta = np.zeros(96)
    theta[32:48], theta[:16] = 0.5, 7.0  # another action's block does not count
    assert RewardModel(theta, "paper").reward(phi[None], np.array([2]))[0] == 0.5 * phi.sum()


def test_bearing_features_hold_the_target_sectors_centre_as_cos_and_sin():
    from nirl_mj.learn.reward import block_names, state_reward_features

    # D = 7, 0, ..., V = 3 (the sector centred 80 degrees to the left), I = 1, U = 1 on S1
    phi = np.array([7, 0, 0, 0, 0, 0, 0, 3, 1, 1, 0, 0, 0, 0, 0, 0], dtype=float)
    block = state_reward_features(phi[None], "bearing")[0]
    names = block_names("bearing")
    assert block.shape == (27,) and len(names) == 27
    by_name = dict(zip(names, block, strict=True))
    assert by_name["D_S1/7"] == 1.0 and by_name["V=3"] == 1.0 and by_name["V=1"] == 0.0
    assert by_name["cos_V"] == pytest.approx(np.cos(np.deg2rad(80.0)))
    assert by_name["sin_V"] == pytest.approx(np.sin(np.deg2rad(80.0)))
    assert by_name["I"] == 1.0 and by_name["U_S1"] == 1.0 and by_name["const"] == 1.0
    # the extended block is the same without the two bearing values
    extended = state_reward_features(phi[None], "extended")[0]
    np.testing.assert_array_equal(np.delete(block, [16, 17]), extended)


def test_the_paper_readings_margin_is_eq13_with_every_pair_and_action_alike():
    """matching = "paper": eq. 13 with eq. 11's expectations on both sides. Every demonstrated pair has
    the expert side mu_E and every alternative the learner's mu, so the step minimises
    theta . (mu - mu_E) + mean_n l_n + lambda/2 ||theta||^2 over one pair and one action: the same
    iterates as the objective over all N pairs and 6 actions written out (to rounding), and one
    step by hand (an empty rollout left out of mu; the step size of iteration 2 under a decay)."""
    from nirl_mj.learn.config import LearnerConfig
    from nirl_mj.learn.mmp import MaxMarginStep, feature_expectations, project_to_ball
    from nirl_mj.learn.reward import trajectory_pair_features

    rng = np.random.default_rng(4)
    demos = [random_trajectory(rng, n, "target") for n in (7, 5)]
    rollouts = [random_trajectory(rng, n, "collision") for n in (3, 0, 6, 4)]
    config = LearnerConfig.preset("paper", mmp_steps=7, mmp_lambda=0.2, mmp_step_decay=0.5)
    own, kind, gamma = config.step, config.loop.reward_features, config.loop.gamma
    step = MaxMarginStep(config.loop, own, demos)
    greedy = np.array(step.demo_actions)
    greedy[:5] = (greedy[:5] + 1) % 6  # 5 of the 12 demonstrated pairs missed
    theta0 = rng.normal(size=96) * 0.05
    theta, margin = step.update(theta0, rollouts, 2, greedy)

    mu_e = feature_expectations(trajectory_pair_features(demos, kind), gamma)
    mu = feature_expectations(trajectory_pair_features([rollouts[i] for i in (0, 2, 3)], kind), gamma)
    n, lr = len(greedy), own.mmp_step_size / (1.0 + 0.5 * 2)
    per_pair = np.where(greedy == step.demo_actions, 0.0, config.loop.margin_loss)
    written_out = minimise_mmp(theta0, np.tile(mu_e, (n, 1)), np.tile(mu, (n, 6, 1)),
                               np.repeat(per_pair[:, None], 6, axis=1), own.mmp_lambda, own.mmp_steps,
                               lr)  # fmt: skip
    np.testing.assert_allclose(theta, written_out[0], rtol=1e-12, atol=1e-12)
    assert margin == pytest.approx(-written_out[1], rel=1e-12)

    # one step by hand: J(theta) = theta . (mu - mu_E) + 5/12 l + lambda/2 ||theta||^2, its gradient
    # mu - mu_E + lambda theta; theta1 = P(theta0 - lr grad); the lower J of theta0 and theta1 is kept
    def j(t: np.ndarray) -> float:
        return t @ (mu - mu_e) + 5 / 12 * config.loop.margin_loss + own.mmp_lambda / 2 * t @ t

    theta1 = project_to_ball(theta0 - lr * (mu - mu_e + own.mmp_lambda * theta0))
    best = min((theta0, theta1), key=j)
    one = MaxMarginStep(config.loop, LearnerConfig.preset("paper", mmp_steps=1, mmp_lambda=0.2,
                                                          mmp_step_decay=0.5).step, demos)  # fmt: skip
    theta_one, margin_one = one.update(theta0, rollouts, 2, greedy)
    np.testing.assert_allclose(theta_one, best, rtol=1e-12, atol=1e-15)
    assert margin_one == pytest.approx(-j(best), rel=1e-12)
    assert not np.allclose(theta1, theta0) and not hasattr(step, "expert")  # no per-pair arrays kept


@pytest.mark.parametrize("kind", ["paper", "extended", "bearing"])
def test_pair_features_are_the_taken_actions_rows_of_all_action_features(kind):
    from nirl_mj.learn.reward import all_action_features, pair_features

    rng = np.random.default_rng(11)
    phi = np.column_stack([rng.integers(1, 8, (20, 7)), rng.integers(1, 10, 20), rng.integers(0, 2, (20, 8))])
    actions = rng.integers(0, 6, 20)
    expected = all_action_features(phi, kind)[np.arange(20), actions]
    np.testing.assert_array_equal(pair_features(phi, actions, kind), expected)
    # datasets hold actions as int8: slot 5 of the bearing map starts at 5 * 27 = 135 > 127
    np.testing.assert_array_equal(pair_features(phi, actions.astype(np.int8), kind), expected)
