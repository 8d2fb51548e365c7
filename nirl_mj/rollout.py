"""Running an agent for whole episodes, each in its own seeded arena, recording trajectories."""

from __future__ import annotations

from collections.abc import Iterator

import dm_env
import numpy as np

from nirl_mj.experts import Expert
from nirl_mj.policies import POLICIES, Policy
from nirl_mj.task import Outcome
from nirl_mj.trajectory import Trajectory, TrajectoryRecorder


def episode_seed(seed: int, episode: int) -> int:
    """The arena seed of episode ``episode`` in a run seeded ``seed``: independent of
    the order in which episodes are run, so runs can be split across processes."""
    return int(np.random.SeedSequence([seed, episode]).generate_state(1)[0])


class PolicyAgent:
    """A policy on phi(s) (``nirl_mj.policies``) behind the :class:`~nirl_mj.experts.Expert` interface."""

    def __init__(self, policy: Policy, kind: str) -> None:
        self.policy = policy
        self.kind = kind

    @classmethod
    def named(cls, name: str) -> PolicyAgent:
        """One of the reference policies in ``nirl_mj.policies.POLICIES``."""
        return cls(POLICIES[name], name)

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        pass

    def act(self, timestep: dm_env.TimeStep) -> int:
        return self.policy(timestep.observation["features"])


def run_episode(env: dm_env.Environment, agent: Expert, seed: int) -> Trajectory:
    """Runs ``agent`` for one episode in the arena of ``seed`` and returns what it did."""
    task = env.task
    env.random_state.seed(seed)
    timestep = env.reset()
    agent.reset(env, timestep)
    recorder = TrajectoryRecorder(task.spec.control.decision_period)
    recorder.start(timestep.observation)
    while not timestep.last():
        action = agent.act(timestep)
        timestep = env.step(action)
        recorder.step(action, timestep.observation)
    outcome = Outcome(int(timestep.observation["outcome"])).name.lower()
    return recorder.finish(outcome, seed, task.spec, task.spec.control.speed, agent.kind)


def run_episodes(
    env: dm_env.Environment, agent: Expert, seed: int, episodes: int, first: int = 0
) -> Iterator[Trajectory]:
    """Yields episodes ``first .. first + episodes - 1``; episode i runs in the arena of
    ``episode_seed(seed, i)``."""
    for i in range(first, first + episodes):
        yield run_episode(env, agent, episode_seed(seed, i))


def path_length(trajectory: Trajectory) -> float:
    """Metres travelled, summed over decisions."""
    return float(np.sum(np.hypot(*np.diff(trajectory.poses[:, :2], axis=0).T)))
