"""GAIL and AIRL with Stable-Baselines3 PPO as the policy learner (``nirl-mj rl --algo gail|airl``).

The discriminators are ``nirl_mj.learn.adversarial``'s. Training alternates as in Ho & Ermon's
algorithm 1 and in the imitation library's ``AdversarialTrainer``: PPO collects a rollout of
``n_steps`` decisions (``rl.SETTINGS["ppo"]``) in which every reward is the discriminator's
(:class:`DiscriminatorReward`; the environment's own reward is dropped, never read), then the
discriminator takes ``epochs`` passes of minibatch Adam steps on that rollout against as many
pairs drawn from the demonstrations (:class:`DiscriminatorTraining`), then PPO updates its policy
on the rollout. The observation is phi(s) scaled to [0, 1], as for the RL reference, or with
``settings.inputs = "bearing"`` NIRL's bearing code (``experiments.observation_code``); the
discriminator reads the same observation, and the demonstrations, the experiment's 30, go through
the same code.

``gail-absorbing`` and ``airl-absorbing`` add the absorbing state of Kostrikov et al. (2019; see
``nirl_mj.learn.adversarial``): every terminal episode, the expert's and the learner's, adds one pair
(s_a, ., s_a) to the discriminator's data, and a terminal transition's reward gains the discounted
stay in s_a, gamma / (1 - gamma) times the policy's reward there. A timeout is a truncation: no s_a.
``gail-norm`` and ``airl-norm`` hand PPO the same rewards normalised by the running mean and
variance of all the rewards handed out so far (``nirl_mj.learn.running_norm``): the imitation
library's default for AIRL (its scripts wrap the reward net in ``NormalizedRewardNet(RunningNorm)``;
its GAIL's policy reward bypasses the normaliser, so ``gail-norm`` goes beyond the library).
``gail-gp`` and ``airl-gp`` add a gradient penalty on the expert's pairs to the discriminator's loss
(R1, ``nirl_mj.learn.adversarial.gradient_penalty``), weight 10; ``-gp1`` and ``-gp0_1`` weigh it
1 and 0.1. ``airl-state`` learns a state-only g(s), Fu et al.'s disentangled reward.
``gail-d2`` and ``airl-d2`` take fewer discriminator steps: two full-batch Adam steps per rollout (all
its pairs against as many demonstrated ones) instead of ``epochs`` passes of minibatches, the
imitation library's default number of updates (``AdversarialTrainer(n_disc_updates_per_round=2)``).

The discriminator's weights are saved with every checkpoint (``discriminator.npz``, atomically) and
restored by a resume; AIRL's reward g(s, a) can be read back with :func:`load_discriminator`.
Needs the optional extra ``nirl-mj[gym]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from nirl_mj.data.atomic import write_npz
from nirl_mj.data.rundir import DISCRIMINATOR_FILE, RunDir, RunError
from nirl_mj.data.trajectory import Trajectory
from nirl_mj.data.transitions import Transitions
from nirl_mj.experiments.observation_code import observation_code
from nirl_mj.learn.adversarial import (
    N_INPUTS,
    PENALTY_WEIGHT,
    discriminator_loss,
    gradient_penalty,
    make_discriminator,
)
from nirl_mj.learn.running_norm import RunningNorm

ABSORBING = "absorbing"  # the suffix of an algorithm with an absorbing state
NORMALISED = "norm"  # the suffix of an algorithm whose policy reward is normalised as it runs
PENALTIES = {"gp": 10.0, "gp1": 1.0, "gp0_1": 0.1}
"""The suffixes of an algorithm whose discriminator has a gradient penalty, and its weight lambda."""
STATE_ONLY = "state"  # the suffix of AIRL with a state-only g(s)
FULL_BATCH_STEPS = {"d2": 2}
"""The suffixes of an algorithm whose discriminator takes that many full-batch steps per rollout."""
NORM_KEY = "reward_norm"  # the RunningNorm's state in discriminator.npz
KINDS = ("gail", "airl")
OPTIONS = ("", ABSORBING, NORMALISED, *PENALTIES, STATE_ONLY, *FULL_BATCH_STEPS)
SETTINGS = {"epochs": 4, "batch_size": 256, "learning_rate": 3e-4}
"""The discriminator's training per PPO rollout (recorded in the run)."""


def expert_transitions(demos: Sequence[Trajectory], scale, absorbing: bool = False) -> Transitions:
    """Every demonstrated (s, a, s') with phi coded by ``scale`` (phi (N, 16) -> the policy's
    observation (N, width)), terminal where the demonstration
    ended in a terminal state (as the environment and NIRL's loop end them; a timeout is a
    truncation). With ``absorbing``, each terminal demonstration adds one pair (s_a, ., s_a)."""
    rows = Transitions.of(demos, absorbing=absorbing)
    if not len(rows):
        raise ValueError("the demonstrations hold no state-action pair: there is nothing to imitate")
    return rows.mapped(scale)


def _tensors(t: Transitions) -> tuple[torch.Tensor, ...]:
    as_tensor = torch.as_tensor
    return (as_tensor(t.phi, dtype=torch.float32), as_tensor(t.action, dtype=torch.long),
            as_tensor(t.next_phi, dtype=torch.float32), as_tensor(t.terminal, dtype=torch.bool),
            as_tensor(t.absorbing, dtype=torch.bool))  # fmt: skip


@dataclass(frozen=True)
class Variant:
    """An adversarial algorithm: its discriminator ("gail" or "airl") and its one option."""

    kind: str
    absorbing: bool  # "-absorbing": Kostrikov et al.'s absorbing state
    normalised: bool  # "-norm": the policy's reward through a RunningNorm (learn/running_norm.py)
    penalty: float = 0.0  # "-gp", "-gp1", "-gp0_1": lambda of an R1 gradient penalty on the expert's pairs
    state_only: bool = False  # "-state" (AIRL only): g(s), Fu et al.'s disentangled reward
    full_batch_steps: int = 0  # "-d2": Adam steps per rollout on all its pairs; 0: SETTINGS' minibatch epochs

    def settings(self) -> dict:
        """The discriminator's training per PPO rollout, as a run records it."""
        if self.full_batch_steps:
            return {"full_batch_steps": self.full_batch_steps, "learning_rate": SETTINGS["learning_rate"]}
        return dict(SETTINGS)

    def passes(self, pairs: int) -> tuple[int, int]:
        """(passes over a rollout of ``pairs`` learner pairs, minibatch size) for the discriminator."""
        if self.full_batch_steps:
            return self.full_batch_steps, max(pairs, 1)
        return SETTINGS["epochs"], SETTINGS["batch_size"]


def algorithms() -> list[str]:
    """Every adversarial algorithm's name ("gail", "airl", then each with each option it takes;
    "-state" is AIRL's only); ``experiments.rl.ADVERSARIAL`` lists the same without importing torch
    (a test checks it)."""
    return [kind + (f"-{option}" if option else "") for option in OPTIONS for kind in KINDS
            if not (option == STATE_ONLY and kind != "airl")]  # fmt: skip


def variant_of(algo: str) -> Variant:
    """Parses an adversarial ``algo``: "airl-absorbing" -> Variant("airl", absorbing=True, ...)."""
    if algo not in algorithms():
        raise ValueError(f"unknown adversarial algorithm {algo!r}: accepted: {', '.join(algorithms())}")
    kind, _, option = algo.partition("-")
    return Variant(
        kind,
        absorbing=option == ABSORBING,
        normalised=option == NORMALISED,
        penalty=PENALTIES.get(option, 0.0),
        state_only=option == STATE_ONLY,
        full_batch_steps=FULL_BATCH_STEPS.get(option, 0),
    )


def log_pi(policy: Any, x: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
    """ln pi(a | s) (N,) under an SB3 actor-critic policy (0 without one)."""
    if policy is None:
        return torch.zeros(len(actions))
    with torch.no_grad():
        _, log_prob, _ = policy.evaluate_actions(x, actions)
    return log_prob


class AdversarialReward:
    """The discriminator, its optimiser and the expert's pairs; rewards and updates.
    ``algo``: "gail" or "airl", alone or with one option (:func:`variant_of`)."""

    def __init__(self, algo: str, gamma: float, demos: Transitions, seed: int) -> None:
        variant = variant_of(algo)
        self.absorbing, self.penalty_weight = variant.absorbing, variant.penalty
        self.variant = variant
        self.norm = RunningNorm() if variant.normalised else None
        self.gamma = float(gamma)
        self.width = int(demos.phi.shape[1])  # the observation's: the code's width
        self.discriminator = make_discriminator(
            variant.kind, gamma, seed, self.absorbing, variant.state_only, n_inputs=self.width
        )
        self.optimiser = torch.optim.Adam(self.discriminator.parameters(), lr=SETTINGS["learning_rate"])
        self.demos = demos
        self.rng = np.random.default_rng(seed)
        self.policy: Any = None  # the PPO policy, for AIRL's ln pi(a | s)

    def logits(self, batch: Transitions) -> torch.Tensor:
        """The discriminator's logits (N,); ln pi(a | s) is computed for AIRL only (GAIL ignores it)."""
        x, a, x_next, terminal, absorbing = _tensors(batch)
        policy = self.policy if self.discriminator.kind == "airl" else None
        return self.discriminator.logits(x, a, x_next, terminal, log_pi(policy, x, a), absorbing)

    def rewards(self, batch: Transitions) -> np.ndarray:
        """The policy's rewards (N,) for the learner's transitions; with an absorbing state, a
        terminal one gains the discounted stay in s_a, gamma / (1 - gamma) times its reward there.
        With "-norm" they are normalised by all the rewards handed out so far, themselves included."""
        with torch.no_grad():
            rewards = self.discriminator.policy_reward(self.logits(batch)).numpy().astype(np.float32)
            if self.absorbing and batch.terminal.any():
                at = self.logits(Transitions.absorbing_pairs(1, self.width))
                stay = self.discriminator.policy_reward(at)
                tail = self.gamma / (1.0 - self.gamma) * float(stay[0])
                rewards = rewards + np.float32(tail) * batch.terminal
        if self.norm is not None:
            rewards = self.norm(rewards)
        return rewards.astype(np.float32)

    def penalty(self, expert: Transitions) -> torch.Tensor:
        """The gradient penalty on the expert's pairs. AIRL's ln pi(a | s) is left out (zeros): it
        depends on s, but through the policy, which the discriminator's step does not move."""
        x, a, x_next, terminal, absorbing = _tensors(expert)
        zeros = torch.zeros(len(a))
        logits = self.discriminator.logits
        weight = self.penalty_weight or PENALTY_WEIGHT  # an unpenalised run's penalty is only ever read
        return gradient_penalty(
            lambda x, x_next: logits(x, a, x_next, terminal, zeros, absorbing), x, x_next, weight
        )

    def update(self, learner: Transitions) -> float:
        """Passes over the learner's pairs (``epochs`` of minibatches, or with "-d2" two of the whole
        rollout), each minibatch against as many expert pairs; returns the last minibatch's loss
        (with "-gp", the penalty included)."""
        loss_value = float("nan")
        passes, size = self.variant.passes(len(learner))
        for _ in range(passes):
            order = self.rng.permutation(len(learner))
            for start in range(0, len(order), size):
                mine = learner.take(order[start : start + size])
                theirs = self.demos.take(self.rng.integers(0, len(self.demos), len(mine)))
                loss = discriminator_loss(self.logits(theirs), self.logits(mine))
                if self.penalty_weight:
                    loss = loss + self.penalty(theirs)
                self.optimiser.zero_grad()
                loss.backward()
                self.optimiser.step()
                loss_value = float(loss.detach())
        return loss_value

    def state(self) -> dict[str, np.ndarray]:
        """The discriminator's weights, and the reward normaliser's statistics with "-norm"."""
        arrays = {k: v.detach().numpy().copy() for k, v in self.discriminator.state_dict().items()}
        if self.norm is not None:
            arrays[NORM_KEY] = self.norm.state()
        return arrays

    def load_state(self, arrays: dict[str, np.ndarray]) -> None:
        _load_weights(self.discriminator, arrays)
        if self.norm is not None:
            if NORM_KEY not in arrays:
                raise RunError(f"the saved discriminator has no {NORM_KEY}: it was not trained with -norm")
            self.norm.load_state(arrays[NORM_KEY])


def _load_weights(discriminator: torch.nn.Module, arrays: dict[str, np.ndarray]) -> None:
    weights = {k: torch.as_tensor(v) for k, v in arrays.items() if k != NORM_KEY}
    discriminator.load_state_dict(weights)


def save_discriminator(run: RunDir, reward: AdversarialReward) -> None:
    write_npz(run.file(DISCRIMINATOR_FILE), reward.state())


def read_discriminator(run: RunDir) -> dict[str, np.ndarray]:
    """The discriminator's weights saved in ``run`` (a clear error if there are none yet)."""
    path = run.file(DISCRIMINATOR_FILE)
    if not path.is_file():
        raise RunError(f"{run} has no {DISCRIMINATOR_FILE}: its training has not reached a checkpoint")
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def load_discriminator(run_dir, kind: str, gamma: float, n_inputs: int | None = None) -> Any:
    """The trained discriminator of a GAIL or AIRL run (AIRL's ``reward(x)`` is its g(s, .)), with
    an absorbing state or a state-only g(s) if it was trained with one. In a run directory its
    inputs (the run's observation code, ``experiments.observation_code``) and absorbing state are
    the run record's (``kind`` and a given ``n_inputs`` must agree with it); a bare discriminator
    file reads ``n_inputs`` (default 16) coded values, one more being an absorbing state."""
    run = RunDir(run_dir)
    arrays = read_discriminator(run)
    if run.is_run:
        record = run.read_record()
        width = observation_code(record.get("config", {}))[1].shape[0]
        variant = variant_of(record["algo"])
        if variant.kind != kind or n_inputs not in (None, width):
            raise RunError(f"{run_dir} is a {record['algo']} run on {width} inputs, not a {kind} "
                           f"discriminator on {n_inputs or width}")  # fmt: skip
        absorbing = variant.absorbing
    first = arrays["net.0.weight" if kind == "gail" else "g.0.weight"]  # (hidden, inputs)
    state_only = kind == "airl" and arrays["g.4.weight"].shape[0] == 1  # (outputs, hidden)
    if not run.is_run:
        width = N_INPUTS if n_inputs is None else n_inputs
        absorbing = first.shape[1] == width + 1
    if first.shape[1] != width + absorbing:
        raise RunError(f"{run_dir}'s discriminator reads {first.shape[1]} inputs, not {width}"
                       + (" and an absorbing state" if absorbing else "")
                       + (" as its run records" if run.is_run else ""))  # fmt: skip
    discriminator = make_discriminator(
        kind, gamma, absorbing=absorbing, state_only=state_only, n_inputs=width
    )
    _load_weights(discriminator, arrays)
    return discriminator


class AirlReward:
    """An AIRL run's learned reward g(s, a) on phi(s), with RewardModel's reading methods (so reward
    maps and Rerun recordings show it as they show r_theta). Units: nats, per decision."""

    def __init__(self, run_dir, gamma: float) -> None:
        """phi(s) goes through the run's own observation code (``experiments.observation_code``)."""
        self.discriminator = load_discriminator(run_dir, "airl", gamma)
        self.scale = observation_code(RunDir(run_dir).read_record().get("config", {}))[0]

    def rewards_all_actions(self, phi: np.ndarray) -> np.ndarray:
        """g(s, a) for every action: phi (N, 16) -> (N, 6)."""
        return self.discriminator.reward(self.scale(np.atleast_2d(phi))).astype(np.float64)

    def reward(self, phi: np.ndarray, action: int | np.ndarray) -> np.ndarray:
        """g(s, a) for phi (..., 16) and actions (...) -> (...)."""
        phi = np.atleast_2d(phi)
        flat = phi.reshape(-1, phi.shape[-1])
        actions = np.broadcast_to(np.asarray(action), phi.shape[:-1]).ravel().astype(int)
        return self.rewards_all_actions(flat)[np.arange(len(flat)), actions]


def reward_wrapper(venv, reward: AdversarialReward):
    """``venv`` with every reward replaced by the discriminator's; it also keeps the transitions
    since the last :meth:`take` for the discriminator's update."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class DiscriminatorReward(VecEnvWrapper):
        def __init__(self) -> None:
            super().__init__(venv)
            self.last_obs: np.ndarray | None = None
            self.kept: list[Transitions] = []

        def reset(self):
            self.last_obs = self.venv.reset()
            return self.last_obs

        def step_async(self, actions) -> None:
            self.actions = np.asarray(actions)
            self.venv.step_async(actions)

        def step_wait(self):
            obs, _, dones, infos = self.venv.step_wait()  # the task's reward is dropped here
            x_next = obs.copy()
            terminal = np.zeros(len(dones), bool)
            for i, (done, info) in enumerate(zip(dones, infos, strict=True)):
                if done:
                    x_next[i] = info["terminal_observation"]
                    terminal[i] = not info.get("TimeLimit.truncated", False)
            actions = self.actions.reshape(-1).astype(np.int64)
            batch = Transitions.pairs(self.last_obs.copy(), actions, x_next, terminal)
            self.kept.append(batch)
            if reward.absorbing and terminal.any():
                self.kept.append(Transitions.absorbing_pairs(int(terminal.sum()), reward.width))
            self.last_obs = obs
            return obs, reward.rewards(batch), dones, infos

        def take(self) -> Transitions:
            kept, self.kept = self.kept, []
            return Transitions.concat(kept) if kept else Transitions.empty(reward.width)

    return DiscriminatorReward()


def training_callback(wrapper, reward: AdversarialReward):
    """An SB3 callback: after each rollout the discriminator learns on it (before PPO's update)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class DiscriminatorTraining(BaseCallback):
        def _on_step(self) -> bool:
            return True

        def _on_rollout_end(self) -> None:
            reward.policy = self.model.policy
            loss = reward.update(wrapper.take())
            self.logger.record("discriminator/loss", loss)

    return DiscriminatorTraining()
