"""GAIL and AIRL: their discriminators by hand, the reward wrapper, and a short run of each."""

import math

import numpy as np
import pytest
import torch
from helpers import OPEN, progress

from nirl_mj.learn.adversarial import (
    PENALTY_WEIGHT,
    AirlDiscriminator,
    GailDiscriminator,
    discriminator_loss,
    gradient_penalty,
    make_discriminator,
)


def constant_heads(disc: torch.nn.Module, **biases: list[float]) -> None:
    """Zero every weight; the last layer of each named head outputs its bias whatever the input."""
    with torch.no_grad():
        for p in disc.parameters():
            p.zero_()
        for name, bias in biases.items():
            getattr(disc, name)[-1].bias.copy_(torch.tensor(bias))


def test_discriminator_loss_by_hand():
    zero = torch.zeros(1)
    assert float(discriminator_loss(zero, zero)) == pytest.approx(2 * math.log(2))
    # expert logit ln 3 (D = 3/4): -ln(3/4); learner logit ln 3: -ln(1 - 3/4) = ln 4
    l3 = torch.tensor([math.log(3.0)])
    assert float(discriminator_loss(l3, l3)) == pytest.approx(math.log(4 / 3) + math.log(4))


def test_gail_logits_pick_the_action_and_reward_is_minus_log_one_minus_d():
    disc = GailDiscriminator()
    constant_heads(disc, net=[0.0, 1.0, 2.0, 3.0, 4.0, math.log(3.0)])
    x = torch.zeros((2, 16))
    logits = disc.logits(x, torch.tensor([1, 5]))
    np.testing.assert_allclose(logits.detach().numpy(), [1.0, math.log(3.0)], rtol=1e-6)
    # D = 3/4 at logit ln 3: -ln(1 - 3/4) = ln 4
    assert float(disc.policy_reward(logits.detach())[1]) == pytest.approx(math.log(4.0), rel=1e-6)


def test_airl_f_shaping_terminal_and_logit_by_hand():
    disc = AirlDiscriminator(gamma=0.5)
    constant_heads(disc, g=[1.0, 2.0, 0.0, 0.0, 0.0, 0.0], h=[4.0])
    x = torch.zeros((2, 16))
    actions, terminal = torch.tensor([0, 1]), torch.tensor([False, True])
    # f = g(s, a) + gamma h(s') - h(s): 1 + 2 - 4 = -1; terminal: h(s') = 0, 2 - 4 = -2
    np.testing.assert_allclose(disc.f(x, actions, x, terminal).detach().numpy(), [-1.0, -2.0], rtol=1e-6)
    # the logit subtracts ln pi(a | s); the policy's reward is the logit
    log_pi = torch.tensor([math.log(0.5), math.log(0.25)])
    logits = disc.logits(x, actions, x, terminal, log_pi)
    np.testing.assert_allclose(logits.detach().numpy(), [-1 + math.log(2), -2 + math.log(4)], rtol=1e-6)
    assert torch.equal(disc.policy_reward(logits), logits)
    np.testing.assert_allclose(disc.reward(np.zeros((1, 16))), [[1, 2, 0, 0, 0, 0]])
    with pytest.raises(ValueError, match="accepted: gail, airl"):
        make_discriminator("wgan", 0.9)


def at_absorbing(head: torch.nn.Sequential, values: list[float]) -> None:
    """After ``constant_heads``: the head outputs ``values`` at s_a (its indicator input, the last,
    set to 1) and its bias elsewhere. Path: the indicator drives hidden unit 0 to tanh(20) = 1 (in
    float32), the second layer passes tanh(1) on, the last layer scales it."""
    with torch.no_grad():
        head[0].weight[0, -1] = 20.0
        head[2].weight[0, 0] = 1.0
        head[4].weight[:, 0] = (torch.tensor(values) - head[4].bias) / math.tanh(1.0)


def test_gail_absorbing_state_is_an_input_of_the_network():
    disc = GailDiscriminator(absorbing=True)
    assert disc.net[0].in_features == 17
    constant_heads(disc, net=[1.0] * 6)
    at_absorbing(disc.net, [math.log(3.0)] * 6)
    absorbing = torch.tensor([False, True])
    x = torch.ones((2, 16))  # s_a's phi is not read: zeroed
    logits = disc.logits(x, torch.tensor([0, 0]), absorbing=absorbing)
    np.testing.assert_allclose(logits.detach().numpy(), [1.0, math.log(3.0)], rtol=1e-5)
    # the networks' input: phi zeroed at s_a, then the indicator
    expected = torch.cat(
        [torch.stack([torch.ones(16), torch.zeros(16)]), torch.tensor([[0.0], [1.0]])], dim=1
    )
    assert torch.equal(disc.inputs(x, absorbing), expected)
    with pytest.raises(ValueError, match="without an absorbing state"):
        GailDiscriminator().logits(torch.zeros((2, 16)), torch.tensor([0, 0]), absorbing=absorbing)


ALL_VARIANTS = ["gail", "gail-absorbing", "airl", "airl-absorbing", "gail-norm", "airl-norm",
                "gail-gp", "airl-gp", "gail-gp1", "airl-gp1", "gail-gp0_1", "airl-gp0_1",
                "airl-state", "gail-d2", "airl-d2"]  # fmt: skip


@pytest.mark.parametrize("algo", ALL_VARIANTS)
def test_a_saved_discriminator_loads_with_its_absorbing_state_or_without(tmp_path, algo):
    from nirl_mj.data.rundir import RunDir, RunError
    from nirl_mj.data.transitions import Transitions
    from nirl_mj.experiments.adversarial import AdversarialReward, load_discriminator, save_discriminator

    demos = Transitions.pairs(np.zeros((1, 16)), np.zeros(1, int), np.zeros((1, 16)), np.zeros(1, bool))
    reward = AdversarialReward(algo, 0.99, demos, seed=3)
    save_discriminator(RunDir(tmp_path), reward)
    loaded = load_discriminator(tmp_path, algo.split("-")[0], 0.99)
    assert loaded.inputs.absorbing == algo.endswith("absorbing")
    assert getattr(loaded, "state_only", False) == algo.endswith("state")
    for name, value in reward.discriminator.state_dict().items():
        assert torch.equal(loaded.state_dict()[name], value)
    if algo.endswith("norm"):  # a resume goes on with the reward normaliser's statistics
        from nirl_mj.experiments.adversarial import read_discriminator

        reward.norm.update(np.array([1.0, 2.0]))
        save_discriminator(RunDir(tmp_path), reward)
        resumed = AdversarialReward(algo, 0.99, demos, seed=3)
        resumed.load_state(read_discriminator(RunDir(tmp_path)))
        np.testing.assert_array_equal(resumed.norm.state(), [1.5, 0.25, 2])
        plain = AdversarialReward(algo.split("-")[0], 0.99, demos, seed=3)  # weights without statistics
        with pytest.raises(RunError, match="not trained with -norm"):
            resumed.load_state(plain.state())


def test_the_adversarial_algorithms_are_the_same_list_everywhere():
    from nirl_mj.experiments.adversarial import algorithms, variant_of
    from nirl_mj.experiments.rl import ADVERSARIAL

    assert sorted(algorithms()) == sorted(ADVERSARIAL) == sorted(ALL_VARIANTS)
    assert [variant_of(a).kind for a in ADVERSARIAL] == [a.split("-")[0] for a in ADVERSARIAL]
    assert variant_of("airl-state").state_only and variant_of("airl").penalty == 0.0
    assert [variant_of(f"gail-{gp}").penalty for gp in ("gp", "gp1", "gp0_1")] == [10.0, 1.0, 0.1]
    for wrong in ("gail-state", "airl-gp-norm", "wgan"):
        with pytest.raises(ValueError, match="accepted: gail, airl, gail-absorbing"):
            variant_of(wrong)
    with pytest.raises(ValueError, match="state-only reward is AIRL's"):
        make_discriminator("gail", 0.9, state_only=True)


@pytest.mark.parametrize("algo, steps", [("gail", 4 * 3), ("airl", 4 * 3), ("gail-d2", 2), ("airl-d2", 2)])
def test_the_discriminator_takes_minibatch_epochs_or_two_full_batch_steps(algo, steps):
    """600 learner pairs: 4 epochs of 3 minibatches (256, 256, 88) by default; with "-d2" two Adam
    steps, each on all 600 pairs against 600 demonstrated ones (the imitation library's default)."""
    from nirl_mj.data.transitions import Transitions
    from nirl_mj.experiments.adversarial import AdversarialReward

    rng = np.random.default_rng(0)

    def pairs(n: int) -> Transitions:
        return Transitions.pairs(
            rng.random((n, 16)), rng.integers(0, 6, n), rng.random((n, 16)), np.zeros(n, bool)
        )

    reward = AdversarialReward(algo, 0.99, pairs(50), seed=1)
    sizes = []
    logits = reward.logits
    reward.logits = lambda batch: (sizes.append(len(batch.action)), logits(batch))[1]
    reward.update(pairs(600))
    per_step = [600] * 4 if algo.endswith("d2") else [256, 256, 256, 256, 88, 88] * 4
    assert sizes == per_step  # the demonstrated pairs' minibatch, then the learner's, per step
    assert reward.optimiser.state_dict()["state"][0]["step"] == steps
    recorded = reward.variant.settings()  # what the run's run.json says it did
    assert recorded == ({"full_batch_steps": 2, "learning_rate": 3e-4} if algo.endswith("d2") else
                        {"epochs": 4, "batch_size": 256, "learning_rate": 3e-4})  # fmt: skip


def test_airl_state_only_reward_by_hand():
    disc = AirlDiscriminator(gamma=0.5, state_only=True)
    assert disc.g[-1].out_features == 1
    constant_heads(disc, g=[2.0], h=[4.0])
    x = torch.zeros((3, 16))
    # f = g(s) + gamma h(s') - h(s), whatever the action: 2 + 2 - 4 = 0; terminal: 2 - 4 = -2
    f = disc.f(x, torch.tensor([0, 3, 5]), x, torch.tensor([False, False, True]))
    np.testing.assert_allclose(f.detach().numpy(), [0.0, 0.0, -2.0], atol=1e-6)
    # one value for every action
    np.testing.assert_allclose(disc.reward(np.zeros((2, 16))), np.full((2, 6), 2.0))


def test_gradient_penalty_by_hand():
    w = torch.arange(16, dtype=torch.float32)
    x = torch.ones((2, 16))
    # l = x . w + 3 x'_0 + a constant: its gradient is (w, 3 e_0) in every row, whatever x
    penalty = gradient_penalty(lambda x, x_next: x @ w + 3 * x_next[:, 0] + 7.0, x, 2 * x)
    expected = PENALTY_WEIGHT / 2 * (float(w @ w) + 9.0)
    assert float(penalty.detach()) == pytest.approx(expected)
    # a logit that ignores x' (GAIL's): only x's gradient
    assert float(gradient_penalty(lambda x, x_next: (x**2).sum(dim=1), x, x).detach()) == pytest.approx(
        PENALTY_WEIGHT / 2 * 4 * 16
    )  # d/dx sum x^2 = 2x = 2 in 16 inputs: |.|^2 = 64


@pytest.mark.parametrize("algo", ["gail-gp", "airl-gp"])
def test_the_penalty_is_r1_of_the_networks_own_gradient(algo):
    """The penalty of a real discriminator against central finite differences of its logits."""
    from nirl_mj.data.transitions import Transitions
    from nirl_mj.experiments.adversarial import AdversarialReward

    rng = np.random.default_rng(1)
    x, x_next = rng.random((3, 16)).astype(np.float32), rng.random((3, 16)).astype(np.float32)
    expert = Transitions.pairs(x, np.array([0, 2, 5]), x_next, np.array([False, True, False]))
    reward = AdversarialReward(algo, 0.9, expert, seed=2)
    a, terminal = torch.tensor([0, 2, 5]), torch.tensor([False, True, False])

    def logits(x, x_next):
        return reward.discriminator.logits(x, a, x_next, terminal, torch.zeros(3)).double()

    squares = np.zeros(3)
    step = 1e-2
    for which in (0, 1):
        for i in range(16):
            up = [torch.as_tensor(x.copy()), torch.as_tensor(x_next.copy())]
            down = [torch.as_tensor(x.copy()), torch.as_tensor(x_next.copy())]
            up[which][:, i] += step
            down[which][:, i] -= step
            with torch.no_grad():
                squares += ((logits(*up) - logits(*down)).numpy() / (2 * step)) ** 2
    expected = PENALTY_WEIGHT / 2 * squares.mean()
    assert float(reward.penalty(expert).detach()) == pytest.approx(expected, rel=2e-3)
    lighter = AdversarialReward(algo + "0_1", 0.9, expert, seed=2)  # the same network, weight 0.1 of 10
    assert float(lighter.penalty(expert).detach()) == pytest.approx(expected / 100, rel=2e-3)


def test_the_penalty_flattens_the_discriminator_where_the_expert_is():
    """Trained on the same separable pairs, a penalised GAIL discriminator's logit varies far less
    around the expert's states than an unpenalised one's (the penalty is not a no-op)."""
    from nirl_mj.data.transitions import Transitions
    from nirl_mj.experiments.adversarial import AdversarialReward

    rng = np.random.default_rng(0)
    a, x_next, terminal = np.zeros(256, int), np.zeros((256, 16)), np.zeros(256, bool)
    expert = Transitions.pairs(rng.random((256, 16)) * 0.5, a, x_next, terminal)
    learner = Transitions.pairs(rng.random((256, 16)) * 0.5 + 0.5, a, x_next, terminal)
    norms = {}
    for algo in ("gail", "gail-gp"):
        reward = AdversarialReward(algo, 0.9, expert, seed=0)
        for _ in range(30):
            reward.update(learner)
        norms[algo] = float(reward.penalty(expert).detach())
    assert norms["gail-gp"] < 0.25 * norms["gail"]


def test_running_norm_by_hand():
    from nirl_mj.learn.running_norm import RunningNorm

    norm = RunningNorm(eps=0.0)
    assert (norm.mean, norm.var, norm.count) == (0.0, 1.0, 0)  # before any value: the identity
    # each batch joins the statistics, then is normalised by them
    np.testing.assert_allclose(norm(np.array([1.0, 3.0])), [-1.0, 1.0])
    assert (norm.mean, norm.var, norm.count) == (2.0, 1.0, 2)  # mean of 1, 3; variance ((-1)^2 + 1^2) / 2
    np.testing.assert_allclose(norm(np.array([5.0])), [2.0 / math.sqrt(8.0 / 3.0)])
    np.testing.assert_allclose([norm.mean, norm.var], [3.0, 8.0 / 3.0])  # of 1, 3, 5: (4 + 0 + 4) / 3
    norm.update(np.array([]))
    assert norm.count == 3
    values = np.random.default_rng(0).normal(2.0, 3.0, 1000)
    merged = RunningNorm()
    for batch in np.array_split(values, 7):  # merging batches of any sizes = the statistics of all
        merged.update(batch)
    np.testing.assert_allclose([merged.mean, merged.var], [values.mean(), values.var()], rtol=1e-12)


def test_airl_absorbing_state_by_hand():
    disc = AirlDiscriminator(gamma=0.5, absorbing=True)
    constant_heads(disc, g=[1.0, 2.0, 0.0, 0.0, 0.0, 0.0], h=[4.0])
    at_absorbing(disc.g, [0.5] * 6)  # g(s_a, .)
    at_absorbing(disc.h, [3.0])  # h(s_a)
    x = torch.zeros((3, 16))
    actions, terminal = torch.tensor([0, 1, 0]), torch.tensor([False, True, True])
    absorbing = torch.tensor([False, False, True])
    # 1 + 0.5 * 4 - 4 = -1; into s_a: 2 + 0.5 * h(s_a) - 4 = -0.5; in s_a: 0.5 + (0.5 - 1) * 3 = -1
    f = disc.f(x, actions, x, terminal, absorbing)
    np.testing.assert_allclose(f.detach().numpy(), [-1.0, -0.5, -1.0], rtol=1e-5)
    # s_a offers one action: ln pi = 0 there, whatever the policy's own ln pi in the zero input
    log_pi = torch.tensor([math.log(0.5), math.log(0.25), math.log(0.1)])
    logits = disc.logits(x, actions, x, terminal, log_pi, absorbing)
    expected = [-1 + math.log(2), -0.5 + math.log(4), -1.0]
    np.testing.assert_allclose(logits.detach().numpy(), expected, rtol=1e-5)
    np.testing.assert_allclose(disc.reward(np.zeros((1, 16))), [[1, 2, 0, 0, 0, 0]], atol=1e-6)  # g(s, .)


class Corridor:
    """A gymnasium env: 16 zeros then the step count in x[0]; ends (terminated) after 2 steps,
    with a task reward of 100 that the wrapper must drop."""

    def __new__(cls):
        gymnasium = pytest.importorskip("gymnasium")

        class Env(gymnasium.Env):
            observation_space = gymnasium.spaces.Box(0.0, 10.0, (16,), np.float32)
            action_space = gymnasium.spaces.Discrete(6)

            def reset(self, seed=None, options=None):
                self.t = 0
                return np.zeros(16, np.float32), {}

            def step(self, action):
                self.t += 1
                obs = np.zeros(16, np.float32)
                obs[0] = self.t
                return obs, 100.0, self.t == 2, False, {}

        return Env()


def test_expert_transitions_end_terminal_only_in_terminal_states():
    from nirl_mj.data.trajectory import Trajectory
    from nirl_mj.experiments.adversarial import expert_transitions

    def demo(outcome: str, n: int = 2) -> Trajectory:
        return Trajectory(features=np.arange(16 * (n + 1), dtype=np.float32).reshape(n + 1, 16),
                          actions=np.zeros(n, int), ranges=np.zeros((n + 1, 9)), poses=np.zeros((n + 1, 3)),
                          times=0.5 * np.arange(n + 1), arena_seed=0, task={}, speed=2.0, outcome=outcome,
                          demonstrator="test")  # fmt: skip

    t = expert_transitions([demo("target"), demo("timeout"), demo("collision")], lambda phi: phi / 100)
    np.testing.assert_array_equal(t.terminal, [False, True, False, False, False, True])
    np.testing.assert_allclose(t.next_phi[0], np.arange(16, 32) / 100)  # s' is the next state, scaled
    with pytest.raises(ValueError, match="nothing to imitate"):
        expert_transitions([demo("timeout", 0)], lambda phi: phi)
    # with an absorbing state, one pair (s_a, ., s_a) after each terminal demonstration
    demos = [demo("target"), demo("timeout"), demo("collision")]
    t = expert_transitions(demos, lambda phi: phi, absorbing=True)
    np.testing.assert_array_equal(t.absorbing, [False, False, True, False, False, False, False, True])
    np.testing.assert_array_equal(t.terminal, [False, True, True, False, False, False, True, True])


def test_the_wrapper_replaces_the_task_reward_and_keeps_transitions():
    pytest.importorskip("stable_baselines3")  # the optional extra nirl-mj[gym]
    from stable_baselines3.common.vec_env import DummyVecEnv

    from nirl_mj.data.transitions import Transitions
    from nirl_mj.experiments.adversarial import AdversarialReward, reward_wrapper

    demos = Transitions.pairs(np.zeros((1, 16)), np.zeros(1, int), np.zeros((1, 16)), np.zeros(1, bool))
    reward = AdversarialReward("gail", 0.99, demos, seed=0)
    constant_heads(reward.discriminator, net=[0.0] * 6)  # D = 1/2: reward ln 2 everywhere
    venv = reward_wrapper(DummyVecEnv([Corridor]), reward)
    first = venv.reset()
    rewards = []
    for action in (3, 4):
        venv.step_async(np.array([action]))
        _, r, done, _ = venv.step_wait()
        rewards.append(float(r[0]))
    np.testing.assert_allclose(rewards, [math.log(2)] * 2, rtol=1e-6)  # never the task's 100
    kept = venv.take()
    np.testing.assert_array_equal(kept.action, [3, 4])
    np.testing.assert_array_equal(kept.phi[0], first[0])
    assert kept.next_phi[1][0] == 2.0  # the terminal observation, not the next episode's first
    np.testing.assert_array_equal(kept.terminal, [False, True])
    assert len(venv.take()) == 0  # taken once


def test_with_an_absorbing_state_a_terminal_step_earns_the_stay_there():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from nirl_mj.data.transitions import Transitions
    from nirl_mj.experiments.adversarial import AdversarialReward, reward_wrapper

    demos = Transitions.pairs(np.zeros((1, 16)), np.zeros(1, int), np.zeros((1, 16)), np.zeros(1, bool))
    reward = AdversarialReward("gail-absorbing", 0.75, demos, seed=0)
    constant_heads(reward.discriminator, net=[0.0] * 6)  # D = 1/2: reward ln 2 in every real state
    at_absorbing(reward.discriminator.net, [math.log(3.0)] * 6)  # in s_a: -ln(1 - 3/4) = ln 4
    venv = reward_wrapper(DummyVecEnv([Corridor]), reward)
    venv.reset()
    rewards = []
    for action in (3, 4):
        venv.step_async(np.array([action]))
        rewards.append(float(venv.step_wait()[1][0]))
    # the terminal step: its own ln 2, then ln 4 at every later step in s_a: 0.75 / 0.25 * ln 4
    np.testing.assert_allclose(rewards, [math.log(2), math.log(2) + 3 * math.log(4)], rtol=1e-6)
    kept = venv.take()
    np.testing.assert_array_equal(kept.absorbing, [False, False, True])  # s_a joins the learner's pairs
    with pytest.raises(ValueError, match="accepted: gail, airl, gail-absorbing"):
        AdversarialReward("airl-lite", 0.75, demos, seed=0)


def test_with_norm_each_reward_is_normalised_by_the_rewards_so_far_itself_included():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from nirl_mj.data.transitions import Transitions
    from nirl_mj.experiments.adversarial import AdversarialReward, reward_wrapper

    demos = Transitions.pairs(np.zeros((1, 16)), np.zeros(1, int), np.zeros((1, 16)), np.zeros(1, bool))
    reward = AdversarialReward("gail-norm", 0.99, demos, seed=0)
    # GAIL's reward softplus(l): ln 2 for l = 0 (action 3), ln(1 + e) for l = 1 (action 4)
    constant_heads(reward.discriminator, net=[0.0, 0.0, 0.0, 0.0, 1.0, 0.0])
    venv = reward_wrapper(DummyVecEnv([Corridor]), reward)
    venv.reset()
    rewards = []
    for action in (3, 4, 3):  # the corridor ends after two steps; the third starts a new episode
        venv.step_async(np.array([action]))
        rewards.append(float(venv.step_wait()[1][0]))
    a, b = math.log(2), math.log(1 + math.e)
    eps = reward.norm.eps
    # each against the mean and variance of the rewards so far, itself included
    second = (b - (a + b) / 2) / math.sqrt(((b - a) / 2) ** 2 + eps)
    mean = (2 * a + b) / 3
    third = (a - mean) / math.sqrt((2 * (a - mean) ** 2 + (b - mean) ** 2) / 3 + eps)
    np.testing.assert_allclose(rewards, [0.0, second, third], rtol=1e-5, atol=1e-7)


def test_a_norm_run_resumes_with_the_statistics_of_every_reward_paid(tmp_path):
    pytest.importorskip("stable_baselines3")
    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.experiments.adversarial import DISCRIMINATOR_FILE, NORM_KEY
    from nirl_mj.experiments.demos import ExpertConfig, collect
    from nirl_mj.experiments.rl import train_rl

    demos = tmp_path / "demos.npz"
    save_dataset(demos, collect(OPEN, ExpertConfig("rule"), episodes=2, seed=0))
    for steps, resume in ((1024, False), (2048, True)):
        record = train_rl(tmp_path / "run", OPEN, "airl-norm", steps, seed=0, demos=demos, resume=resume)
        with np.load(tmp_path / "run" / DISCRIMINATOR_FILE) as saved:
            count = int(saved[NORM_KEY][2])
        assert count == record["steps_done"] >= steps  # one reward per decision, across the resume


# AIRL-absorbing learns through the same code as AIRL; its absorbing state is pinned by hand above and
# read back from saved weights in test_a_saved_discriminator_loads_with_its_absorbing_state_or_without.
# The test pins training seed 0. Runs this short vary with the seed (measured 2026-11-29, progress over
# 6 arenas, the random policy's 0.30): seed 0 GAIL 0.80, AIRL 0.68; seed 1 GAIL 0.42, AIRL 0.77; at
# 4,096 decisions 0.29-0.51. So a change of seed or budget here is a change of what the test shows.
@pytest.mark.parametrize("algo", ["gail", "airl"])
def test_a_short_adversarial_run_beats_the_uniform_random_policy(tmp_path, algo):
    pytest.importorskip("stable_baselines3")
    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.experiments.adversarial import DISCRIMINATOR_FILE, load_discriminator
    from nirl_mj.experiments.demos import ExpertConfig, collect
    from nirl_mj.experiments.evaluation import evaluate
    from nirl_mj.experiments.rl import load_rl_policy, train_rl
    from nirl_mj.experiments.seeds import domain_seeds
    from nirl_mj.sim.task import make_env

    task = OPEN
    demos = tmp_path / "demos.npz"
    save_dataset(demos, collect(task, ExpertConfig("rule"), episodes=4, seed=0))
    record = train_rl(tmp_path / "run", task, algo, STEPS, seed=0, demos=demos)
    assert (tmp_path / "run" / DISCRIMINATOR_FILE).is_file() and record["demos"] == str(demos)
    policy, _ = load_rl_policy(tmp_path / "run")
    tests = domain_seeds("test", 0, 6)
    _, learned = evaluate(make_env(task), policy, tests)
    rng = np.random.default_rng(0)
    _, random = evaluate(make_env(task), lambda phi: int(rng.integers(6)), tests)
    assert progress(learned) > progress(random) + 0.25
    if algo == "airl":  # the learned reward g(s, .) reads back, and a subject shows it like r_theta
        from nirl_mj.experiments.subjects import run_subject

        disc = load_discriminator(tmp_path / "run", "airl", 0.99)
        g = disc.reward(np.zeros((2, 16)))
        reward = run_subject(tmp_path / "run").reward()
        phi = np.zeros((2, 16), np.float32)
        np.testing.assert_allclose(reward.rewards_all_actions(phi), g, rtol=1e-6)
        np.testing.assert_allclose(reward.reward(phi, np.array([1, 4])), g[[0, 1], [1, 4]], rtol=1e-6)


STEPS = 8192
