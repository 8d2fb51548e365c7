"""The on-disk dataset format (``docs/DATASET.md``): the ONLY module that knows it (``experiments.reuse``
compares two files array by array, without reading the format).

One compressed NPZ per dataset, plain numpy arrays, no pickles, so a file reads
back with ``np.load(path, allow_pickle=False)``. :func:`save_dataset` writes
atomically; :func:`load_dataset` validates everything and raises one
:class:`DatasetError` naming the file and the problem.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import zipfile
import zlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from nirl_mj.data.atomic import AtomicFile, refuse_existing
from nirl_mj.data.features import FEATURE_NAMES, N_ACTIONS, N_FEATURES, N_SENSORS
from nirl_mj.data.trajectory import ACTION_KINDS, CONTINUOUS_DIM, OUTCOMES, Trajectory, action_kind, task_json

FORMAT = "nirl-mj-demos"
"""Value of the ``format`` entry that marks a file as an nirl-mj demonstration dataset."""
VERSION = 1
"""Dataset format version :func:`save_dataset` writes for discrete actions (files as they always were)."""
CONTINUOUS_VERSION = 2
"""The version it writes for continuous actions: version 1 plus the ``action_kind`` entry, and
``actions`` float32 (A, 2) where ``action_kind`` is ``"continuous"`` (docs/DATASET.md)."""
SUPPORTED_VERSIONS = (1, 2)
"""Dataset format versions :func:`load_dataset` reads."""

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
# key: (dtype kinds, dtype names (None: a unicode string of any width), shape (None: any
# length)), in the order they are checked: ``lengths`` first, the others are counted against it.
_SCHEMA: dict[str, tuple[str, tuple[str, ...] | None, tuple[int | None, ...]]] = {
    "lengths": ("i", ("int64",), (None,)),
    "arena_seed": ("iu", ("int64", "uint64"), (None,)),
    "speed": ("f", ("float64",), (None,)),
    "outcome": ("U", None, (None,)),
    "demonstrator": ("U", None, (None,)),
    "task_index": ("i", ("int64",), (None,)),
    "tasks": ("U", None, (None,)),
    "features": ("f", ("float32",), (None, N_FEATURES)),
    "actions": ("i", ("int8",), (None,)),
    "ranges": ("f", ("float32",), (None, N_SENSORS)),
    "poses": ("f", ("float64",), (None, 3)),
    "times": ("f", ("float64",), (None,)),
}
# ``actions`` of a dataset of continuous actions (version 2, ``action_kind`` "continuous").
_CONTINUOUS_ACTIONS = ("f", ("float32",), (None, CONTINUOUS_DIM))
_PER_TRAJECTORY = ("arena_seed", "speed", "outcome", "demonstrator", "task_index")
_PER_STATE = ("features", "ranges", "poses", "times")
# Column blocks of phi(s) (see nirl_mj.data.features) and their allowed values: D (danger
# 0..7) for the seven sensors, V (target sector 1..9), I (target detected 0/1), U (wall flags 0/1).
_FEATURE_VALUES = (
    (slice(0, 7), np.arange(8, dtype=np.float32), "danger level D"),
    (slice(7, 8), np.arange(1, 10, dtype=np.float32), "target sector V"),
    (slice(8, 9), np.array([0, 1], np.float32), "target-detected flag I"),
    (slice(9, 16), np.array([0, 1], np.float32), "wall flag U"),
)


class DatasetError(ValueError):
    """A dataset file is missing, unreadable, foreign or inconsistent; the message names
    the file and the problem."""


# -- writing ---------------------------------------------------------------------------


def _to_arrays(trajectories: Sequence[Trajectory]) -> dict[str, np.ndarray]:
    """The file's arrays (docs/DATASET.md) from trajectories."""
    tasks: dict[str, int] = {}
    task_index = []
    for t in trajectories:
        try:
            key = task_json(t.task)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"task dict is not JSON-serialisable: {exc}") from None
        task_index.append(tasks.setdefault(key, len(tasks)))
    seeds = [t.arena_seed for t in trajectories]
    # int64 unless a seed needs the 64th bit.
    seed_dtype = np.int64 if max(seeds) < 2**63 else np.uint64
    continuous = action_kind(trajectories) == "continuous"
    # Discrete actions: version 1, the very arrays of files written before continuous actions existed.
    kind = {"action_kind": np.array("continuous")} if continuous else {}
    return {
        "format": np.array(FORMAT),
        "version": np.array(CONTINUOUS_VERSION if continuous else VERSION, dtype=np.int64),
        **kind,
        "feature_names": np.array(FEATURE_NAMES),
        "lengths": np.array([len(t) for t in trajectories], dtype=np.int64),
        "features": np.concatenate([t.features for t in trajectories]).astype(np.float32, copy=False),
        "actions": np.concatenate([t.actions for t in trajectories]).astype(
            np.float32 if continuous else np.int8, copy=False
        ),
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

    Atomic (:class:`nirl_mj.data.atomic.AtomicFile`): readers see the old file or the
    whole new one, never a partial one. Refuses an existing ``path`` unless
    ``overwrite``; refuses an empty list, trajectories mixing discrete and continuous
    actions and data :func:`load_dataset` would reject (so nothing is written that cannot be
    read back). Discrete actions are written as version 1, continuous ones as version 2.
    """
    path = Path(path)
    trajectories = list(trajectories)
    if not trajectories:
        raise ValueError(f"refusing to save an empty dataset to {path}: no trajectories given")
    for i, t in enumerate(trajectories):
        if not isinstance(t, Trajectory):
            raise ValueError(f"trajectories[{i}] is a {type(t).__name__}, not a Trajectory")
    refuse_existing(path, overwrite)
    arrays = _to_arrays(trajectories)
    _validate(arrays, f"refusing to save {path}")
    with AtomicFile(path, overwrite=overwrite) as target, open(target.tmp, "wb") as f:
        # Looked up on np at call time (tests interrupt the write through it).
        np.savez_compressed(f, **arrays)
    return path


# -- reading ---------------------------------------------------------------------------


def load_dataset(path: str | os.PathLike) -> list[Trajectory]:
    """Reads and validates a dataset written by :func:`save_dataset`.

    Raises :class:`DatasetError` naming the file and the problem: missing file,
    not an NPZ (or truncated), a foreign NPZ, an unsupported version, another
    feature layout, a missing key, a wrong dtype or shape, lengths that do not
    match the rows, NaN/inf, values out of range, an empty dataset. The trajectories'
    actions are (T,) int8 or, in a dataset of continuous actions, (T, 2) float32 shares
    (``Trajectory.action_kind``; learners of discrete actions refuse those:
    :func:`nirl_mj.data.trajectory.require_discrete`).
    """
    path = Path(path)
    where = str(path)
    if not path.exists():
        raise DatasetError(f"{where}: no such file")
    if not path.is_file():
        raise DatasetError(f"{where}: not a regular file")
    if not os.access(path, os.R_OK):
        raise DatasetError(f"{where}: not readable (permission denied)")
    arrays = _read_npz(path)
    _validate(arrays, where)
    return _from_arrays(arrays, where)


def dataset_digest(trajectories: Sequence[Trajectory]) -> str:
    """sha256 of the dataset's content (every array as :func:`save_dataset` would store it), so two
    files holding the same demonstrations match whatever their zip metadata, and any change shows."""
    h = hashlib.sha256()
    for key, array in sorted(_to_arrays(trajectories).items()):
        array = np.ascontiguousarray(array)
        h.update(f"{key}|{array.dtype.str}|{array.shape}|".encode())
        h.update(array.tobytes())
    return h.hexdigest()


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
        names = npz.zip.namelist()
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise DatasetError(f"{where}: the archive holds entry {twice[0]!r} twice; which one is meant is "
                               "ambiguous, so the file is refused")  # fmt: skip
        for key in npz.files:
            _check_size(npz.zip, f"{key}.npy", where)  # before numpy allocates what a header claims
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


def _check_size(archive: zipfile.ZipFile, name: str, where: str) -> None:
    """Refuses an entry whose .npy header claims more data than the entry holds."""
    if name not in archive.namelist():
        return
    info = archive.getinfo(name)
    try:
        with archive.open(name) as f:
            version = np.lib.format.read_magic(f)
            read = (
                np.lib.format.read_array_header_1_0
                if version == (1, 0)
                else np.lib.format.read_array_header_2_0
            )
            shape, _, dtype = read(f)
            header = f.tell()
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise DatasetError(f"{where}: entry {name!r} has no valid .npy header: {exc}") from None
    needed = math.prod(shape) * dtype.itemsize
    if needed > info.file_size - header:
        raise DatasetError(f"{where}: entry {name!r} claims shape {shape} ({needed} bytes) but holds "
                           f"{info.file_size - header} bytes: corrupt")  # fmt: skip


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


# -- validation ------------------------------------------------------------------------


class _Invalid(Exception):
    """One problem with a dataset's arrays; :func:`_validate` adds where they came from."""


def _validate(a: Mapping[str, np.ndarray], where: str) -> None:
    """Checks a dataset's arrays (docs/DATASET.md); raises :class:`DatasetError` prefixed
    with ``where``. Runs :data:`_CHECKS` in order, each assuming the ones before it passed:
    identity (format, version, layout) first, so a foreign or newer file is reported as
    such rather than as a missing key."""
    try:
        for check in _CHECKS:
            check(a)
    except _Invalid as exc:
        raise DatasetError(f"{where}: {exc}") from None


def _scalar_string(arr: np.ndarray) -> str | None:
    if arr.shape == () and arr.dtype.kind == "U":
        return str(arr)
    return None


def _check_format(a: Mapping[str, np.ndarray]) -> None:
    if "format" not in a:
        raise _Invalid(
            f"not an nirl-mj dataset: no 'format' entry (expected format {FORMAT!r}); keys: {sorted(a)}"
        )
    fmt = _scalar_string(a["format"])
    if fmt != FORMAT:
        shown = fmt if fmt is not None else a["format"]
        raise _Invalid(f"not an nirl-mj dataset: format is {shown!r}, expected {FORMAT!r}")


def _check_version(a: Mapping[str, np.ndarray]) -> None:
    if "version" not in a:
        raise _Invalid("missing key 'version'")
    version = a["version"]
    if version.shape != () or version.dtype.kind not in "iu":
        raise _Invalid(
            f"'version' must be an integer scalar, got dtype {version.dtype} shape {version.shape}"
        )
    if int(version) not in SUPPORTED_VERSIONS:
        raise _Invalid(
            f"unsupported dataset version {int(version)}; this nirl-mj reads version(s) "
            f"{', '.join(map(str, SUPPORTED_VERSIONS))}"
        )


def _check_keys(a: Mapping[str, np.ndarray]) -> None:
    missing = [k for k in _REQUIRED_KEYS if k not in a]
    if missing:
        raise _Invalid(f"missing key(s) {', '.join(missing)}")
    names = a["feature_names"]
    if names.dtype.kind != "U" or names.shape != (N_FEATURES,) or tuple(names.tolist()) != FEATURE_NAMES:
        raise _Invalid(
            f"feature layout {names.tolist()} differs from this nirl-mj's phi(s) layout "
            f"{list(FEATURE_NAMES)}; the dataset was recorded with other features"
        )


def _kind(a: Mapping[str, np.ndarray]) -> str:
    """The action kind of checked arrays: version 1 holds discrete actions, version 2 says which."""
    return str(a["action_kind"]) if int(a["version"]) >= CONTINUOUS_VERSION else "discrete"


def _check_action_kind(a: Mapping[str, np.ndarray]) -> None:
    if int(a["version"]) < CONTINUOUS_VERSION:
        return
    if "action_kind" not in a:
        raise _Invalid(f"missing key 'action_kind' (a version {int(a['version'])} dataset says which actions "
                       f"it holds: {', '.join(ACTION_KINDS)})")  # fmt: skip
    kind = _scalar_string(a["action_kind"])
    if kind not in ACTION_KINDS:
        shown = kind if kind is not None else a["action_kind"]
        raise _Invalid(f"unknown action_kind {shown!r}; accepted: {', '.join(ACTION_KINDS)}")


def _check_array(a: Mapping[str, np.ndarray], key: str) -> None:
    """The dtype and shape of ``a[key]`` against :data:`_SCHEMA` (``actions`` by the action kind)."""
    arr = a[key]
    continuous_actions = key == "actions" and _kind(a) == "continuous"
    kinds, dtypes, shape = _CONTINUOUS_ACTIONS if continuous_actions else _SCHEMA[key]
    if arr.dtype.kind not in kinds or (dtypes is not None and arr.dtype.name not in dtypes):
        want = " or ".join(dtypes) if dtypes else "unicode string"
        raise _Invalid(f"wrong dtype for {key!r}: {arr.dtype}, expected {want}")
    if arr.ndim != len(shape) or any(
        s is not None and got != s for got, s in zip(arr.shape, shape, strict=False)
    ):
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise _Invalid(f"wrong shape for {key!r}: {arr.shape}, expected {want}")


def _check_schema(a: Mapping[str, np.ndarray]) -> None:
    _check_array(a, "lengths")
    n = a["lengths"].shape[0]
    if n == 0:
        raise _Invalid("empty dataset: no trajectories")
    for key in list(_SCHEMA)[1:]:
        _check_array(a, key)
        if key in _PER_TRAJECTORY and a[key].shape[0] != n:
            raise _Invalid(
                f"inconsistent lengths: {key!r} has {a[key].shape[0]} entries for {n} trajectories"
            )


def _check_counts(a: Mapping[str, np.ndarray]) -> None:
    """Rows of the per-decision and per-state arrays against ``lengths``."""
    lengths = a["lengths"]
    if np.any(lengths < 0):
        negative = lengths[lengths < 0][:5].tolist()
        raise _Invalid(f"inconsistent lengths: negative trajectory length(s) in 'lengths' {negative}")
    n_actions = int(lengths.sum())
    n_states = n_actions + lengths.shape[0]
    if a["actions"].shape[0] != n_actions:
        raise _Invalid(
            f"inconsistent lengths: 'actions' has {a['actions'].shape[0]} rows but sum(lengths) = {n_actions}"
        )
    for key in _PER_STATE:
        if a[key].shape[0] != n_states:
            raise _Invalid(
                f"inconsistent lengths: {key!r} has {a[key].shape[0]} rows but sum(lengths + 1) = {n_states}"
            )


def _check_finite(a: Mapping[str, np.ndarray]) -> None:
    for key in (*_PER_STATE, "actions") if _kind(a) == "continuous" else _PER_STATE:
        bad = ~np.isfinite(a[key])
        if bad.any():
            raise _Invalid(f"non-finite value (NaN or inf) in {key!r} at row {int(np.argwhere(bad)[0][0])}")
    speed = a["speed"]
    if not np.all(np.isfinite(speed)):
        raise _Invalid(
            f"non-finite value (NaN or inf) in 'speed' at trajectory {int(np.argmax(~np.isfinite(speed)))}"
        )


def _check_speed_and_seed(a: Mapping[str, np.ndarray]) -> None:
    speed = a["speed"]
    if np.any(speed <= 0):
        raise _Invalid(f"speed out of range: trajectory {int(np.argmax(speed <= 0))} has speed <= 0 m/s")
    if a["arena_seed"].dtype.kind == "i" and np.any(a["arena_seed"] < 0):
        raise _Invalid("arena_seed out of range: negative seed")


def _check_features(a: Mapping[str, np.ndarray]) -> None:
    """phi(s)'s blocks hold only their allowed values (:data:`_FEATURE_VALUES`)."""
    features = a["features"]
    for cols, allowed, what in _FEATURE_VALUES:
        bad = ~np.isin(features[:, cols], allowed)
        if bad.any():
            row, offset = (int(i) for i in np.argwhere(bad)[0])
            col = cols.start + offset
            raise _Invalid(
                f"{what} out of range: features[{row}, {col}] ({FEATURE_NAMES[col]}) = "
                f"{features[row, col]!r}, allowed {allowed.astype(int).tolist()}"
            )


def _check_actions(a: Mapping[str, np.ndarray]) -> None:
    actions = a["actions"]
    if _kind(a) == "continuous":
        if actions.shape[0] and np.abs(actions).max() > 1.0:
            row = int(np.argmax(np.abs(actions).max(axis=1) > 1.0))
            raise _Invalid(f"continuous action out of range: actions[{row}] = {actions[row].tolist()}, "
                           "allowed shares (forward speed, yaw rate) in [-1, 1]")  # fmt: skip
        return
    if actions.shape[0] and (actions.min() < 0 or actions.max() >= N_ACTIONS):
        row = int(np.argmax((actions < 0) | (actions >= N_ACTIONS)))
        raise _Invalid(
            f"action out of range: actions[{row}] = {int(actions[row])}, allowed 0..{N_ACTIONS - 1}"
        )


def _check_outcomes(a: Mapping[str, np.ndarray]) -> None:
    unknown = sorted(set(a["outcome"].tolist()) - set(OUTCOMES))
    if unknown:
        raise _Invalid(f"unknown outcome(s) {unknown}; allowed {', '.join(OUTCOMES)}")


TASK_RULES: list[Callable[[dict, str], object]] = []
READ_TASK_KEYS = (("arena", "target"), ("arena", "target_radius"), ("control", "speed"),
                  ("control", "decision_period"), ("sensing", "range"),
                  ("sensing", "danger7_clearance"))  # fmt: skip
"""The keys of a task record that readers of trajectories take from it directly (``data.outcomes``,
``data.transitions``, ``inspect.recording``)."""
"""Checks of a task record beyond its shape, each ``rule(task, where)`` raising ``ValueError``:
the task file's rules live in ``nirl_mj.sim.spec``, which registers them here when imported (the
data layer cannot import the simulation's), so a record with a negative speed or an unknown key is
refused as a task file with it would be."""


def _check_tasks(a: Mapping[str, np.ndarray]) -> None:
    tasks, task_index = a["tasks"], a["task_index"]
    if np.any((task_index < 0) | (task_index >= tasks.shape[0])):
        raise _Invalid(f"task_index out of range: values must be in 0..{tasks.shape[0] - 1}")
    for i, text in enumerate(tasks.tolist()):
        try:
            task = json.loads(text)
        except json.JSONDecodeError as exc:
            raise _Invalid(f"tasks[{i}] is not valid JSON: {exc}") from None
        if not isinstance(task, dict):
            raise _Invalid(f"tasks[{i}] is not a JSON object (a TaskSpec.to_dict())")
        missing = [".".join(key) for key in READ_TASK_KEYS if not isinstance(task.get(key[0]), dict)
                   or key[1] not in task[key[0]]]  # fmt: skip
        if missing:  # the task file's rules fill in defaults; these are read from the record as it is
            raise _Invalid(f"tasks[{i}] lacks {', '.join(missing)} (a TaskSpec.to_dict() holds them)")
        for rule in TASK_RULES:
            try:
                rule(task, f"tasks[{i}]")
            except ValueError as exc:
                raise _Invalid(f"the task record {exc}") from None
        control = task.get("control")
        declared = control.get("actions", "discrete") if isinstance(control, dict) else "discrete"
        if declared != _kind(a) and declared in ACTION_KINDS:
            raise _Invalid(f"tasks[{i}] has {declared} actions ([control] actions) but the dataset holds "
                           f"{_kind(a)} ones")  # fmt: skip


def _check_times(a: Mapping[str, np.ndarray]) -> None:
    """Times start at 0 s in every trajectory (seconds since its start) and never run backwards
    within one."""
    lengths = a["lengths"]
    starts = np.concatenate([[0], np.cumsum(lengths + 1)[:-1]]).astype(np.int64)
    late = np.flatnonzero(a["times"][starts] != 0)
    if late.size:
        i = int(late[0])
        first = float(a["times"][starts[i]])
        raise _Invalid(f"'times' of trajectory {i} start at {first} s; each trajectory's times are seconds "
                       "since its start, so its first is 0")  # fmt: skip
    dt = np.diff(a["times"])
    dt[starts[1:] - 1] = 0.0  # across trajectory boundaries
    if np.any(dt < 0):
        raise _Invalid(f"'times' decrease within a trajectory at row {int(np.argmax(dt < 0)) + 1}")


_CHECKS: tuple[Callable[[Mapping[str, np.ndarray]], None], ...] = (
    _check_format,
    _check_version,
    _check_keys,
    _check_action_kind,
    _check_schema,
    _check_counts,
    _check_finite,
    _check_speed_and_seed,
    _check_features,
    _check_actions,
    _check_outcomes,
    _check_tasks,
    _check_times,
)
"""Every check of a dataset's arrays, in the order :func:`_validate` runs them."""
