"""The one episode loop: an agent drives the robot for one episode in a seeded arena.

Rollouts, evaluation, demonstrations, videos and teleoperation all run episodes
through :func:`run_episode`; what differs between them is the agent and the
per-step hook (a video grabs frames, teleoperation may abandon an episode).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import dm_env

from nirl_mj.data.trajectory import Trajectory, TrajectoryRecorder
from nirl_mj.sim.task import Outcome


class Agent(Protocol):
    """Who drives: a demonstrator, a reference policy or a learner's policy."""

    kind: str
    """Short name recorded with every trajectory, e.g. ``"planner"``."""

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        """Called after ``env.reset()``, before the first :meth:`act` of an episode."""

    def act(self, timestep: dm_env.TimeStep) -> int | None:
        """The action 0..5 for the current timestep (None: end the episode here, unrecorded)."""


StepHook = Callable[[int, dm_env.TimeStep, "int | None"], None]
"""``on_step(step, timestep, action)``: called with the first timestep (step 0, action None) and
after every decision with the action that led to it; ``env.physics`` shows the state."""


class EpisodeAbandoned(Exception):
    """An agent returned no action: the episode ends early (teleoperation's Enter, Backspace or
    a closed window). ``trajectory`` holds the decisions made so far, with the outcome the
    state had or, still running, ``"timeout"`` (as if the step budget ran out); the agent's
    owner decides whether to keep it."""

    def __init__(self, message: str, trajectory: Trajectory) -> None:
        super().__init__(message)
        self.trajectory = trajectory


def run_episode(
    env: dm_env.Environment, agent: Agent, seed: int, on_step: StepHook | None = None
) -> Trajectory:
    """Runs ``agent`` for one episode in the arena of ``seed`` and returns what it did.

    Raises :class:`EpisodeAbandoned` (with the episode so far) if the agent returns None
    instead of an action."""
    spec = env.task.spec
    if spec.control.actions != "discrete":
        raise ValueError(
            f"task {spec.name} has continuous actions; episodes are recorded (as trajectories, datasets, "
            "evaluations) with the six discrete actions only: drive it through nirl_mj.gym (NavigationEnv)"
        )
    env.random_state.seed(seed)
    timestep = env.reset()
    agent.reset(env, timestep)
    recorder = TrajectoryRecorder(spec.control.decision_period)
    recorder.start(timestep.observation)
    if on_step:
        on_step(0, timestep, None)
    while not timestep.last():
        action = agent.act(timestep)
        if action is None:
            so_far = recorder.finish(_outcome(timestep), seed, spec, spec.control.speed, agent.kind)
            raise EpisodeAbandoned(f"{agent.kind} ended the episode in arena {seed}", so_far)
        timestep = env.step(action)
        recorder.step(action, timestep.observation)
        if on_step:
            on_step(len(recorder), timestep, action)
    return recorder.finish(_outcome(timestep), seed, spec, spec.control.speed, agent.kind)


def _outcome(timestep: dm_env.TimeStep) -> Outcome:
    """How the episode stands; still running counts as a timeout (an episode cut short)."""
    outcome = Outcome(int(timestep.observation["outcome"][0]))
    return Outcome.TIMEOUT if outcome == Outcome.RUNNING else outcome
