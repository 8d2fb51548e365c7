"""Trajectories: the one record of an episode shared by experts, learners and recordings.

A :class:`Trajectory` of T decisions holds the T + 1 states visited (phi(s),
range readings, pose, time) and the T actions taken, plus where it ran (task
spec, arena seed, speed), how it ended and who drove. :class:`TrajectoryRecorder`
builds one during a rollout.

This is also the ONLY module that knows the on-disk dataset format
(``docs/DATASET.md``): one compressed NPZ per dataset, plain numpy arrays, no
pickles, so a file reads back with ``np.load(path, allow_pickle=False)``.
:func:`save_dataset` writes atomically; :func:`load_dataset` validates
everything and raises one :class:`DatasetError` naming the file and the problem.
"""

from __future__ import annotations

import contextlib
import dataclasses
import enum
import json
import os
import tempfile
import zipfile
import zlib
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from nirl_mj.data.atomic import FILE_MODE
from nirl_mj.data.features import ACTION_NAMES, FEATURE_NAMES, N_ACTIONS, N_FEATURES, N_SENSORS

FORMAT = "nirl-mj-demos"
"""Value of the ``format`` entry that marks a file as an nirl-mj demonstration dataset."""
VERSION = 1
"""Dataset format version written by :func:`save_dataset`."""
SUPPORTED_VERSIONS = (1,)
"""Dataset format versions :func:`load_dataset` reads."""

OUTCOMES = ("target", "collision", "timeout", "physics_error")
"""How an episode can end (lower-case names of :class:`nirl_mj.sim.task.Outcome`, minus RUNNING)."""

# Column blocks of phi(s) (see nirl_mj.data.features): D (danger 0..7) for the seven
# sensors, V (target sector 1..9), I (target detected 0/1), U (wall flags 0/1).
_D_COLS = slice(0, 7)
_V_COL = 7
_I_COL = 8
_U_COLS = slice(9, 16)

# Array keys of a dataset file with their dtypes (see docs/DATASET.md). Strings
# are checked by kind ("U") since their width depends on the content.
_REQUIRED_KEYS = (
    "format",
    "version",
    "feature_names",
    "lengths",
    "features",
    "actions",
    "ranges",
    "poses",
    "times",
    "arena_seed",
    "speed",
    "outcome",
    "demonstrator",
    "task_index",
    "tasks",
)


class DatasetError(ValueError):
    """A dataset file is missing, unreadable, foreign or inconsistent; the message names
    the file and the problem."""


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
    - ``actions`` (T,) int8: action index 0..5 taken in state t (``features.ACTION_NAMES``);
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
        put("actions", _frozen_array(self.actions, np.int8, "actions"))
        put("ranges", _frozen_array(self.ranges, np.float32, "ranges"))
        put("poses", _frozen_array(self.poses, np.float64, "poses"))
        put("times", _frozen_array(self.times, np.float64, "times"))
        if self.actions.ndim != 1:
            raise ValueError(f"Trajectory.actions: expected shape (T,), got {self.actions.shape}")
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
        if t and (self.actions.min() < 0 or self.actions.max() >= N_ACTIONS):
            raise ValueError(f"Trajectory.actions: values must be in 0..{N_ACTIONS - 1}")
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

    def pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The demonstration's state-action pairs: (phi(s_t) (T, 16) float32, a_t (T,) int8)."""
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


def stack_pairs(trajectories: Sequence[Trajectory]) -> tuple[np.ndarray, np.ndarray]:
    """All state-action pairs of ``trajectories`` concatenated: ((M, 16) float32, (M,) int8)."""
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

    def __init__(self, decision_period: float) -> None:
        if not decision_period > 0:
            raise ValueError(f"decision_period must be > 0 seconds, got {decision_period}")
        self._period = float(decision_period)
        self._reset()

    def _reset(self) -> None:
        self._features: list[np.ndarray] = []
        self._ranges: list[np.ndarray] = []
        self._poses: list[np.ndarray] = []
        self._actions: list[int] = []

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

    def step(self, action: int, observation: Mapping[str, np.ndarray]) -> None:
        """Records ``action`` taken in the previous state and the ``observation`` it led to."""
        if not self._features:
            raise RuntimeError("TrajectoryRecorder.step before start: call start(reset observation) first")
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
            actions=np.asarray(self._actions, dtype=np.int8),
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


# -- dataset files ---------------------------------------------------------------------


def _task_json(task: dict) -> str:
    # sort_keys: equal tasks give equal strings, so ``tasks`` holds each once.
    return json.dumps(task, sort_keys=True)


def _to_arrays(trajectories: Sequence[Trajectory]) -> dict[str, np.ndarray]:
    """The file's arrays (docs/DATASET.md) from trajectories."""
    tasks: dict[str, int] = {}
    task_index = []
    for t in trajectories:
        try:
            key = _task_json(t.task)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"task dict is not JSON-serialisable: {exc}") from None
        task_index.append(tasks.setdefault(key, len(tasks)))
    seeds = [t.arena_seed for t in trajectories]
    # int64 unless a seed needs the 64th bit.
    seed_dtype = np.int64 if max(seeds) < 2**63 else np.uint64
    return {
        "format": np.array(FORMAT),
        "version": np.array(VERSION, dtype=np.int64),
        "feature_names": np.array(FEATURE_NAMES),
        "lengths": np.array([len(t) for t in trajectories], dtype=np.int64),
        "features": np.concatenate([t.features for t in trajectories]).astype(np.float32, copy=False),
        "actions": np.concatenate([t.actions for t in trajectories]).astype(np.int8, copy=False),
        "ranges": np.concatenate([t.ranges for t in trajectories]).astype(np.float32, copy=False),
        "poses": np.concatenate([t.poses for t in trajectories]).astype(np.float64, copy=False),
        "times": np.concatenate([t.times for t in trajectories]).astype(np.float64, copy=False),
        "arena_seed": np.array(seeds, dtype=seed_dtype),
        "speed": np.array([t.speed for t in trajectories], dtype=np.float64),
        "outcome": np.array([t.outcome for t in trajectories], dtype=np.str_),
        "demonstrator": np.array([t.demonstrator for t in trajectories], dtype=np.str_),
        "task_index": np.array(task_index, dtype=np.int64),
        "tasks": np.array(list(tasks), dtype=np.str_),
    }


def save_dataset(
    path: str | os.PathLike, trajectories: Sequence[Trajectory], overwrite: bool = False
) -> Path:
    """Writes ``trajectories`` to ``path`` (exactly that name; no suffix is added) as an
    NPZ dataset; returns the path.

    Atomic: the file is written to a temporary file in the same directory,
    fsynced and renamed over ``path``, so readers see the old file or the whole
    new one, never a partial one. Refuses an existing ``path`` unless
    ``overwrite``; refuses an empty list and data :func:`load_dataset` would
    reject (so nothing is written that cannot be read back).
    """
    path = Path(path)
    trajectories = list(trajectories)
    if not trajectories:
        raise ValueError(f"refusing to save an empty dataset to {path}: no trajectories given")
    for i, t in enumerate(trajectories):
        if not isinstance(t, Trajectory):
            raise ValueError(f"trajectories[{i}] is a {type(t).__name__}, not a Trajectory")
    if path.exists() and not overwrite:
        raise FileExistsError(
            f"{path} already exists; pass overwrite=True (or choose another path) to replace it"
        )
    arrays = _to_arrays(trajectories)
    _validate(arrays, f"refusing to save {path}")
    directory = path.parent if str(path.parent) else Path(".")
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        os.fchmod(fd, FILE_MODE)  # mkstemp's 0600 would survive the rename
        with os.fdopen(fd, "wb") as f:
            # Looked up on np at call time (tests interrupt the write through it).
            np.savez_compressed(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        if overwrite:
            os.replace(tmp_name, path)
        else:
            _link_no_clobber(tmp_name, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp_name)
        raise
    _fsync_directory(directory)
    return path


def _link_no_clobber(tmp_name: str, path: Path) -> None:
    """Moves ``tmp_name`` to ``path`` unless ``path`` appeared meanwhile (hard link:
    atomic and fails on an existing target); falls back to a rename where the
    file system has no hard links."""
    try:
        os.link(tmp_name, path)
    except FileExistsError:
        raise FileExistsError(
            f"{path} already exists; pass overwrite=True (or choose another path) to replace it"
        ) from None
    except OSError:
        if path.exists():
            raise FileExistsError(
                f"{path} already exists; pass overwrite=True (or choose another path) to replace it"
            ) from None
        os.replace(tmp_name, path)
        return
    os.unlink(tmp_name)


def _fsync_directory(directory: Path) -> None:
    # Makes the rename itself durable; not possible on every platform.
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def load_dataset(path: str | os.PathLike) -> list[Trajectory]:
    """Reads and validates a dataset written by :func:`save_dataset`.

    Raises :class:`DatasetError` naming the file and the problem: missing file,
    not an NPZ (or truncated), a foreign NPZ, an unsupported version, another
    feature layout, a missing key, a wrong dtype or shape, lengths that do not
    match the rows, NaN/inf, values out of range, an empty dataset.
    """
    path = Path(path)
    where = str(path)
    if not path.exists():
        raise DatasetError(f"{where}: no such file")
    if not path.is_file():
        raise DatasetError(f"{where}: not a regular file")
    arrays = _read_npz(path)
    _validate(arrays, where)
    return _from_arrays(arrays, where)


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of the NPZ at ``path``, read eagerly (so truncation shows up here)."""
    where = str(path)
    not_npz = f"{where}: not an NPZ dataset file (not a zip archive, or truncated)"
    try:
        npz = np.load(path, allow_pickle=False)
    except (zipfile.BadZipFile, EOFError, OSError, zlib.error) as exc:
        raise DatasetError(f"{not_npz}: {exc}") from None
    except ValueError:
        # np.load falls back to unpickling files that are neither .npy nor zip;
        # its message (advice to allow pickles) would mislead here.
        raise DatasetError(f"{not_npz}: it does not start with a zip or .npy header") from None
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise DatasetError(f"{not_npz}: it holds a single .npy array")
    arrays = {}
    with npz:
        for key in npz.files:
            try:
                arrays[key] = npz[key]
            except ValueError as exc:
                if "pickle" in str(exc).lower() or "object" in str(exc).lower():
                    raise DatasetError(
                        f"{where}: entry {key!r} holds pickled Python objects; datasets are plain arrays only"
                    ) from None
                raise DatasetError(f"{where}: entry {key!r} is corrupt or truncated: {exc}") from None
            except (zipfile.BadZipFile, EOFError, OSError, zlib.error) as exc:
                raise DatasetError(f"{where}: entry {key!r} is corrupt or truncated: {exc}") from None
    return arrays


def _scalar_string(arr: np.ndarray) -> str | None:
    if arr.shape == () and arr.dtype.kind == "U":
        return str(arr)
    return None


def _validate(a: Mapping[str, np.ndarray], where: str) -> None:
    """Checks a dataset's arrays (docs/DATASET.md); raises :class:`DatasetError` prefixed
    with ``where``. Order matters: identity (format, version, layout) first, so a
    foreign or newer file is reported as such rather than as a missing key."""

    def fail(msg: str) -> None:
        raise DatasetError(f"{where}: {msg}")

    if "format" not in a:
        fail(f"not an nirl-mj dataset: no 'format' entry (expected format {FORMAT!r}); keys: {sorted(a)}")
    fmt = _scalar_string(a["format"])
    if fmt != FORMAT:
        shown = fmt if fmt is not None else a["format"]
        fail(f"not an nirl-mj dataset: format is {shown!r}, expected {FORMAT!r}")
    if "version" not in a:
        fail("missing key 'version'")
    version = a["version"]
    if version.shape != () or version.dtype.kind not in "iu":
        fail(f"'version' must be an integer scalar, got dtype {version.dtype} shape {version.shape}")
    if int(version) not in SUPPORTED_VERSIONS:
        fail(
            f"unsupported dataset version {int(version)}; this nirl-mj reads version(s) "
            f"{', '.join(map(str, SUPPORTED_VERSIONS))}"
        )
    missing = [k for k in _REQUIRED_KEYS if k not in a]
    if missing:
        fail(f"missing key(s) {', '.join(missing)}")
    names = a["feature_names"]
    if names.dtype.kind != "U" or names.shape != (N_FEATURES,) or tuple(names.tolist()) != FEATURE_NAMES:
        fail(
            f"feature layout {names.tolist()} differs from this nirl-mj's phi(s) layout "
            f"{list(FEATURE_NAMES)}; the dataset was recorded with other features"
        )

    def check(key: str, kinds: str, dtypes: tuple[str, ...] | None, ndim_shape: tuple) -> np.ndarray:
        arr = a[key]
        if arr.dtype.kind not in kinds or (dtypes is not None and arr.dtype.name not in dtypes):
            want = " or ".join(dtypes) if dtypes else "unicode string"
            fail(f"wrong dtype for {key!r}: {arr.dtype}, expected {want}")
        if arr.ndim != len(ndim_shape) or any(
            s is not None and got != s for got, s in zip(arr.shape, ndim_shape, strict=False)
        ):
            want = "(" + ", ".join("n" if s is None else str(s) for s in ndim_shape) + ")"
            fail(f"wrong shape for {key!r}: {arr.shape}, expected {want}")
        return arr

    lengths = check("lengths", "i", ("int64",), (None,))
    n = lengths.shape[0]
    if n == 0:
        fail("empty dataset: no trajectories")
    per_traj = {
        "arena_seed": ("iu", ("int64", "uint64")),
        "speed": ("f", ("float64",)),
        "outcome": ("U", None),
        "demonstrator": ("U", None),
        "task_index": ("i", ("int64",)),
    }
    for key, (kinds, dtypes) in per_traj.items():
        check(key, kinds, dtypes, (None,))
        if a[key].shape[0] != n:
            fail(f"inconsistent lengths: {key!r} has {a[key].shape[0]} entries for {n} trajectories")
    tasks = check("tasks", "U", None, (None,))
    features = check("features", "f", ("float32",), (None, N_FEATURES))
    actions = check("actions", "i", ("int8",), (None,))
    ranges = check("ranges", "f", ("float32",), (None, N_SENSORS))
    poses = check("poses", "f", ("float64",), (None, 3))
    times = check("times", "f", ("float64",), (None,))

    if np.any(lengths < 0):
        negative = lengths[lengths < 0][:5].tolist()
        fail(f"inconsistent lengths: negative trajectory length(s) in 'lengths' {negative}")
    n_actions = int(lengths.sum())
    n_states = n_actions + n
    if actions.shape[0] != n_actions:
        fail(f"inconsistent lengths: 'actions' has {actions.shape[0]} rows but sum(lengths) = {n_actions}")
    for key, arr in (("features", features), ("ranges", ranges), ("poses", poses), ("times", times)):
        if arr.shape[0] != n_states:
            fail(f"inconsistent lengths: {key!r} has {arr.shape[0]} rows but sum(lengths + 1) = {n_states}")

    for key, arr in (("features", features), ("ranges", ranges), ("poses", poses), ("times", times)):
        bad = ~np.isfinite(arr)
        if bad.any():
            row = int(np.argwhere(bad)[0][0])
            fail(f"non-finite value (NaN or inf) in {key!r} at row {row}")
    speed = a["speed"]
    if not np.all(np.isfinite(speed)):
        fail(f"non-finite value (NaN or inf) in 'speed' at trajectory {int(np.argmax(~np.isfinite(speed)))}")
    if np.any(speed <= 0):
        fail(f"speed out of range: trajectory {int(np.argmax(speed <= 0))} has speed <= 0 m/s")
    if a["arena_seed"].dtype.kind == "i" and np.any(a["arena_seed"] < 0):
        fail("arena_seed out of range: negative seed")

    def check_values(cols: slice | int, allowed: np.ndarray, what: str) -> None:
        block = features[:, cols]
        bad = ~np.isin(block, allowed)
        if bad.any():
            idx = np.argwhere(bad)[0]
            row = int(idx[0])
            col = (cols.start + int(idx[1])) if isinstance(cols, slice) else cols
            fail(
                f"{what} out of range: features[{row}, {col}] ({FEATURE_NAMES[col]}) = "
                f"{features[row, col]!r}, allowed {allowed.astype(int).tolist()}"
            )

    check_values(_D_COLS, np.arange(8, dtype=np.float32), "danger level D")
    check_values(_V_COL, np.arange(1, 10, dtype=np.float32), "target sector V")
    check_values(_I_COL, np.array([0, 1], np.float32), "target-detected flag I")
    check_values(_U_COLS, np.array([0, 1], np.float32), "wall flag U")
    if n_actions and (actions.min() < 0 or actions.max() >= N_ACTIONS):
        row = int(np.argmax((actions < 0) | (actions >= N_ACTIONS)))
        fail(f"action out of range: actions[{row}] = {int(actions[row])}, allowed 0..{N_ACTIONS - 1}")

    unknown = sorted(set(a["outcome"].tolist()) - set(OUTCOMES))
    if unknown:
        fail(f"unknown outcome(s) {unknown}; allowed {', '.join(OUTCOMES)}")
    task_index = a["task_index"]
    if np.any((task_index < 0) | (task_index >= tasks.shape[0])):
        fail(f"task_index out of range: values must be in 0..{tasks.shape[0] - 1}")
    for i, text in enumerate(tasks.tolist()):
        try:
            task = json.loads(text)
        except json.JSONDecodeError as exc:
            fail(f"tasks[{i}] is not valid JSON: {exc}")
        if not isinstance(task, dict):
            fail(f"tasks[{i}] is not a JSON object (a TaskSpec.to_dict())")

    # Times must not run backwards within a trajectory (they restart at each one).
    starts = np.concatenate([[0], np.cumsum(lengths + 1)[:-1]])
    dt = np.diff(times)
    dt[starts[1:] - 1] = 0.0  # across trajectory boundaries
    if np.any(dt < 0):
        fail(f"'times' decrease within a trajectory at row {int(np.argmax(dt < 0)) + 1}")


def _from_arrays(a: Mapping[str, np.ndarray], where: str) -> list[Trajectory]:
    lengths = a["lengths"]
    tasks = [json.loads(s) for s in a["tasks"].tolist()]
    s_end = np.cumsum(lengths + 1)
    a_end = np.cumsum(lengths)
    out = []
    for i, t in enumerate(lengths.tolist()):
        s1, s0 = int(s_end[i]), int(s_end[i]) - t - 1
        a1, a0 = int(a_end[i]), int(a_end[i]) - t
        try:
            out.append(
                Trajectory(
                    features=a["features"][s0:s1],
                    actions=a["actions"][a0:a1],
                    ranges=a["ranges"][s0:s1],
                    poses=a["poses"][s0:s1],
                    times=a["times"][s0:s1],
                    arena_seed=int(a["arena_seed"][i]),
                    # A fresh dict per trajectory: callers may mutate it.
                    task=json.loads(json.dumps(tasks[int(a["task_index"][i])])),
                    speed=float(a["speed"][i]),
                    outcome=str(a["outcome"][i]),
                    demonstrator=str(a["demonstrator"][i]),
                )
            )
        except ValueError as exc:  # pragma: no cover - _validate should catch all of these
            raise DatasetError(f"{where}: trajectory {i}: {exc}") from None
    return out


# -- summary -----------------------------------------------------------------------


def summarise(trajectories: Sequence[Trajectory]) -> dict[str, Any]:
    """Summary of a dataset for ``nirl-mj inspect``: outcome rates (fractions), steps per
    episode (decisions), the action histogram, episodes per demonstrator and per
    speed (m/s), number of distinct tasks."""
    n = len(trajectories)
    outcomes = Counter(t.outcome for t in trajectories)
    steps = np.array([len(t) for t in trajectories], dtype=np.int64)
    counts = np.zeros(N_ACTIONS, dtype=np.int64)
    for t in trajectories:
        counts += np.bincount(t.actions, minlength=N_ACTIONS)
    total = int(counts.sum())
    return {
        "episodes": n,
        "success_rate": outcomes["target"] / n if n else 0.0,
        "collision_rate": outcomes["collision"] / n if n else 0.0,
        "timeout_rate": outcomes["timeout"] / n if n else 0.0,
        "physics_error_rate": outcomes["physics_error"] / n if n else 0.0,
        "pairs": total,
        "mean_steps": float(steps.mean()) if n else 0.0,
        "min_steps": int(steps.min()) if n else 0,
        "max_steps": int(steps.max()) if n else 0,
        "action_counts": {name: int(c) for name, c in zip(ACTION_NAMES, counts, strict=True)},
        "action_fractions": {
            name: (float(c) / total if total else 0.0) for name, c in zip(ACTION_NAMES, counts, strict=True)
        },
        "demonstrators": dict(sorted(Counter(t.demonstrator for t in trajectories).items())),
        "speeds": dict(sorted(Counter(t.speed for t in trajectories).items())),
        "tasks": len({_task_json(t.task) for t in trajectories}),
    }
