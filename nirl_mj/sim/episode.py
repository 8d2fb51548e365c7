"""The one episode loop: an agent drives the robot for one episode in a seeded arena.

Rollouts, evaluation, demonstrations, videos and teleoperation all run episodes
through :func:`run_episode`; what differs between them is the agent and the
per-step hook (a video grabs frames, teleoperation may abandon an episode).

On a task with continuous actions (``[control] actions = "continuous"``) an agent answers with
the shares (forward speed, yaw rate) in [-1, 1] of the task's :func:`~nirl_mj.sim.task.action_scale`
(as the Gymnasium environment takes them), or with a discrete action 0..5, which is driven as
its continuous twin (:func:`~nirl_mj.sim.drive.action_share`): so every expert, the reference
policies and a continuous RL policy drive such a task. The trajectory keeps each share as float32,
and the task is given exactly ``share_twist(share)``, so a recorded episode replays bit for bit
from its arena seed and its actions (here or through ``nirl_mj.gym``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import dm_env
import numpy as np

from nirl_mj.data.trajectory import Trajectory, TrajectoryRecorder
from nirl_mj.sim.drive import action_share
from nirl_mj.sim.task import Outcome, action_scale, share_twist


class Agent(Protocol):
    """Who drives: a demonstrator, a reference policy or a learner's policy."""

    kind: str
    """Short name recorded with every trajectory, e.g. ``"planner"``."""

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        """Called after ``env.reset()``, before the first :meth:`act` of an episode."""

    def act(self, timestep: dm_env.TimeStep) -> int | np.ndarray | None:
        """The action 0..5 for the current timestep (None: end the episode here, unrecorded); on a task
        with continuous actions also the two shares (forward speed, yaw rate) in [-1, 1]."""


StepHook = Callable[[int, dm_env.TimeStep, "int | np.ndarray | None"], None]
"""``on_step(step, timestep, action)``: called with the first timestep (step 0, action None) and
after every decision with the action that led to it, as the agent gave it; ``env.physics`` shows
the state."""


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
    kind = spec.control.actions
    command = action_command(spec)
    env.random_state.seed(seed)
    timestep = env.reset()
    agent.reset(env, timestep)
    recorder = TrajectoryRecorder(spec.control.decision_period, kind)
    recorder.start(timestep.observation)
    if on_step:
        on_step(0, timestep, None)
    while not timestep.last():
        action = agent.act(timestep)
        if action is None:
            so_far = recorder.finish(_outcome(timestep), seed, spec, spec.control.speed, agent.kind)
            raise EpisodeAbandoned(f"{agent.kind} ended the episode in arena {seed}", so_far)
        recorded, taken = command(action)
        timestep = env.step(taken)
        recorder.step(recorded, timestep.observation)
        if on_step:
            on_step(len(recorder), timestep, action)
    return recorder.finish(_outcome(timestep), seed, spec, spec.control.speed, agent.kind)


def action_command(spec) -> Callable:
    """``command(action) -> (what the trajectory records, what the task takes)`` for the task ``spec``:
    the action itself on a discrete task, :func:`continuous_command`'s pair on a continuous one."""
    return continuous_command(spec) if spec.control.actions == "continuous" else _discrete_command


def _discrete_command(action):
    """(what the trajectory records, what the task takes) of a discrete task: the action itself."""
    return action, action


def continuous_command(spec) -> Callable:
    """``command(action) -> (float32 shares recorded, float64 twist taken)`` on a task with continuous
    actions: a discrete action 0..5 as its :func:`action_share`, two shares as they are (float32;
    beyond [-1, 1] by more than a float32 rounding, or not finite, a clear error)."""
    scale = action_scale(spec)

    def command(action):
        integer = isinstance(action, int | np.integer) and not isinstance(action, bool)
        if integer or (isinstance(action, np.ndarray) and action.shape == () and action.dtype.kind in "iu"):
            share = action_share(int(action))
        else:
            try:
                a = np.asarray(action, dtype=np.float64)
            except (TypeError, ValueError):
                a = np.full(3, np.nan)
            if a.shape != (2,) or not np.all(np.isfinite(a)) or np.abs(a).max() > 1.0 + 1e-6:
                raise ValueError(
                    f"task {spec.name} has continuous actions: an action is a discrete one 0..5 or the two "
                    f"shares (forward speed, yaw rate) in [-1, 1] of ({scale[0]:g} m/s, {scale[1]:.4g} "
                    f"rad/s), got {action!r}"
                )
            share = np.clip(a, -1.0, 1.0).astype(np.float32)
        return share, share_twist(share, scale)

    return command


def _outcome(timestep: dm_env.TimeStep) -> Outcome:
    """How the episode stands; still running counts as a timeout (an episode cut short)."""
    outcome = Outcome(int(timestep.observation["outcome"][0]))
    return Outcome.TIMEOUT if outcome == Outcome.RUNNING else outcome
