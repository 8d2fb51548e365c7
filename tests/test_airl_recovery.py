"""AIRL against a problem whose answer is known (issue 31): a 4 x 4 grid with a known state-only
reward, which AIRL must recover up to shaping.

**The problem.** 16 cells, one-hot as the discriminator's 16 inputs (``N_INPUTS``); actions 0..3 of
the discriminator's six move up, down, left, right (into a wall: stay). Each step in cell s pays
r(s) (``REWARD``: -1 to -2.9, the goal 5); from the goal (cell 15) any action ends the episode (a
terminal transition). gamma = 0.9. The expert is max-ent (soft-)optimal for r, computed exactly by
soft value iteration, as AIRL assumes (Fu, Luo & Levine 2018); every episode starts in a uniformly
drawn non-goal cell and is cut (truncated, not terminal) after 25 steps. The reward was chosen so
that, from every cell, the expert's best next cell beats every other next cell by at least 0.58 in
soft Q, and its greedy path reaches the goal: the optimal policy is unique up to moves that lead to
the same cell.

**What is exercised.** ``nirl_mj.experiments.adversarial.AdversarialReward`` as PPO drives it,
minus PPO: its ``update`` (4 epochs of 256-pair minibatches of the learner's transitions, each
against as many pairs drawn from the demonstrations, ``discriminator_loss``, Adam at 3e-4: the
project's ``SETTINGS``, unchanged), its ``logits`` (AIRL's f - ln pi(a | s), with ln pi read through
``policy.evaluate_actions`` as from an SB3 policy; here a tabular policy offers that method) and its
``rewards`` (the policy's reward l = f - ln pi), over ``nirl_mj.learn.adversarial.AirlDiscriminator``
(f = g + gamma h(s') - h(s), h(s') = 0 after a terminal transition) and its ``reward`` (g). Not
exercised: PPO, the simulator, the reward wrapper and callback, and the absorbing, -norm, -gp and
-d2 options. The policy step is exact instead of PPO's: each round, the learner's policy becomes the
soft-optimal policy of the reward f(s, a, s') = l + ln pi (soft value iteration), the maximiser of
AIRL's policy objective E sum gamma^t (f - ln pi). Rounds of 64 learner episodes against 400 expert
episodes (2068 pairs): 200 for ``airl-state``, 100 for ``airl``.

**What AIRL guarantees, and what was seen** (seed 0; 2-core CPU shared with another job, one torch
thread: about 8 s for ``airl-state``, 4 s for ``airl``):

- ``airl-state`` (Fu et al.'s state-only g(s)): with deterministic dynamics, g = r and h = V (the
  expert's soft value) up to one constant k of shaping, gamma k - k, k after the terminal step being
  0 (h = 0 there): g(s) = r(s) + (1 - gamma) k off the goal, g(goal) = r(goal) + k, h = V + k.
  Seen: the policy soft-optimal for g alone (no h) moves to the expert's best next cell in all 15
  cells; its mean KL from the expert's policy is 0.007 (0.066 for the reward "-2 everywhere, 5 at
  the goal", which also picks the wrong cell in 2 of 15; 1.8 for the untrained g); g correlates
  with r at 0.92 over the 15 non-goal cells (0.97 with the goal); the fit of g gives k = -2.96
  (g(goal) = 2.0) with 0.23 RMS per cell left (r spans 1.9 off the goal); h - V = -2.84 +- 0.21
  (std over the 16 cells; V spans 9.6), the same k. Seeds 1-4 gave KL 0.005-0.009, correlation
  0.87-0.97, residual 0.16-0.27.
- ``airl`` (the project's default, g(s, a)): with deterministic dynamics s' is a function of
  (s, a), so g(s, a) can absorb any shaping gamma Phi(s') - Phi(s): AIRL identifies g only up to
  it, and the policy soft-optimal for g(s, a) is what it guarantees. Seen: that policy moves to the
  expert's best next cell in all 15 cells, KL 0.022 (seeds 1-4: 0.016-0.031). The action best by
  g(s, .) in each cell, which is what g(s, a) in a reward map shows, is not guaranteed and is not
  asserted: it missed the expert's move in one cell of 15 for seeds 0-3 (cells 10, 0, 0, 2).
- The same checks fail for the untrained discriminator's g, for the recovered g with its sign
  flipped and for the goal-only reward.
"""

import numpy as np
import pytest
import torch

from nirl_mj.data.transitions import Transitions
from nirl_mj.experiments.adversarial import AdversarialReward

SIDE, GAMMA, HORIZON = 4, 0.9, 25
N_STATES, N_MOVES, GOAL = SIDE * SIDE, 4, SIDE * SIDE - 1
REWARD = np.array(
    [-2.8, -1.8, -2.4, -1.6,
     -2.4, -1.4, -1.8, -2.3,
     -1.7, -2.6, -1.0, -2.8,
     -2.9, -2.1, -2.0, 5.0]
)  # fmt: skip
ONE_HOT = np.eye(N_STATES, dtype=np.float32)
NON_GOAL = np.arange(N_STATES) != GOAL


def successors() -> np.ndarray:
    """The next cell (16, 4) of each cell and move (up, down, left, right; a wall: stay)."""
    nxt = np.zeros((N_STATES, N_MOVES), int)
    for s in range(N_STATES):
        row, col = divmod(s, SIDE)
        for a, (dr, dc) in enumerate([(-1, 0), (1, 0), (0, -1), (0, 1)]):
            nxt[s, a] = min(max(row + dr, 0), SIDE - 1) * SIDE + min(max(col + dc, 0), SIDE - 1)
    return nxt


NEXT = successors()


def soft_value_iteration(reward: np.ndarray, sweeps: int = 400) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Q (16, 4), V (16,), pi (16, 4)) soft-optimal at temperature 1 for a reward (16,) paid in s
    or (16, 4) paid for (s, a); the goal's step is terminal (no future)."""
    r = np.broadcast_to(reward[:, None] if reward.ndim == 1 else reward, (N_STATES, N_MOVES))
    v = np.zeros(N_STATES)
    for _ in range(sweeps):  # gamma^400 < 1e-18
        q = r + GAMMA * v[NEXT] * NON_GOAL[:, None]
        top = q.max(axis=1)
        v = top + np.log(np.exp(q - top[:, None]).sum(axis=1))
    return q, v, np.exp(q - v[:, None])


def best_next_cell(q: np.ndarray) -> np.ndarray:
    """The cell (16,) that the action best by q leads to (moves into the same cell tie exactly)."""
    return NEXT[np.arange(N_STATES), q.argmax(axis=1)]


EXPERT_Q, EXPERT_V, EXPERT_PI = soft_value_iteration(REWARD)


def sample(pi: np.ndarray, episodes: int, rng: np.random.Generator) -> Transitions:
    """Episodes of ``pi`` from uniform non-goal cells, cut after HORIZON steps (a truncation)."""
    cells, moves, after, ends = [], [], [], []
    for _ in range(episodes):
        s = int(rng.integers(0, GOAL))
        for _ in range(HORIZON):
            a = int(rng.choice(N_MOVES, p=pi[s]))
            cells.append(s)
            moves.append(a)
            ends.append(s == GOAL)
            after.append(s if s == GOAL else NEXT[s, a])  # never read after the terminal step
            if s == GOAL:
                break
            s = after[-1]
    return Transitions.pairs(ONE_HOT[cells], np.array(moves), ONE_HOT[after], np.array(ends))


class TabularPolicy:
    """ln pi(a | s) through SB3's ``ActorCriticPolicy.evaluate_actions`` interface, which
    ``experiments.adversarial.log_pi`` calls."""

    def __init__(self, pi: np.ndarray) -> None:
        self.log_pi = torch.as_tensor(np.log(pi), dtype=torch.float32)

    def evaluate_actions(self, x: torch.Tensor, actions: torch.Tensor):
        return None, self.log_pi[x.argmax(dim=1), actions], None


EVERY_PAIR = Transitions.pairs(
    ONE_HOT[np.repeat(np.arange(N_STATES), N_MOVES)],
    np.tile(np.arange(N_MOVES), N_STATES),
    ONE_HOT[NEXT.reshape(-1)],
    np.repeat(~NON_GOAL, N_MOVES),
)


def train(algo: str, rounds: int = 100, episodes: int = 64, seed: int = 0) -> AdversarialReward:
    """AIRL with an exact policy step: discriminator updates on the current policy's episodes, then
    the soft-optimal policy of f(s, a, s') = l + ln pi."""
    demos = sample(EXPERT_PI, 400, np.random.default_rng(seed + 1))
    reward = AdversarialReward(algo, GAMMA, demos, seed=seed)
    rng = np.random.default_rng(seed + 2)
    pi = np.full((N_STATES, N_MOVES), 1.0 / N_MOVES)
    for _ in range(rounds):
        reward.policy = TabularPolicy(pi)
        reward.update(sample(pi, episodes, rng))
        f = reward.rewards(EVERY_PAIR).reshape(N_STATES, N_MOVES) + np.log(pi)
        pi = soft_value_iteration(f)[2]
    return reward


def g_of_states(reward: AdversarialReward) -> np.ndarray:
    """The recovered reward g (16,) of a state-only AIRL (every action's column is g(s))."""
    return reward.discriminator.reward(ONE_HOT)[:, 0].astype(np.float64)


def mean_kl_from_expert(pi: np.ndarray) -> float:
    """Mean over non-goal cells of KL(expert's pi || pi)."""
    return float((EXPERT_PI * np.log(EXPERT_PI / pi)).sum(axis=1)[NON_GOAL].mean())


def shaping_fit(g: np.ndarray) -> tuple[float, float]:
    """(k, RMS residual) of g = r + b k, b = 1 - gamma off the goal and 1 at it: the only shaping
    gamma k - k (k after the terminal step: 0) that a state-only g can absorb."""
    b = np.where(NON_GOAL, 1.0 - GAMMA, 1.0)
    k = float(b @ (g - REWARD) / (b @ b))
    return k, float(np.sqrt(np.mean((g - REWARD - b * k) ** 2)))


def recovers(g: np.ndarray) -> bool:
    """The checks of a recovered state-only reward: its soft-optimal policy (g alone, no h) moves
    to the expert's best next cell everywhere and is close to the expert's policy, and g ranks the
    non-goal cells as r does."""
    q, _, pi = soft_value_iteration(g)
    same_moves = np.array_equal(best_next_cell(q)[NON_GOAL], best_next_cell(EXPERT_Q)[NON_GOAL])
    correlation = np.corrcoef(g[NON_GOAL], REWARD[NON_GOAL])[0, 1]
    return bool(same_moves and mean_kl_from_expert(pi) < 0.03 and correlation > 0.8)


@pytest.fixture(scope="module")
def one_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def state_only(one_thread) -> AdversarialReward:
    return train("airl-state", rounds=200)


def test_the_problem_has_a_unique_answer():
    best = best_next_cell(EXPERT_Q)
    gaps = [EXPERT_Q[s].max() - EXPERT_Q[s][NEXT[s] != best[s]].max() for s in range(GOAL)]
    assert min(gaps) > 0.5
    for start in range(GOAL):  # the greedy path reaches the goal from every cell
        s, steps = start, 0
        while s != GOAL and steps < N_STATES:
            s, steps = best[s], steps + 1
        assert s == GOAL


def test_state_only_airl_recovers_the_reward_up_to_shaping(state_only):
    g = g_of_states(state_only)
    q, _, pi = soft_value_iteration(g)
    np.testing.assert_array_equal(best_next_cell(q)[NON_GOAL], best_next_cell(EXPERT_Q)[NON_GOAL])
    assert mean_kl_from_expert(pi) < 0.03  # seen 0.007
    assert np.corrcoef(g[NON_GOAL], REWARD[NON_GOAL])[0, 1] > 0.8  # seen 0.92
    k, residual = shaping_fit(g)
    assert residual < 0.4  # seen 0.23; r spans 1.9 off the goal
    assert recovers(g)
    # h is the expert's soft value V up to the same constant k
    with torch.no_grad():
        h = state_only.discriminator.h(torch.as_tensor(ONE_HOT))[:, 0].numpy()
    gap = h - EXPERT_V
    assert gap.std() < 0.4 and abs(gap.mean() - k) < 0.5  # seen -2.84 +- 0.21, k = -2.96; V spans 9.6


def test_the_checks_fail_without_training_or_with_the_sign_flipped(state_only):
    assert recovers(REWARD)
    assert not recovers(-g_of_states(state_only))
    untrained = AdversarialReward("airl-state", GAMMA, sample(EXPERT_PI, 1, np.random.default_rng(0)), seed=0)
    assert not recovers(g_of_states(untrained))
    goal_only = np.where(NON_GOAL, -2.0, 5.0) + 1e-3 * np.arange(N_STATES)  # ties broken
    assert not recovers(goal_only)


def test_state_action_airl_recovers_the_experts_policy(one_thread):
    g = train("airl").discriminator.reward(ONE_HOT)[:, :N_MOVES].astype(np.float64)
    q, _, pi = soft_value_iteration(g)
    np.testing.assert_array_equal(best_next_cell(q)[NON_GOAL], best_next_cell(EXPERT_Q)[NON_GOAL])
    assert mean_kl_from_expert(pi) < 0.05  # seen 0.022; the goal-only reward: 0.066
