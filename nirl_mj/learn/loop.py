"""NIRL, Algorithm 1 of the paper, in the order it runs; both variants are configurations.

Each iteration ("episode" in the paper):

1. run the current policy (Boltzmann, eq. 8) for ``trajectories_per_episode``
   trajectories in fresh training arenas (line 4);
2. find theta by projected subgradient on the max-margin objective (eq. 12-13,
   line 5); the minimum is the margin t; stop if t <= epsilon (lines 6-8);
3. rewards r_theta = theta^T f (eq. 2), SARSA targets (eq. 14) and
   backpropagation on the cross-entropy cost (eq. 15) give the next network
   (lines 9-10).

Every policy is kept; the one reported is chosen by the configured rule
(paper: highest prediction accuracy on the demonstrations). What the
``default`` variant changes, and why, is in docs/ALGORITHM.md. The learner
never reads the task's reward or success signal: only the demonstrations, and
its own trajectories' collisions and arrivals (terminal states).

``reward_source`` swaps the learned reward for a known one, which gives the
controls: ``"progress"`` (SARSA on the progress towards the target: the
ceiling of the inner loop) and ``"constant"`` (what surviving alone earns).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from dataclasses import dataclass

import dm_env
import numpy as np
import torch

from nirl_mj.data.outcomes import outcome_rates
from nirl_mj.data.trajectory import Trajectory, stack_pairs
from nirl_mj.learn import network, sarsa
from nirl_mj.learn.methods import REWARD_STEPS, RolloutContext, reward_step
from nirl_mj.learn.predictability import balanced_accuracy
from nirl_mj.learn.reward import RewardModel, all_action_features
from nirl_mj.sim.episode import run_episode

VARIANTS = ("paper", "default")
REWARD_SOURCES = ("learned", "progress", "constant")


@dataclass(frozen=True)
class NirlConfig:
    """Every choice of the learner. ``paper()`` and ``default()`` give the two variants."""

    variant: str = "default"
    method: str = "nirl"  # the reward step: "nirl" (max margin, eq. 11-13) or a baseline (learn/methods.py)
    episodes: int = 60  # ~2-4 min per run on one core (planar training drive)
    trajectories_per_episode: int = 10
    gamma: float = 0.65  # eq. 14
    alpha: float = 0.8  # eq. 14
    eta: float = 5.0  # eq. 8, Boltzmann parameter at the first iteration (low: every action gets tried)
    eta_final: float = 60.0  # eta is interpolated linearly to this over the episodes
    reward_features: str = "extended"  # "paper" (eq. 4-5) or "extended"
    matching: str = "occupancy"  # "paper": eq. 11 expectations; "occupancy": per-pair sums
    # occupancy only: what follows a deviation from the expert's pair. 1: the learner's mean
    # discounted sum (its own behaviour); 0: the expert's own continuation,
    # mu(s, a) = f(s, a) + gamma mu_E(s', a'_E) (akin to SCIRL's heuristic, which uses
    # mu_E(s, a_E): docs/ALGORITHM.md); in between: a mixture.
    future_mix: float = 0.0
    margin_loss: float = 0.1  # l(s, a) for a != a_E (paper: 1)
    mmp_lambda: float = 0.0  # lambda_1 of eq. 13
    mmp_steps: int = 30
    mmp_step_size: float = 0.5  # sigma_1
    mmp_step_decay: float = 0.1  # sigma_1 / (1 + decay * i) over iterations i
    epsilon: float = float("-inf")  # stop when the margin t <= epsilon (paper: 0)
    reward_scaling: bool = True  # rewards mapped into [0, 1 - gamma]
    terminal_arrival_value: float = 1.0  # value of reaching the target (a terminal state)
    net_step: float = 0.4  # sigma_2 of eq. 15
    net_l2: float = 1e-3  # lambda_2 of eq. 15
    replay_episodes: int = 10  # 0: train on this episode's pairs only (paper)
    net_epochs: int = 4  # full-batch steps (no replay) or minibatch epochs (replay)
    batch_size: int = 64
    input_scaling: bool = True  # network input D/7 and V/9 instead of raw phi
    selection: str = "validation"  # "demo_accuracy" (paper) or "validation"
    validation_arenas: int = 20
    validate_every: int = 5
    # validation selection: the best `final_candidates` policies are re-validated on as many
    # new validation arenas, and the best over both sets is chosen (1: no second round)
    final_candidates: int = 3
    reward_source: str = "learned"
    train_drive: str = "planar"  # the training rollouts' drive fidelity (same kinematics, 5x faster)
    # -- the baselines' reward steps (method "al", "re", "scirl"; docs/ALGORITHM.md, "Baselines") --
    # AL, RE: what a feature expectation is. "trajectory": eq. 11, each trajectory's discounted sum
    # from its start (the papers' reading; with gamma 0.65 it sees ~3 steps); "suffix": the mean
    # discounted suffix sum over every visited pair (sees every state)
    al_expectations: str = "trajectory"
    re_expectations: str = "trajectory"
    re_horizon: int = 16  # pairs per RE sample (and its importance ratio); gamma^16 ~ 1e-3
    re_step: float = 0.5  # RE: gradient-ascent step on the dual g(theta)
    re_steps: int = 30  # RE: ascent steps per iteration, warm-started from the last theta
    re_pool: int = 10  # RE: iterations whose rollouts are pooled as importance samples
    re_confidence: float = 0.95  # RE: Hoeffding confidence of the L1 widths epsilon_i (0: no L1 term)
    # RE: how the L1 term -sum eps_i |theta_i| is stepped. "subgradient" (the paper): theta_i flips by
    # +-re_step eps_i around 0 every step; "proximal" (soft-thresholding): such theta_i rest at 0
    re_l1_step: str = "proximal"
    scirl_steps: int = 40  # SCIRL: normalised subgradient steps (as the authors' code)
    scirl_step_size: float = 3.0  # SCIRL: step size / (k + 1) at step k (authors: 3 / (k + 1))

    def __post_init__(self) -> None:
        if self.method not in REWARD_STEPS:
            raise ValueError(f"unknown method {self.method!r}; accepted: {', '.join(REWARD_STEPS)}")
        if self.reward_source not in REWARD_SOURCES:
            raise ValueError(
                f"unknown reward_source {self.reward_source!r}; accepted: {', '.join(REWARD_SOURCES)}"
            )

    @classmethod
    def paper(cls, **changes) -> NirlConfig:
        """The algorithm as the paper writes it."""
        base = dict(
            variant="paper",
            eta=10.0,
            eta_final=10.0,
            reward_features="paper",
            matching="paper",
            future_mix=1.0,
            episodes=120,
            margin_loss=1.0,
            mmp_step_decay=0.0,
            reward_scaling=False,
            terminal_arrival_value=0.0,
            replay_episodes=0,
            net_epochs=20,
            input_scaling=False,
            selection="demo_accuracy",
            epsilon=0.0,
        )
        return cls(**{**base, **changes})

    @classmethod
    def default(cls, **changes) -> NirlConfig:
        return cls(**changes)

    @classmethod
    def named(cls, variant: str, **changes) -> NirlConfig:
        if variant not in VARIANTS:
            raise ValueError(f"unknown variant {variant!r}; accepted: {', '.join(VARIANTS)}")
        return cls.paper(**changes) if variant == "paper" else cls.default(**changes)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


_INPUT_SCALE = np.array([7.0] * 7 + [9.0] + [1.0] * 8)


def network_inputs(phi: np.ndarray, scaled: bool) -> np.ndarray:
    """What the network sees: phi (N, 16), or with D/7 and V/9 so every input is in [0, 1]."""
    x = np.asarray(phi, dtype=np.float64)
    return x / _INPUT_SCALE if scaled else x


class NetworkAgent:
    """The neural policy as an agent: Boltzmann (eq. 8) while training, greedy (eq. 9) after."""

    def __init__(
        self, net: network.QNetwork, scaled: bool, eta: float | None, rng: np.random.Generator
    ) -> None:
        self.net, self.scaled, self.eta, self.rng = net, scaled, eta, rng
        self.kind = "nirl"

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        # The network does not change during an episode: read its weights once.
        self._weights = (self.net.W1.detach().numpy(), self.net.W2.detach().numpy())

    def act(self, timestep: dm_env.TimeStep) -> int:
        x = network_inputs(timestep.observation["features"][None], self.scaled)
        q = network.q_values(self.net, x, self._weights)[0]
        if self.eta is None:
            return int(network.greedy_actions(q[None])[0])
        return network.sample_action(q, self.eta, self.rng)


def greedy_policy(net: network.QNetwork, scaled: bool) -> Callable[[np.ndarray], int]:
    """The trained policy on phi(s) (eq. 9), as ``nirl_mj.experts.policies`` policies are."""

    def policy(phi: np.ndarray) -> int:
        q = network.q_values(net, network_inputs(np.asarray(phi)[None], scaled))
        return int(network.greedy_actions(q)[0])

    return policy


@dataclass
class Transitions:
    """SARSA transitions of the learner's own trajectories, one row each.

    ``next_action`` is -1 where the next action is the greedy one (a timeout's
    last step); ``terminal`` rows do not bootstrap and take ``terminal_value``;
    ``progress`` is the travel towards the target in units of one decision's
    travel (only the ``progress`` control reads it).
    """

    phi: np.ndarray
    action: np.ndarray
    next_phi: np.ndarray
    next_action: np.ndarray
    terminal: np.ndarray
    terminal_value: np.ndarray
    progress: np.ndarray

    @classmethod
    def empty(cls) -> Transitions:
        return cls(
            np.zeros((0, 16)), np.zeros(0, int), np.zeros((0, 16)), np.zeros(0, int), np.zeros(0, bool),
            np.zeros(0), np.zeros(0),
        )  # fmt: skip

    @classmethod
    def of(cls, trajectories: list[Trajectory], arrival_value: float) -> Transitions:
        parts = []
        for t in trajectories:
            n = len(t)
            if n == 0:
                continue
            next_action = np.append(t.actions[1:], -1).astype(int)
            terminal = np.zeros(n, bool)
            value = np.zeros(n)
            if t.outcome in ("collision", "physics_error", "target"):
                terminal[-1] = True
                value[-1] = arrival_value if t.outcome == "target" else 0.0
            target = np.asarray(t.task["arena"]["target"], dtype=np.float64)
            distance = np.hypot(*(t.poses[:, :2] - target).T)
            per_step = t.task["control"]["speed"] * t.task["control"]["decision_period"]
            progress = (distance[:-1] - distance[1:]) / per_step
            parts.append(
                cls(
                    t.features[:-1],
                    t.actions.astype(int),
                    t.features[1:],
                    next_action,
                    terminal,
                    value,
                    progress,
                )
            )
        return cls.concat(parts) if parts else cls.empty()

    @classmethod
    def concat(cls, parts: list[Transitions]) -> Transitions:
        return cls(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in dataclasses.fields(cls)))

    def __len__(self) -> int:
        return len(self.action)


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


class Nirl:
    """Algorithm 1's state between iterations, and one iteration (:meth:`step`)."""

    def __init__(self, config: NirlConfig, demos: list[Trajectory], seed: int) -> None:
        if not demos:
            raise ValueError("NIRL needs at least one demonstration")
        self.config = config
        self.seed = seed
        self.rng = np.random.default_rng([seed, 7])
        torch.set_num_threads(1)  # tiny network: threads only add nondeterminism
        self.net = network.QNetwork(seed=seed)
        self.demo_phi, self.demo_actions = stack_pairs(demos)
        self.demo_inputs = network_inputs(self.demo_phi, config.input_scaling)
        self.reward_step = reward_step(config, demos) if config.reward_source == "learned" else None
        n_theta = all_action_features(self.demo_phi[:1], config.reward_features).shape[-1]
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
        c = self.config
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
        c = self.config
        q = network.q_values(self.net, network_inputs(t.phi, c.input_scaling))
        q_next_all = network.q_values(self.net, network_inputs(t.next_phi, c.input_scaling))
        q_sa = q[np.arange(len(t)), t.action]
        rows = np.arange(len(t))
        q_next = np.where(
            t.next_action >= 0, q_next_all[rows, np.maximum(t.next_action, 0)], q_next_all.max(axis=1)
        )
        rewards, spread = self._rewards(t)
        targets, clipped = sarsa.sarsa_targets(
            q_sa, rewards, q_next, t.terminal, c.alpha, c.gamma, t.terminal_value
        )
        return targets, clipped, spread

    def _fit(self, t: Transitions) -> float:
        c = self.config
        targets, self._clipped, self._spread = self._targets(t)
        x = network_inputs(t.phi, c.input_scaling)
        if c.replay_episodes == 0:  # the paper: full-batch steps on this episode's pairs
            for _ in range(max(c.net_epochs, 1)):
                cost = network.gradient_step(self.net, x, t.action, targets, c.net_l2, c.net_step)
            return float(cost)
        return network.minibatch_epochs(
            self.net, x, t.action, targets, c.net_l2, c.net_step, c.net_epochs, c.batch_size, self.rng
        )

    # -- one iteration of Algorithm 1 -------------------------------------------------

    def eta(self) -> float:
        c = self.config
        frac = self.iteration / max(c.episodes - 1, 1)
        return c.eta + (c.eta_final - c.eta) * frac

    def step(
        self, env: dm_env.Environment, train_seeds: list[int], validate: Callable | None = None
    ) -> Metrics:
        """One iteration: rollouts in the arenas of ``train_seeds``, theta, the next network."""
        c = self.config
        eta = self.eta()
        agent = NetworkAgent(self.net, c.input_scaling, eta, self.rng)
        trajectories = [run_episode(env, agent, s) for s in train_seeds]  # line 4
        before = network.get_weights(self.net)
        visited = np.concatenate([network_inputs(t.features[:-1], c.input_scaling) for t in trajectories])
        entropy = network.policy_entropy(network.q_values(self.net, visited), eta)

        margin = float("nan")
        if self.reward_step is not None:  # line 5
            greedy = network.greedy_actions(network.q_values(self.net, self.demo_inputs))
            # the policy that drove the rollouts (RE-IRL's importance weights read it)
            drove = (before["W1"], before["W2"])
            context = RolloutContext(
                eta, lambda phi: network.q_values(self.net, network_inputs(phi, c.input_scaling), drove)
            )
            self.theta, margin = self.reward_step.update(
                self.theta, trajectories, self.iteration, greedy, context
            )
            if margin <= c.epsilon:  # lines 6-8
                self.stopped = True

        fresh = Transitions.of(trajectories, c.terminal_arrival_value)  # lines 9-10
        self.replay = ([*self.replay, fresh])[-max(c.replay_episodes, 1) :]
        cost = self._fit(Transitions.concat(self.replay))
        after = network.get_weights(self.net)

        greedy = network.greedy_actions(network.q_values(self.net, self.demo_inputs))
        demo_acc = float(np.mean(greedy == self.demo_actions))
        preferred = (
            RewardModel(self.theta, c.reward_features).rewards_all_actions(self.demo_phi).argmax(axis=1)
        )
        validation = validate(self.net) if validate is not None else None
        self.kept.append(after)
        self.thetas.append(self.theta.copy())
        self.scores.append(
            demo_acc if c.selection == "demo_accuracy" else (validation if validation is not None else -1.0)
        )
        rates = outcome_rates(t.outcome for t in trajectories)
        metrics = Metrics(
            episode=self.iteration,
            margin=float(margin),
            cost=float(cost),
            dw1=float(np.abs(after["W1"] - before["W1"]).sum()),
            dw2=float(np.abs(after["W2"] - before["W2"]).sum()),
            demo_accuracy=demo_acc,
            demo_balanced_accuracy=balanced_accuracy(self.demo_actions, greedy),
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

    @property
    def selected(self) -> int:
        """Index of the policy the configured rule picks (the first best)."""
        return int(np.argmax(self.scores)) if self.scores else -1

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
        state |= {f"replay_{f.name}": getattr(replay, f.name) for f in dataclasses.fields(Transitions)}
        if self.reward_step is not None:
            state |= {f"reward_step_{k}": v for k, v in self.reward_step.state().items()}
        return state

    def load_state(self, state: dict[str, np.ndarray]) -> None:
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
        replay = Transitions(*(np.array(state[f"replay_{f.name}"]) for f in dataclasses.fields(Transitions)))
        if self.reward_step is not None:
            prefix = "reward_step_"
            own = {k.removeprefix(prefix): v for k, v in state.items() if k.startswith(prefix)}
            self.reward_step.load_state(own)
        self.replay, start = [], 0
        for size in state["replay_sizes"]:
            self.replay.append(Transitions(*(getattr(replay, f.name)[start : start + size]
                                             for f in dataclasses.fields(Transitions))))  # fmt: skip
            start += size
