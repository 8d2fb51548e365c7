"""The shared IRL loop: NIRL's Algorithm 1 in the order it runs; methods and variants are configurations.

Each iteration ("episode" in the paper):

1. run the current policy (Boltzmann, eq. 8) for ``trajectories_per_episode``
   trajectories in fresh training arenas (line 4);
2. find theta by projected subgradient on the max-margin objective (eq. 12-13,
   line 5); minus the objective's minimum is the margin t (how far the best reward still puts
   the expert above every alternative; what it reads depends on the reading, docs/ALGORITHM.md);
   stop if t <= epsilon (lines 6-8: the paper preset's epsilon = 0; the default never stops);
3. rewards r_theta = theta^T f (eq. 2), value targets (eq. 14: SARSA in the
   paper variant; n-step Q-learning targets in the default, docs/ALGORITHM.md)
   and backpropagation on the cross-entropy cost (eq. 15) give the next
   network (lines 9-10).

Every policy is kept; the one reported is chosen by the configured rule
(paper: highest prediction accuracy on the demonstrations). What the
``default`` variant changes, and why, is in docs/ALGORITHM.md. With ``reward_source`` "learned",
``terminal_value`` "learned" and a selection rule that reads no task signal, the learner reads the
demonstrations, phi(s) and that its own episodes ended, nothing else: not the task's reward,
outcome (arrival or collision) or success (``nirl_mj.experiments.reads`` names what each
setting reads).

``reward_source`` swaps the learned reward for a known one, which gives the
controls: ``"progress"`` (the inner learner on the progress towards the
target: the ceiling of the inner loop) and ``"constant"`` (what surviving alone earns).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from nirl_mj.data.features import N_ACTIONS
from nirl_mj.data.outcomes import outcome_rates
from nirl_mj.data.trajectory import TERMINAL_OUTCOMES, Trajectory, stack_pairs
from nirl_mj.data.transitions import Transitions
from nirl_mj.learn import network, sarsa
from nirl_mj.learn.config import PRETREATMENTS, LearnerConfig
from nirl_mj.learn.inputs import NetworkInputs
from nirl_mj.learn.methods import RolloutContext, reward_step
from nirl_mj.learn.predictability import balanced_accuracy
from nirl_mj.learn.pretreat import map_pretreat
from nirl_mj.learn.reward import RewardModel, all_action_features
from nirl_mj.learn.selection import latest_best
from nirl_mj.learn.terminal import absorbing_values


class NetworkAgent:
    """The neural policy as an agent: Boltzmann (eq. 8) while training, greedy (eq. 9) after."""

    acts_on_features = True  # reads phi(s) alone: one agent can drive many worlds at once

    def __init__(
        self, net: network.QNetwork, inputs: NetworkInputs, eta: float | None, rng: np.random.Generator
    ) -> None:
        self.net, self.inputs, self.eta, self.rng = net, inputs, eta, rng
        self.kind = "nirl"

    def reset(self, env: Any, timestep: Any) -> None:
        # The network does not change during an episode: read its weights once. phi(s) is
        # discrete and repeats often within an episode, so each state's choice (the greedy
        # action, or the Boltzmann CDF to draw from) is computed once per episode.
        self._weights = (self.net.W1.detach().numpy(), self.net.W2.detach().numpy())
        self._choices: dict[bytes, int | np.ndarray] = {}

    def act(self, timestep: Any) -> int:
        """The action for a dm_env timestep (reads ``timestep.observation["features"]``, phi(s))."""
        phi = timestep.observation["features"]
        key = phi.tobytes()
        choice = self._choices.get(key)
        if choice is None:
            q = network.q_values(self.net, self.inputs(phi[None]), self._weights)[0]
            if self.eta is None:
                choice = int(network.greedy_actions(q[None])[0])
            else:
                choice = network.boltzmann_cdf(q, self.eta)
            self._choices[key] = choice
        if self.eta is None:
            return choice
        return network.draw_action(choice, self.rng)

    def act_batch(self, phi: np.ndarray) -> np.ndarray:
        """The actions (N,) int64 for the states phi (N, 16) of N worlds, in one network call.

        Greedy: argmax of each row (eq. 9). Boltzmann: one ``rng.random()`` per row, in row order,
        drawn as :meth:`act` draws them (inverse CDF, eq. 8), so a batch spends the generator as
        N calls of :meth:`act` would. The batched matrix product may round differently from a
        one-row product in the last digit, so an exact tie may break otherwise than in :meth:`act`.
        Needs :meth:`reset` called once (it reads the network's weights)."""
        phi = np.asarray(phi)
        q = network.q_values(self.net, self.inputs(phi), self._weights)
        if self.eta is None:
            return network.greedy_actions(q).astype(np.int64)
        cdf = np.cumsum(network.boltzmann_probabilities(q, self.eta), axis=-1)
        return network.draw_actions(cdf, self.rng)


def demonstrated_pairs(demos: list[Trajectory]) -> tuple[np.ndarray, np.ndarray]:
    """phi(s) (N, 16) and actions (N,) of every demonstrated decision; an error if there are none."""
    phi, actions = stack_pairs(demos)
    if len(actions) == 0:
        raise ValueError(
            f"the demonstrations hold no state-action pair (all {len(demos)} trajectories end before "
            "their first decision): there is nothing to learn from"
        )
    return phi, actions


def greedy_policy(net: network.QNetwork, inputs: NetworkInputs) -> Callable[[np.ndarray], int]:
    """The trained policy on phi(s) (eq. 9), as ``nirl_mj.experts.policies`` policies are."""

    def policy(phi: np.ndarray) -> int:
        q = network.q_values(net, inputs(np.asarray(phi)[None]))
        return int(network.greedy_actions(q)[0])

    return policy


@dataclass
class Metrics:
    """One iteration's record (a line of metrics.jsonl)."""

    episode: int
    margin: float
    cost: float
    dw1: float
    dw2: float
    demo_accuracy: float
    demo_balanced_accuracy: float
    success_rate: float
    collision_rate: float
    timeout_rate: float
    reward_spread: float
    clipped_share: float
    policy_entropy: float
    eta: float
    theta_norm: float
    reward_prefers_forward: float
    validation_success: float | None


Rollouts = Callable[["NetworkAgent", Sequence[int]], list[Trajectory]]
"""``rollouts(agent, seeds)``: the agent driven once in the arena of each seed (the simulation's
episode loop, passed in by the caller: this package does not simulate)."""


class IrlLoop:
    """The loop every IRL method shares (Algorithm 1): its state between iterations, and one
    iteration (:meth:`step`). The reward step is ``config.loop.method``'s."""

    def __init__(self, config: LearnerConfig, demos: list[Trajectory], seed: int) -> None:
        if not demos:
            raise ValueError("the IRL loop needs at least one demonstration")
        prior = PRETREATMENTS[config.loop.pretreatment]
        if prior is not None:
            demos, _ = map_pretreat(demos, prior)
        self.config = config
        self.loop = config.loop
        self.seed = seed
        self.rng = np.random.default_rng([seed, 7])
        torch.set_num_threads(1)  # tiny network: threads only add nondeterminism
        self.inputs = NetworkInputs.of(config.loop)
        self.net = network.QNetwork(self.inputs.size, config.loop.hidden_units, seed=seed)
        self.demo_phi, self.demo_actions = demonstrated_pairs(demos)
        self.demo_inputs = self.inputs(self.demo_phi)
        # phi(s_T) where the demonstrations ended (not truncated): the learned absorbing value's anchor
        self.expert_ends = np.array([t.features[-1] for t in demos if t.outcome in TERMINAL_OUTCOMES])
        self.reward_step = reward_step(config, demos) if config.loop.reward_source == "learned" else None
        n_theta = all_action_features(self.demo_phi[:1], config.loop.reward_features).shape[-1]
        self.theta = np.zeros(n_theta)
        self.replay: list[Transitions] = []
        self.iteration = 0
        self.kept: list[dict[str, np.ndarray]] = []  # every policy (Algorithm 1's output)
        self.thetas: list[np.ndarray] = []
        self.scores: list[float] = []  # the selection score of each kept policy
        self.stopped = False

    # -- eq. 14-15 -------------------------------------------------------------------

    def _rewards(self, t: Transitions) -> tuple[np.ndarray, float]:
        """Rewards of the transitions and their spread before any scaling."""
        c = self.loop
        if c.reward_source == "progress":
            raw = t.progress
            lo, hi = -1.0, 1.0
        elif c.reward_source == "constant":
            raw = np.ones(len(t))
            lo, hi = 0.0, 2.0
        else:
            raw = RewardModel(self.theta, c.reward_features).reward(t.phi, t.action)
            lo, hi = float(raw.min()), float(raw.max())
        spread = hi - lo
        if not c.reward_scaling:
            return raw, spread
        return (1.0 - c.gamma) * (raw - lo) / max(spread, 1e-12), spread

    def _targets(self, t: Transitions) -> tuple[np.ndarray, float, float]:
        c = self.loop
        q = network.q_values(self.net, self.inputs(t.phi))
        q_next_all = network.q_values(self.net, self.inputs(t.next_phi))
        q_sa = q[np.arange(len(t)), t.action]
        rows = np.arange(len(t))
        greedy_next = q_next_all.max(axis=1)
        if c.bootstrap == "q":  # Q-learning: the greedy policy's value of the next state
            q_next = greedy_next
        else:  # eq. 14: the next pair the policy took (the greedy one after a timeout's last step)
            q_next = np.where(t.next_action >= 0, q_next_all[rows, np.maximum(t.next_action, 0)], greedy_next)
        rewards, spread = self._rewards(t)
        ends = self._terminal_values(t)
        targets, clipped = sarsa.sarsa_targets(
            q_sa, rewards, q_next, t.terminal, c.alpha, c.gamma, ends, t.remaining, c.n_step
        )
        return targets, clipped, spread

    def _terminal_values(self, t: Transitions) -> np.ndarray:
        """The value of each row's episode end, (N,), read where ``t.terminal`` (learn/terminal.py)."""
        if self.loop.terminal_value == "outcome":
            return t.terminal_value
        values = np.zeros(len(t))
        ends = t.next_phi[t.terminal]
        values[t.terminal] = absorbing_values(self.expert_ends, ends, self.loop.reward_features)
        return values

    def fit_replay(self) -> float:
        """Step 4 of an iteration on the replay window as it stands (theta, rollouts untouched)."""
        return self._fit(Transitions.concat(self.replay))

    def _fit(self, t: Transitions) -> float:
        """``fit_rounds`` rounds of targets (eq. 14) from the current network, each fitted (eq. 15);
        the cost the last round's fit reports (full batch: before its last step; replay: the mean
        over its minibatch steps)."""
        c = self.loop
        x = self.inputs(t.phi)
        for _ in range(c.fit_rounds):
            targets, self._clipped, self._spread = self._targets(t)
            if c.replay_episodes == 0:  # the paper: full-batch steps on this episode's pairs
                for _ in range(max(c.net_epochs, 1)):
                    cost = network.gradient_step(self.net, x, t.action, targets, c.net_l2, c.net_step)
            else:
                cost = network.minibatch_epochs(
                    self.net, x, t.action, targets, c.net_l2, c.net_step, c.net_epochs, c.batch_size, self.rng
                )
        return float(cost)

    # -- one iteration of Algorithm 1 -------------------------------------------------

    def eta(self) -> float:
        """This iteration's Boltzmann parameter (eq. 8): ``eta`` -> ``eta_final`` linearly."""
        c = self.loop
        frac = self.iteration / max(c.episodes - 1, 1)
        return c.eta + (c.eta_final - c.eta) * frac

    def step(self, rollouts: Rollouts, train_seeds: list[int], validate: Callable | None = None) -> Metrics:
        """One iteration: rollouts in the arenas of ``train_seeds``, theta, the next network."""
        c = self.loop
        eta = self.eta()
        agent = NetworkAgent(self.net, self.inputs, eta, self.rng)
        trajectories = rollouts(agent, train_seeds)  # line 4
        before = network.get_weights(self.net)
        visited = np.concatenate([self.inputs(t.features[:-1]) for t in trajectories])
        entropy = network.policy_entropy(network.q_values(self.net, visited), eta)

        margin = float("nan")
        if self.reward_step is not None:  # line 5
            greedy = network.greedy_actions(network.q_values(self.net, self.demo_inputs))
            # the policy that drove the rollouts (RE-IRL's importance weights read it)
            drove = (before["W1"], before["W2"])
            context = RolloutContext(eta, lambda phi: network.q_values(self.net, self.inputs(phi), drove))
            self.theta, margin = self.reward_step.update(
                self.theta, trajectories, self.iteration, greedy, context
            )
            if c.epsilon is not None and margin <= c.epsilon:  # lines 6-8
                self.stopped = True

        arrival = c.terminal_arrival_value if c.reads_outcome else 0.0
        fresh = Transitions.of(trajectories, arrival, progress=c.reward_source == "progress")  # lines 9-10
        self.replay = ([*self.replay, fresh])[-max(c.replay_episodes, 1) :]
        cost = self.fit_replay()
        after = network.get_weights(self.net)
        kept, policy_net = after, self.net

        greedy = network.greedy_actions(network.q_values(policy_net, self.demo_inputs))
        demo_acc = float(np.mean(greedy == self.demo_actions))
        balanced = balanced_accuracy(self.demo_actions, greedy)
        preferred = (
            RewardModel(self.theta, c.reward_features).rewards_all_actions(self.demo_phi).argmax(axis=1)
        )
        validation = validate(policy_net) if validate is not None else None
        self.kept.append(kept)
        self.thetas.append(self.theta.copy())
        self.scores.append(self._score(demo_acc, balanced, validation))
        rates = outcome_rates(t.outcome for t in trajectories)
        metrics = Metrics(
            episode=self.iteration,
            margin=float(margin),
            cost=float(cost),
            dw1=float(np.abs(after["W1"] - before["W1"]).sum()),
            dw2=float(np.abs(after["W2"] - before["W2"]).sum()),
            demo_accuracy=demo_acc,
            demo_balanced_accuracy=balanced,
            success_rate=rates["success_rate"],
            collision_rate=rates["collision_rate"],
            timeout_rate=rates["timeout_rate"],
            reward_spread=float(self._spread),
            clipped_share=float(self._clipped),
            policy_entropy=float(entropy),
            eta=eta,
            theta_norm=float(np.linalg.norm(self.theta)),
            reward_prefers_forward=float(np.mean(preferred == 0)),
            validation_success=validation,
        )
        self.iteration += 1
        return metrics

    def _score(self, accuracy: float, balanced: float, validation: float | None) -> float:
        """The selection score of this iteration's policy (``LoopConfig.selection``): the higher, the
        better; the latest of the best is chosen (:attr:`selected`)."""
        rule = self.loop.selection
        if rule == "demo_accuracy":
            return accuracy
        if rule == "demo_balanced":
            return balanced
        if rule == "last":
            return float(self.iteration)
        return validation if validation is not None else -1.0

    @property
    def selected(self) -> int:
        """Index of the policy the configured rule picks (the latest of the best:
        ``nirl_mj.learn.selection``)."""
        return latest_best(self.scores)

    # -- checkpoints -------------------------------------------------------------------

    def state(self) -> dict[str, np.ndarray]:
        """Everything needed to continue exactly where this iteration ended."""
        replay = Transitions.concat(self.replay) if self.replay else Transitions.empty()
        state = {
            "iteration": np.array(self.iteration),
            "theta": self.theta,
            "rng": np.array(json.dumps(self.rng.bit_generator.state)),
            "stopped": np.array(self.stopped),
            "scores": np.array(self.scores, dtype=np.float64),
            "thetas": np.array(self.thetas).reshape(len(self.thetas), self.theta.size),
            "replay_sizes": np.array([len(r) for r in self.replay], dtype=np.int64),
        }
        state |= {f"net_{k}": v for k, v in network.get_weights(self.net).items()}
        for name in network.get_weights(self.net):
            state[f"kept_{name}"] = np.array([w[name] for w in self.kept]) if self.kept else np.zeros((0,))
        # the loop's rows are never absorbing (an end's value is learn/terminal.py's): that field is not
        # saved, so checkpoints keep the form they had before the class was shared
        state |= {f"replay_{k}": v for k, v in replay.arrays().items() if k != "absorbing"}
        if self.reward_step is not None:
            state |= {f"reward_step_{k}": v for k, v in self.reward_step.state().items()}
        return state

    def check_state(self, state: dict[str, np.ndarray]) -> None:
        """Refuses (ValueError naming the field) a checkpoint this loop cannot continue from: a field
        missing, of another shape or type, not finite, or an iteration outside 0..episodes, so that
        a resume never trains on (and writes out) a damaged state."""

        def field(name: str) -> np.ndarray:
            if name not in state:
                raise ValueError(f"{name}: missing")
            return np.asarray(state[name])

        def finite(name: str, value: np.ndarray, shape: tuple) -> None:
            if value.shape != shape:
                raise ValueError(f"{name}: shape {value.shape}, expected {shape}")
            if not np.issubdtype(value.dtype, np.number) or not np.all(np.isfinite(value)):
                raise ValueError(f"{name}: not all finite numbers")

        iteration = field("iteration")
        if iteration.shape != () or not np.issubdtype(iteration.dtype, np.integer):
            raise ValueError(f"iteration: {iteration!r} is not a whole number")
        n = int(iteration)
        if not 0 <= n <= self.loop.episodes:
            raise ValueError(f"iteration = {n}: outside 0..{self.loop.episodes} (the run's episodes)")
        finite("theta", field("theta"), self.theta.shape)
        finite("scores", field("scores"), (n,))
        finite("thetas", field("thetas"), (n, self.theta.size))
        for name, weights in network.get_weights(self.net).items():
            finite(f"net_{name}", field(f"net_{name}"), weights.shape)
            if n:
                finite(f"kept_{name}", field(f"kept_{name}"), (n, *weights.shape))
        sizes = field("replay_sizes")
        if sizes.ndim != 1 or not np.issubdtype(sizes.dtype, np.integer) or np.any(sizes < 0):
            raise ValueError("replay_sizes: not a list of counts")
        rows = int(sizes.sum())
        for name in (k for k in state if k.startswith("replay_") and k != "replay_sizes"):
            value = np.asarray(state[name])
            if value.ndim == 0 or value.shape[0] != rows:
                raise ValueError(
                    f"{name}: {value.shape[0] if value.ndim else 0} rows, replay_sizes say {rows}"
                )
            if np.issubdtype(value.dtype, np.floating) and not np.all(np.isfinite(value)):
                raise ValueError(f"{name}: not all finite numbers")
        for name, low in (("replay_action", 0), ("replay_next_action", -1)):  # -1: no next action
            value = np.asarray(state.get(name, np.zeros(0, int)))
            if value.size and (not np.issubdtype(value.dtype, np.integer) or value.min() < low
                               or value.max() >= N_ACTIONS):  # fmt: skip
                raise ValueError(f"{name}: not all actions {low}..{N_ACTIONS - 1}")
        stopped = field("stopped")
        if stopped.shape != () or stopped.dtype != bool:
            raise ValueError(f"stopped: {stopped!r} is not true or false")
        try:
            json.loads(str(field("rng")))
        except (ValueError, TypeError) as exc:
            raise ValueError(f"rng: unreadable ({exc})") from None

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Continues from ``state`` (:meth:`state`), checked first (:meth:`check_state`)."""
        self.check_state(state)
        self.iteration = int(state["iteration"])
        self.theta = np.array(state["theta"], dtype=np.float64)
        self.rng.bit_generator.state = json.loads(str(state["rng"]))
        self.stopped = bool(state["stopped"])
        self.scores = [float(s) for s in state["scores"]]
        self.thetas = [np.array(t) for t in state["thetas"]]
        names = list(network.get_weights(self.net))
        network.set_weights(self.net, {k: np.array(state[f"net_{k}"]) for k in names})
        n_kept = len(self.scores)
        self.kept = [{k: np.array(state[f"kept_{k}"][i]) for k in names} for i in range(n_kept)]
        prefix = "replay_"
        replay = Transitions.from_arrays({k.removeprefix(prefix): v for k, v in state.items()
                                          if k.startswith(prefix) and k != "replay_sizes"})  # fmt: skip
        if self.reward_step is not None:
            prefix = "reward_step_"
            own = {k.removeprefix(prefix): v for k, v in state.items() if k.startswith(prefix)}
            self.reward_step.load_state(own)
        self.replay, start = [], 0
        for size in state["replay_sizes"]:
            self.replay.append(replay.take(slice(start, start + size)))
            start += size
