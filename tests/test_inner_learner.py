"""The inner learner's options, each on a hand-computed case: Q-learning targets, the network
width, n-step targets, exploration, bearing inputs and value-fitting rounds."""

import dataclasses

import numpy as np
import pytest

from nirl_mj.data.trajectory import Trajectory
from nirl_mj.data.transitions import Transitions
from nirl_mj.learn import network, sarsa
from nirl_mj.learn.config import LearnerConfig, checked_changes
from nirl_mj.learn.loop import IrlLoop

PHI = np.array([0, 0, 0, 0, 0, 0, 0, 4, 1, 0, 0, 0, 0, 0, 0, 0], dtype=float)


def demos() -> list[Trajectory]:
    n = 3
    trajectory = Trajectory(
        features=np.tile(PHI, (n + 1, 1)), actions=np.array([0, 1, 0]), ranges=np.zeros((n + 1, 9)),
        poses=np.zeros((n + 1, 3)), times=0.5 * np.arange(n + 1), arena_seed=0, task={}, speed=2.0,
        outcome="timeout", demonstrator="test",
    )  # fmt: skip
    return [trajectory]


def loop(**changes) -> IrlLoop:
    settings = {"reward_source": "constant", "reward_scaling": False, **changes}
    config = LearnerConfig.preset("default", **settings)
    return IrlLoop(config, demos(), seed=0)


def transitions(next_action: int, terminal: bool) -> Transitions:
    return Transitions(
        phi=PHI[None], action=np.array([2]), next_phi=PHI[None], next_action=np.array([next_action]),
        terminal=np.array([terminal]), terminal_value=np.array([0.0]), progress=np.zeros(1),
        remaining=np.ones(1, int), absorbing=np.zeros(1, bool),
    )  # fmt: skip


@pytest.mark.parametrize("bootstrap", ["sarsa", "q"])
def test_targets_bootstrap_from_the_next_pair_or_the_greedy_value(bootstrap):
    learner = loop(bootstrap=bootstrap, alpha=0.5, gamma=0.5)
    q = network.q_values(learner.net, learner.demo_inputs[:1])[0]  # every state here is PHI
    targets, _, _ = learner._targets(transitions(next_action=4, terminal=False))
    nxt = q.max() if bootstrap == "q" else q[4]
    # eq. 14 with r = 1 (constant reward, unscaled): Q + alpha (r + gamma Q' - Q)
    assert targets[0] == pytest.approx(np.clip(q[2] + 0.5 * (1.0 + 0.5 * nxt - q[2]), 0, 1))
    terminal, _, _ = learner._targets(transitions(next_action=4, terminal=True))
    assert terminal[0] == pytest.approx(np.clip(q[2] + 0.5 * (1.0 - q[2]), 0, 1))  # no bootstrap


def test_the_network_width_is_a_setting():
    learner = loop(hidden_units=32)  # 17 inputs ((cos, sin) of V in V's place) and a bias
    assert network.get_weights(learner.net)["W1"].shape == (32, 18)
    assert network.get_weights(learner.net)["W2"].shape == (6, 33)


@pytest.mark.parametrize(
    ("name", "neutral", "why"),
    [("weight_averaging", 0.0, "Polyak averaging .* commit d3ea6fe"),
     ("reward_ceiling", 1.0, "rewards scaled into .* commit 7626b6d")],
)  # fmt: skip
def test_a_retired_setting_loads_only_at_the_value_that_did_nothing(name, neutral, why):
    # a removed setting (learn/config.py RETIRED): a record or experiment that holds its neutral value
    # loads as it was trained; any other value is refused, naming the commit that runs it
    record = {**LearnerConfig.preset("default").to_dict(), name: neutral}
    assert LearnerConfig.from_record(record) == LearnerConfig.preset("default")
    with pytest.raises(ValueError, match=f"{name} = 0.5: {why}"):
        LearnerConfig.from_record({**record, name: 0.5})
    with pytest.raises(ValueError, match=f"--config: {name} = 0.8"):
        checked_changes({name: 0.8}, "--config")
    assert checked_changes({name: neutral, "gamma": 0.5}, "--config") == {"gamma": 0.5}


def test_n_step_returns_stop_at_the_end_of_each_trajectory():
    # two trajectories: rows 0-2 and row 3; future_t is what a one-step target adds after r_t
    rewards = np.array([1.0, 2.0, 3.0, 4.0])
    future = np.array([10.0, 20.0, 30.0, 40.0])
    remaining = np.array([3, 2, 1, 1])
    one = sarsa.n_step_returns(rewards, future, remaining, gamma=0.5, n=1)
    np.testing.assert_allclose(one, [11.0, 22.0, 33.0, 44.0])  # r_t + future_t (eq. 14)
    two = sarsa.n_step_returns(rewards, future, remaining, gamma=0.5, n=2)
    # row 0: 1 + 0.5 * 2 + 0.5 * 20 = 12; row 1: 2 + 0.5 * 3 + 0.5 * 30 = 18.5; rows 2-3 end there
    np.testing.assert_allclose(two, [12.0, 18.5, 33.0, 44.0])
    three = sarsa.n_step_returns(rewards, future, remaining, gamma=0.5, n=3)
    # row 0: 1 + 0.5 * 2 + 0.25 * 3 + 0.25 * 30 = 10.25
    np.testing.assert_allclose(three, [10.25, 18.5, 33.0, 44.0])
    with pytest.raises(ValueError, match="n >= 1"):
        sarsa.n_step_returns(rewards, future, remaining, gamma=0.5, n=0)


def test_n_step_targets_in_the_loop_follow_the_trajectory():
    # the outcome reading: the rows' own terminal_value is the value of their end
    config = LearnerConfig.preset("default", reward_source="constant", bootstrap="q", alpha=1.0, gamma=0.5,
                                  n_step=2, terminal_value="outcome")  # fmt: skip
    learner = IrlLoop(config, demos(), seed=0)
    q = network.q_values(learner.net, learner.demo_inputs[:1])[0]  # every state here is PHI
    t = Transitions.concat([transitions(next_action=4, terminal=False)] * 2)
    t.remaining[:] = [2, 1]
    targets, _, _ = learner._targets(t)
    # constant reward scaled into [0, 1 - gamma]: r = 0.25 (alpha = 1: the target is the return)
    # row 0: 0.25 + 0.5 * 0.25 + 0.25 max Q(s''); row 1 ends its trajectory: 0.25 + 0.5 max Q(s')
    np.testing.assert_allclose(targets, [0.375 + 0.25 * q.max(), 0.25 + 0.5 * q.max()])
    t.terminal[1], t.terminal_value[1] = True, 0.5
    targets, _, _ = learner._targets(t)
    # row 0: 0.25 + 0.5 * 0.25 + 0.5 * 0.5 = 0.625; row 1: 0.25 + 0.5 = 0.75 (no bootstrap at the end)
    np.testing.assert_allclose(targets, [0.625, 0.75])


def test_scaled_rewards_span_zero_to_one_minus_gamma():
    # progress in [-1, 1] (the control's known range) maps to [0, 1 - gamma]
    learner = IrlLoop(LearnerConfig.preset("default", reward_source="progress", gamma=0.9), demos(), 0)
    for progress, expected in ((-1.0, 0.0), (0.0, 0.05), (1.0, 0.1)):
        t = dataclasses.replace(transitions(next_action=-1, terminal=False), progress=np.array([progress]))
        rewards, spread = learner._rewards(t)
        assert rewards[0] == pytest.approx(expected) and spread == 2.0
    # so the best reward forever is worth 0.1 / (1 - 0.9) = 1: an arrival's value


def test_exploration_goes_linearly_from_eta_to_eta_final():
    learner = loop(episodes=3, eta=5.0, eta_final=60.0)
    assert [learner.eta() for learner.iteration in range(3)] == pytest.approx([5.0, 32.5, 60.0])


def test_bearing_inputs_put_the_sectors_centre_as_cos_and_sin_in_vs_place():
    from nirl_mj.learn.inputs import NetworkInputs

    phi = np.array([[7, 0, 0, 0, 0, 0, 0, 5, 1, 1, 0, 0, 0, 0, 0, 0]], dtype=float)  # V = 5: 160 degrees
    x = NetworkInputs(scaled=True, bearing=True)(phi)
    assert x.shape == (1, 17) and NetworkInputs(bearing=True).size == 17
    np.testing.assert_allclose(x[0, :7], [1, 0, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(x[0, 7:9], [np.cos(np.deg2rad(160.0)), np.sin(np.deg2rad(160.0))])
    np.testing.assert_allclose(x[0, 9:], [1, 1, 0, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(NetworkInputs(scaled=True)(phi)[0, 7], 5 / 9)  # the default code: V/9
    learner = loop(input_bearing=True)
    assert network.get_weights(learner.net)["W1"].shape == (32, 18)


def test_network_agent_remembers_each_states_choice_without_changing_a_draw():
    """The agent computes each phi's Boltzmann CDF once per episode; its draws are those of
    sample_action on freshly computed values, from the same generator (repeated states included)."""
    from types import SimpleNamespace

    from nirl_mj.learn import network
    from nirl_mj.learn.inputs import NetworkInputs
    from nirl_mj.learn.loop import NetworkAgent

    net, inputs = network.QNetwork(16, 10, 6, seed=3), NetworkInputs()
    states = np.random.default_rng(1).integers(0, 8, size=(4, 16)).astype(np.float32)
    visits = [states[k] for k in (0, 1, 0, 2, 0, 1, 3, 3, 0)]
    agent = NetworkAgent(net, inputs, 4.0, np.random.default_rng(7))
    agent.reset(None, None)
    drawn = [agent.act(SimpleNamespace(observation={"features": phi})) for phi in visits]
    rng = np.random.default_rng(7)
    fresh = [network.sample_action(network.q_values(net, inputs(phi[None]))[0], 4.0, rng) for phi in visits]
    assert drawn == fresh
    assert len(agent._choices) == 4
    greedy = NetworkAgent(net, inputs, None, np.random.default_rng(7))
    greedy.reset(None, None)
    assert [greedy.act(SimpleNamespace(observation={"features": phi})) for phi in visits] == [
        int(network.greedy_actions(network.q_values(net, inputs(phi[None])))[0]) for phi in visits
    ]


@pytest.mark.parametrize("eta", [4.0, None])
def test_network_agent_acts_on_many_worlds_at_once_as_world_by_world(eta):
    """act_batch (the Warp backend's one call for every world) chooses what act chooses row by
    row, Boltzmann draws included, and leaves the generator where N calls of act leave it."""
    from types import SimpleNamespace

    from nirl_mj.learn.inputs import NetworkInputs
    from nirl_mj.learn.loop import NetworkAgent

    net, inputs = network.QNetwork(17, 32, 6, seed=5), NetworkInputs(scaled=True, bearing=True)
    states = np.random.default_rng(2).integers(0, 8, size=(300, 16)).astype(np.float32)
    states[:, 7] = np.random.default_rng(3).integers(1, 10, size=300)  # V, the target's sector: 1..9
    one, many = (NetworkAgent(net, inputs, eta, np.random.default_rng(11)) for _ in range(2))
    one.reset(None, None)
    many.reset(None, None)
    by_world = [one.act(SimpleNamespace(observation={"features": phi})) for phi in states]
    at_once = many.act_batch(states)
    assert at_once.shape == (300,) and at_once.dtype == np.int64
    assert at_once.tolist() == by_world
    assert len(set(by_world)) > 1  # the states differ enough for the choice to vary
    assert one.rng.random() == many.rng.random()


def test_a_learner_reads_the_loop_and_its_own_reward_steps_settings():
    """settings_read, what --reuse and restored cells compare: AL does not read the max-margin
    step's decay, NIRL does; both read the loop's n_step."""
    al, nirl = LearnerConfig().replace(method="al"), LearnerConfig().replace(method="nirl")
    assert "mmp_step_decay" in al.to_dict() and "mmp_step_decay" not in al.settings_read()
    assert "al_expectations" in al.settings_read() and "al_expectations" not in nirl.settings_read()
    changed = {"mmp_step_decay": 0.1}
    assert al.replace(**changed).settings_read() == al.settings_read()
    assert nirl.replace(**changed).settings_read() != nirl.settings_read()
    assert al.replace(n_step=1).settings_read() != al.settings_read()


def self_loop(n: int = 1) -> Transitions:
    """``n`` copies of one pair that returns to its own state and takes the same action again."""
    one = transitions(next_action=2, terminal=False)
    return Transitions.concat([one] * n)


@pytest.mark.parametrize("replay", [10, 0])  # minibatch epochs over a window; the paper's full batch
def test_each_fitting_round_computes_its_targets_again_from_the_network(replay):
    # scaled rewards (0.05 a decision) keep the targets inside [0, 1], where they read the network
    two = loop(fit_rounds=2, reward_scaling=True, replay_episodes=replay)
    one = loop(reward_scaling=True, replay_episodes=replay)
    t = self_loop(4)
    two._fit(t)
    one._fit(t)  # the same network and draws: round 1, then round 2 on targets of the new network
    one._fit(t)
    for name, w in network.get_weights(two.net).items():
        np.testing.assert_array_equal(w, network.get_weights(one.net)[name])
    # as many epochs on one set of targets: another network
    fixed = loop(net_epochs=8, reward_scaling=True, replay_episodes=replay)
    fixed._fit(t)
    assert not np.array_equal(network.get_weights(fixed.net)["W2"], network.get_weights(two.net)["W2"])


def test_more_fitting_rounds_bring_a_self_loop_nearer_its_value():
    # constant reward 1, scaled into [0, 1 - gamma] over [0, 2]: r = 0.05 a decision at gamma 0.9; the
    # pair returns to itself (SARSA on its own action), so its value is r / (1 - gamma) = 0.5
    def error(rounds: int) -> float:
        learner = loop(fit_rounds=rounds, reward_scaling=True, bootstrap="sarsa", n_step=1)
        learner._fit(self_loop(64))
        return abs(network.q_values(learner.net, learner.demo_inputs[:1])[0, 2] - 0.5)

    errors = [error(rounds) for rounds in (1, 4, 16)]
    assert errors[0] > errors[1] > errors[2] and errors[2] < 0.5 * errors[0]


def test_fitting_rounds_are_counted_from_one():
    with pytest.raises(ValueError, match="fit_rounds"):
        LearnerConfig.preset("default", fit_rounds=0)
