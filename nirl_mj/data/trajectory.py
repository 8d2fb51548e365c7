"""Trajectories: the one record of an episode shared by experts, learners and recordings.

A :class:`Trajectory` of T decisions holds the T + 1 states visited (phi(s),
range readings, pose, time) and the T actions taken, plus where it ran (task
spec, arena seed, speed), how it ended and who drove. :class:`TrajectoryRecorder`
builds one during a rollout. The dataset file format lives in
:mod:`nirl_mj.data.dataset`, outcome rates and summaries in :mod:`nirl_mj.data.outcomes`.
"""

from __future__ import annotations

import dataclasses
import enum
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from nirl_mj.data.features import N_ACTIONS, N_FEATURES, N_SENSORS

OUTCOMES = ("target", "collision", "timeout", "physics_error")
"""How an episode can end (lower-case names of :class:`nirl_mj.sim.task.Outcome`, minus RUNNING)."""
TERMINAL_OUTCOMES = ("target", "collision", "physics_error")
"""The outcomes that end in a terminal state; a timeout truncates the episode instead."""
ACTION_KINDS = ("discrete", "continuous")
"""What a trajectory's actions are (a task's ``[control] actions``): ``"discrete"``, an index 0..5 per
decision; ``"continuous"``, the shares (forward speed, yaw rate) in [-1, 1] per decision."""
CONTINUOUS_DIM = 2
"""A continuous action's length: the shares of the forward speed and of the yaw rate."""


def _check_indices(value: Any) -> None:
    """Discrete actions as given: whole numbers in 0..5 (of any integer or float type)."""
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"Trajectory.actions: cannot convert to action indices: {exc}") from None
    if raw.dtype.kind not in "iuf":
        raise ValueError(f"Trajectory.actions: expected indices 0..{N_ACTIONS - 1}, got dtype {raw.dtype}")
    if raw.size and not (np.all(np.isfinite(raw)) and np.all(raw == np.round(raw))
                         and raw.min() >= 0 and raw.max() < N_ACTIONS):  # fmt: skip
        raise ValueError(f"Trajectory.actions: values must be whole numbers in 0..{N_ACTIONS - 1}")


def _frozen_array(value: Any, dtype: type, name: str) -> np.ndarray:
    """``value`` as a read-only array of ``dtype``; a read-only *view* so that the
    caller's own array keeps its flags."""
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"Trajectory.{name}: cannot convert to {np.dtype(dtype).name}: {exc}") from None
    arr = arr.view()
    arr.flags.writeable = False
    return arr


def _outcome_name(outcome: Any) -> str:
    """Accepts an outcome string or an enum such as :class:`nirl_mj.sim.task.Outcome`
    (without importing the heavy task module)."""
    if isinstance(outcome, enum.Enum):
        return outcome.name.lower()
    return outcome


def task_json(task: dict) -> str:
    """A task dict as canonical JSON: equal tasks give equal strings (sorted keys), so a
    dataset stores each task once and a summary counts distinct tasks."""
    return json.dumps(task, sort_keys=True)


def _task_dict(task: Any) -> dict:
    """A TaskSpec is stored as its ``to_dict()``; a dict is taken as is."""
    if hasattr(task, "to_dict") and not isinstance(task, Mapping):
        return task.to_dict()
    return task


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One episode of T decisions (``eq=False``: fields are arrays; compare them field by field).

    Per-state arrays have T + 1 rows (the final state included), per-decision
    arrays T rows:

    - ``features`` (T+1, 16) float32: phi(s_t), layout ``features.FEATURE_NAMES``;
    - ``actions`` (T,) int8: action index 0..5 taken in state t (``features.ACTION_NAMES``); or, on a
      task with continuous actions, (T, 2) float32: the shares in [-1, 1] of the task's forward speed
      (``control.speed`` m/s) and of its largest yaw rate (60 degrees per decision, rad/s) held
      during decision t (``nirl_mj.sim.task.action_scale``);
    - ``ranges`` (T+1, 9) float32: clearance of sensors S1..S9 from the robot's outline, metres;
    - ``poses`` (T+1, 3) float64: x, y (metres), yaw (radians, counter-clockwise);
    - ``times`` (T+1,) float64: seconds since the episode's start.

    Metadata: ``arena_seed`` (the episode's arena seed, 0 <= seed < 2**64),
    ``task`` (``TaskSpec.to_dict()`` of the task it ran on; a TaskSpec is
    converted), ``speed`` (m/s), ``outcome`` (one of :data:`OUTCOMES`; an
    ``Outcome`` enum is converted), ``demonstrator`` (e.g. "planner", "human").

    Arrays are converted to the dtypes above and made read-only views.
    """

    features: np.ndarray
    actions: np.ndarray
    ranges: np.ndarray
    poses: np.ndarray
    times: np.ndarray
    arena_seed: int
    task: dict
    speed: float
    outcome: str
    demonstrator: str

    def __post_init__(self) -> None:
        # Frozen: normalise through object.__setattr__ (only during construction).
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put("features", _frozen_array(self.features, np.float32, "features"))
        continuous = np.ndim(self.actions) == 2  # (T, 2) shares; (T,) indices
        if not continuous:  # checked before the cast to int8, which would wrap 256 to 0 and cut 2.7 to 2
            _check_indices(self.actions)
        put("actions", _frozen_array(self.actions, np.float32 if continuous else np.int8, "actions"))
        put("ranges", _frozen_array(self.ranges, np.float32, "ranges"))
        put("poses", _frozen_array(self.poses, np.float64, "poses"))
        put("times", _frozen_array(self.times, np.float64, "times"))
        if self.actions.ndim != 1 and self.actions.shape[1:] != (CONTINUOUS_DIM,):
            raise ValueError(f"Trajectory.actions: expected shape (T,) (discrete actions) or (T, 2) "
                             f"(continuous ones), got {self.actions.shape}")  # fmt: skip
        t = self.actions.shape[0]
        expected = {
            "features": (t + 1, N_FEATURES),
            "ranges": (t + 1, N_SENSORS),
            "poses": (t + 1, 3),
            "times": (t + 1,),
        }
        for name, shape in expected.items():
            got = getattr(self, name).shape
            if got != shape:
                raise ValueError(
                    f"Trajectory.{name}: expected shape {shape} for T = {t} actions (T + 1 states), got {got}"
                )
        if continuous and not shares_in_range(self.actions):
            raise ValueError("Trajectory.actions: continuous actions are finite shares in [-1, 1]")
        seed = self.arena_seed
        if isinstance(seed, np.integer):
            seed = int(seed)
        if not isinstance(seed, int) or isinstance(seed, bool) or not 0 <= seed < 2**64:
            raise ValueError(f"Trajectory.arena_seed: expected an integer in 0..2**64-1, got {seed!r}")
        put("arena_seed", seed)
        task = _task_dict(self.task)
        if not isinstance(task, dict):
            raise ValueError(
                f"Trajectory.task: expected a TaskSpec.to_dict() dict, got {type(task).__name__}"
            )
        put("task", task)
        try:
            speed = float(self.speed)
        except (TypeError, ValueError):
            raise ValueError(f"Trajectory.speed: expected a number (m/s), got {self.speed!r}") from None
        if not np.isfinite(speed) or speed <= 0:
            raise ValueError(f"Trajectory.speed: expected a finite speed > 0 m/s, got {speed}")
        put("speed", speed)
        outcome = _outcome_name(self.outcome)
        if outcome not in OUTCOMES:
            raise ValueError(f"Trajectory.outcome: expected one of {', '.join(OUTCOMES)}, got {outcome!r}")
        put("outcome", outcome)
        if not isinstance(self.demonstrator, str):
            raise ValueError(f"Trajectory.demonstrator: expected a string, got {self.demonstrator!r}")

    def __len__(self) -> int:
        """T, the number of decisions."""
        return int(self.actions.shape[0])

    @property
    def action_kind(self) -> str:
        """``"continuous"`` for (T, 2) shares, ``"discrete"`` for (T,) indices (:data:`ACTION_KINDS`)."""
        return ACTION_KINDS[self.actions.ndim - 1]

    def pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The demonstration's state-action pairs: (phi(s_t) (T, 16) float32, a_t (T,) int8, or (T, 2)
        float32 for continuous actions)."""
        return self.features[:-1], self.actions

    @property
    def success(self) -> bool:
        """True if the episode reached the target."""
        return self.outcome == "target"

    def with_actions(self, actions: np.ndarray) -> Trajectory:
        """A copy with ``actions`` (T,) replaced, e.g. after relabelling."""
        return dataclasses.replace(self, actions=actions)


def path_length(trajectory: Trajectory) -> float:
    """Metres travelled, summed over decisions."""
    return float(np.sum(np.hypot(*np.diff(trajectory.poses[:, :2], axis=0).T)))


def action_kind(trajectories: Sequence[Trajectory]) -> str:
    """The one action kind of ``trajectories`` (:data:`ACTION_KINDS`; ``"discrete"`` for none); a clear
    error if they mix both."""
    kinds = {t.action_kind for t in trajectories}
    if len(kinds) > 1:
        raise ValueError("the trajectories mix discrete and continuous actions; a dataset holds one kind")
    return kinds.pop() if kinds else "discrete"


def shares_in_range(actions: np.ndarray) -> bool:
    """Whether continuous ``actions`` (..., 2) are finite shares in [-1, 1] (the recorded form)."""
    return bool(np.all(np.isfinite(actions)) and (actions.size == 0 or np.abs(actions).max() <= 1.0))


def require_discrete(trajectories: Sequence[Trajectory], where: str = "the demonstrations") -> None:
    """A clear one-line error if ``trajectories`` (``where``: e.g. the dataset's path) hold continuous
    actions: the learners here (NIRL, BC, DAgger, the IRL baselines, GAIL/AIRL, plugins) choose among
    the six discrete actions."""
    if any(t.action_kind == "continuous" for t in trajectories):
        raise ValueError(
            f"{where}: holds continuous actions (forward and yaw-rate shares), but NIRL, BC, DAgger and "
            f"the IRL and adversarial baselines choose among the {N_ACTIONS} discrete actions: accepted: "
            'demonstrations of discrete actions 0..5 (recorded on a task with [control] actions = "discrete")'
        )


def stack_pairs(trajectories: Sequence[Trajectory]) -> tuple[np.ndarray, np.ndarray]:
    """All state-action pairs of ``trajectories`` concatenated: ((M, 16) float32, (M,) int8); discrete
    actions only (:func:`require_discrete`)."""
    require_discrete(trajectories)
    if not trajectories:
        return np.zeros((0, N_FEATURES), np.float32), np.zeros(0, np.int8)
    return (
        np.concatenate([t.features[:-1] for t in trajectories]),
        np.concatenate([t.actions for t in trajectories]),
    )


class TrajectoryRecorder:
    """Builds a :class:`Trajectory` during a rollout, one observation at a time.

    ``observation`` is nirl_mj's dm_env observation dict (only ``features``,
    ``ranges`` and ``pose`` are read, and copied, since dm_env may reuse its
    buffers). Time is the number of decisions times ``decision_period``
    (seconds). Usage::

        rec = TrajectoryRecorder(spec.control.decision_period)
        ts = env.reset(); rec.start(ts.observation)
        while not ts.last():
            a = policy(ts.observation["features"]); ts = env.step(a); rec.step(a, ts.observation)
        traj = rec.finish("target", seed, spec, spec.control.speed, "planner")
    """

    def __init__(self, decision_period: float, actions: str = "discrete") -> None:
        if not decision_period > 0:
            raise ValueError(f"decision_period must be > 0 seconds, got {decision_period}")
        if actions not in ACTION_KINDS:
            raise ValueError(f"actions = {actions!r}: accepted: {', '.join(ACTION_KINDS)}")
        self._period = float(decision_period)
        self._continuous = actions == "continuous"
        self._reset()

    def _reset(self) -> None:
        self._features: list[np.ndarray] = []
        self._ranges: list[np.ndarray] = []
        self._poses: list[np.ndarray] = []
        self._actions: list = []

    def __len__(self) -> int:
        """Decisions recorded so far."""
        return len(self._actions)

    @property
    def started(self) -> bool:
        """True between :meth:`start` and :meth:`finish`."""
        return bool(self._features)

    def _append(self, observation: Mapping[str, np.ndarray]) -> None:
        # np.array copies: observation arrays may be buffers dm_env overwrites.
        self._features.append(np.array(observation["features"], dtype=np.float32))
        self._ranges.append(np.array(observation["ranges"], dtype=np.float32))
        self._poses.append(np.array(observation["pose"], dtype=np.float64))

    def start(self, observation: Mapping[str, np.ndarray]) -> None:
        """Records the first state (the observation of ``env.reset()``); drops anything recorded."""
        self._reset()
        self._append(observation)

    def step(self, action: int | np.ndarray, observation: Mapping[str, np.ndarray]) -> None:
        """Records ``action`` taken in the previous state (an index 0..5, or for continuous actions the
        two shares in [-1, 1], kept as float32) and the ``observation`` it led to."""
        if not self._features:
            raise RuntimeError("TrajectoryRecorder.step before start: call start(reset observation) first")
        if self._continuous:
            a = np.array(action, dtype=np.float32)
            if a.shape != (CONTINUOUS_DIM,) or not shares_in_range(a):
                raise ValueError(f"a continuous action is two finite shares in [-1, 1], got {action!r}")
        else:
            a = int(action)
            if not 0 <= a < N_ACTIONS:
                raise ValueError(f"action must be in 0..{N_ACTIONS - 1}, got {action!r}")
        self._actions.append(a)
        self._append(observation)

    def finish(
        self, outcome: str | enum.Enum, arena_seed: int, task: Any, speed: float, demonstrator: str
    ) -> Trajectory:
        """The recorded :class:`Trajectory`; the recorder is then empty and can be reused.

        ``task`` is a TaskSpec or its ``to_dict()``; ``outcome`` a string of
        :data:`OUTCOMES` or an ``Outcome`` enum; ``speed`` m/s.
        """
        if not self._features:
            raise RuntimeError("TrajectoryRecorder.finish before start")
        t = len(self._actions)
        traj = Trajectory(
            features=np.stack(self._features),
            actions=(
                np.array(self._actions, dtype=np.float32).reshape(t, CONTINUOUS_DIM)
                if self._continuous
                else np.asarray(self._actions, dtype=np.int8)
            ),
            ranges=np.stack(self._ranges),
            poses=np.stack(self._poses),
            times=np.arange(t + 1, dtype=np.float64) * self._period,
            arena_seed=arena_seed,
            task=task,
            speed=speed,
            outcome=outcome,
            demonstrator=demonstrator,
        )
        self._reset()
        return traj
