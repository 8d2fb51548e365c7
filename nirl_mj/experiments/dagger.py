"""DAgger (Ross, Gordon & Bagnell 2011): imitation with an interactive expert, the reference row.

The paper's Algorithm 3.1 with beta_1 = 1 and beta_i = 0 afterwards (the variant its experiments
found best): round 1 is the expert driving, i.e. the experiment's demonstrations, and the first
policy is behaviour cloning of them (``learn/bc.py``, the same network and fit). Each later round
drives the current policy (greedy) on ``episodes`` fresh training arenas while the expert, reset
with every episode and shown every timestep, says what it would do in each visited state; the
labelled pairs join the data set, and a new policy is cloned from all of it (from scratch, with
the run's seed). The policy returned is the last one (the paper picks the best on validation;
the last is used here, so DAgger spends no validation arenas).

The expert is the experiment's demonstrator (by default the sensor expert, which reads only what
the robot senses and remembers: ``nirl_mj.experts.sensor``). DAgger thus gets more expert labels
than the other rows (30 demonstrations plus every state of ``rounds x episodes`` learner
episodes): it is the reference for what an interactive expert buys, not a method on the same
information. Rollouts run on the training drive (planar, as NIRL's) and arenas of
``seeds.domain_seed("train", seed, k)``, which held-out tests never use.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from nirl_mj.data.trajectory import Trajectory
from nirl_mj.experiments.seeds import domain_seeds
from nirl_mj.learn.bc import CloneSettings, clone_pairs, training_pairs
from nirl_mj.sim import spec as specs


@dataclass(frozen=True)
class DaggerConfig:
    """Rounds after the demonstrations' round, learner episodes per round, the training drive."""

    rounds: int = 8
    episodes: int = 10
    drive: str = "planar"

    def __post_init__(self) -> None:
        if self.rounds < 0 or self.episodes < 1:
            raise ValueError(
                f"DAgger needs rounds >= 0 and episodes >= 1, got {self.rounds}, {self.episodes}"
            )

    @classmethod
    def of(cls, settings: Mapping[str, Any]) -> DaggerConfig:
        """The config a method's ``settings`` table asks for (:data:`SETTINGS`, whole numbers; the
        others keep their defaults): the interactive expert's budget, ``rounds x episodes`` learner
        episodes labelled."""
        unknown = sorted(set(settings) - set(SETTINGS))
        if unknown:
            accepted = ", ".join(SETTINGS)
            raise ValueError(f"unknown DAgger setting(s) {', '.join(unknown)}; accepted: {accepted}")
        for key, value in settings.items():
            if not isinstance(value, int) or isinstance(value, bool):
                raise ValueError(f"DAgger's {key} must be a whole number, got {value!r}")
        return cls(**settings)


SETTINGS = ("rounds", "episodes")
"""The keys of a DAgger method's ``settings`` (``method.NAME.settings`` in an experiment file)."""


class LabellingAgent:
    """Drives ``policy`` (on phi(s)) while ``expert`` labels every visited state (an Agent)."""

    def __init__(self, policy: Callable[[np.ndarray], int], expert) -> None:
        self.policy, self.expert = policy, expert
        self.kind = "dagger"
        self.phi: list[np.ndarray] = []
        self.labels: list[int] = []

    def reset(self, env, timestep) -> None:
        self.expert.reset(env, timestep)

    def act(self, timestep) -> int:
        phi = np.array(timestep.observation["features"])
        # the expert sees every timestep, so its memory (rays, progress) stays its own
        self.labels.append(int(self.expert.act(timestep)))
        self.phi.append(phi)
        return int(self.policy(phi))


def train_dagger(
    task: specs.TaskSpec,
    demos: Sequence[Trajectory],
    seed: int,
    expert: str = "sensor",
    config: DaggerConfig = DaggerConfig(),
    on_round: Callable[[int, int], None] | None = None,
    settings: CloneSettings | None = None,
) -> tuple[Callable[[np.ndarray], int], list[int]]:
    """The last DAgger policy on phi(s) and the training arenas it drove in; each round's fit as
    behaviour cloning's ``settings`` (default: ``CloneSettings.of("default")``).

    ``on_round(round, labelled pairs)`` reports progress after each round."""
    from nirl_mj.experiments.demos import ExpertConfig
    from nirl_mj.sim.episode import run_episode
    from nirl_mj.sim.task import make_env

    # as behaviour cloning (learn/bc.py): each fit stopped early on the held-out demonstrations
    settings = settings or CloneSettings.of("default")
    (phi, actions), held_pairs = training_pairs(demos, settings)
    data_phi, data_actions = [phi], [np.asarray(actions, dtype=np.int64)]
    policy = clone_pairs(phi, actions, seed, settings, held_pairs)
    env = make_env(specs.replace(task, robot={"drive": config.drive}))
    teacher = ExpertConfig.named(expert, seed).build()
    arenas = domain_seeds("train", seed, config.rounds * config.episodes)
    for round_ in range(config.rounds):
        agent = LabellingAgent(policy, teacher)
        for arena in arenas[round_ * config.episodes : (round_ + 1) * config.episodes]:
            run_episode(env, agent, arena)
        if agent.labels:
            data_phi.append(np.stack(agent.phi))
            data_actions.append(np.asarray(agent.labels, dtype=np.int64))
        policy = clone_pairs(
            np.concatenate(data_phi), np.concatenate(data_actions), seed, settings, held_pairs
        )
        if on_round:
            on_round(round_ + 1, sum(len(a) for a in data_actions))
    return policy, arenas
