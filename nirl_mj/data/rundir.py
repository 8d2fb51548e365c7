"""A training run's directory on disk: every file name, every read and every write.

A run directory holds:

- ``run.json``: the run record (task, learner config, seed, demonstrations and their content
  sha256, the arena seeds used; when training has finished also the selection and
  ``train_seeds``);
- ``metrics.jsonl``: one JSON object per finished iteration;
- ``checkpoint.npz``: the whole learner state after the last finished iteration;
- ``policy.npz``: the selected and the last network (``selected/W1``, ``last/W2``, ...);
- ``reward.json``: the selected reward (``{"kind", "theta": {name: value}}``);
- ``eval.json``: held-out evaluations by key (``task|seed=S|tests=N|which``, ``|backend=warp``
  for an evaluation on the Warp backend, and ``|set SECTION.KEY=VALUE`` for each task value that
  ``--set`` changed).

A reinforcement-learning run (``nirl-mj rl``, record ``"kind": "rl"``) holds ``run.json``,
``model.zip`` (the Stable-Baselines3 model, written at every checkpoint and at the end), the
selected checkpoint ``selected-<decisions>.zip``, GAIL's and AIRL's ``discriminator.npz`` and
``eval.json``.

Every write is atomic (``nirl_mj.data.atomic``), so a killed process leaves each file
either as it was or as it became. The record is written first and last: a run counts
as finished once its record holds ``train_seeds`` and the policy file exists.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from nirl_mj.data.atomic import AtomicFile, leftover_temporaries, write_npz, write_text
from nirl_mj.data.lock import DirectoryLock

RUN_FILE, METRICS_FILE, CHECKPOINT_FILE = "run.json", "metrics.jsonl", "checkpoint.npz"
POLICY_FILE, REWARD_FILE, EVAL_FILE = "policy.npz", "reward.json", "eval.json"
MODEL_FILE, SELECTED_MODEL_FILE = "model.zip", "selected.zip"
SELECTED_MODEL_PATTERN = "selected-{steps}.zip"  # an RL run's selected checkpoint, named in its record
DISCRIMINATOR_FILE = "discriminator.npz"  # GAIL's and AIRL's discriminator (experiments.adversarial)
POLICIES = ("selected", "last")
RECORD_KEYS = ("task", "config", "seed", "demos", "demo_seeds", "validation_seeds")
"""What every run record holds from its start."""


class RunError(ValueError):
    """A run directory is missing, foreign, corrupted or would be overwritten."""


@dataclass(frozen=True)
class RunDir:
    """The files of one training run under ``path``."""

    path: Path

    def __init__(self, path: str | os.PathLike) -> None:
        if Path(path).exists() and not Path(path).is_dir():
            raise RunError(f"{path} is a file, not a run directory")
        object.__setattr__(self, "path", Path(path))

    def __str__(self) -> str:
        return str(self.path)

    def file(self, name: str) -> Path:
        """The path of one of the run's files (one of the ``*_FILE`` names)."""
        return self.path / name

    # -- state ---------------------------------------------------------------------------

    @property
    def is_run(self) -> bool:
        """Whether a run record exists here."""
        return self.file(RUN_FILE).is_file()

    @property
    def has_checkpoint(self) -> bool:
        return self.file(CHECKPOINT_FILE).is_file()

    @property
    def is_finished(self) -> bool:
        """Training ended and wrote its policy, reward and final record."""
        return self.is_run and self.file(POLICY_FILE).is_file() and "train_seeds" in self.read_record()

    def is_empty(self) -> bool:
        return not self.path.exists() or not any(self.path.iterdir())

    def remove_leftovers(self) -> list[Path]:
        """Deletes temporary files left by a process killed while writing (call with no writer
        running: when resuming); returns what was removed. An evaluation may be adding its entry to
        ``eval.json`` meanwhile (it holds that file's lock, not the run's): its lock is waited for."""
        if not self.path.is_dir():
            return []
        with DirectoryLock(self.file(EVAL_FILE), "eval", wait=True):
            leftovers = leftover_temporaries(self.path)
            for path in leftovers:
                path.unlink(missing_ok=True)
        return leftovers

    def names(self) -> set[str]:
        """The names of the files present."""
        return {p.name for p in self.path.iterdir()} if self.path.is_dir() else set()

    # -- the record ------------------------------------------------------------------------

    def read_record(self) -> dict[str, Any]:
        """``run.json``, with a clear error if this is not a run directory."""
        path = self.file(RUN_FILE)
        if not path.is_file():
            raise RunError(
                f"{self.path} is not a nirl-mj run directory (no {RUN_FILE}); train one with `nirl-mj train`"
            )
        record = _json_object(path)
        missing = [key for key in RECORD_KEYS if key not in record]
        if missing:
            raise RunError(f"{path} is corrupted or not a run record: it lacks {', '.join(missing)}")
        wrong = _record_type_problem(record)
        if wrong:
            raise RunError(f"{path} is corrupted: {wrong}")
        return record

    def write_record(self, record: Mapping[str, Any]) -> None:
        self.path.mkdir(parents=True, exist_ok=True)
        write_text(self.file(RUN_FILE), json.dumps(record, indent=1))

    # -- metrics ---------------------------------------------------------------------------

    def read_metrics(self) -> list[dict[str, Any]]:
        """Every finished iteration's metrics row (none before the first). A row still being
        appended by another process (no newline yet) is left for the next read."""
        path = self.file(METRICS_FILE)
        lines = path.read_text(errors="replace").splitlines(keepends=True) if path.exists() else []
        rows = []
        for number, line in enumerate(lines, start=1):
            if not line.endswith("\n") or not line.strip():
                continue
            try:
                row = json.loads(line)
            except json.JSONDecodeError as exc:
                raise RunError(f"{path}: line {number} is not JSON ({exc})") from None
            if not isinstance(row, dict):
                raise RunError(
                    f"{path}: line {number} holds {line.strip()[:40]!r}, not an iteration's metrics"
                )
            rows.append(row)
        return rows

    def iterations_done(self) -> int:
        """Metrics rows written so far (finished iterations, possibly one past the checkpoint); a
        row without its newline (torn) is not one: each row is appended with its newline at once."""
        path = self.file(METRICS_FILE)
        lines = path.read_text(errors="replace").splitlines(keepends=True) if path.exists() else []
        return sum(line.endswith("\n") for line in lines)

    def start_metrics(self) -> None:
        write_text(self.file(METRICS_FILE), "")

    def append_metrics(self, row: Mapping[str, Any]) -> None:
        """Appends one iteration's row; a value that is not a finite number (the margin of a run
        without a reward step, NaN) is written as null, so that every line is strict JSON."""
        # An append, not an atomic rewrite: a crash may leave one row past the checkpoint,
        # which keep_metrics removes on resume. Synced before the checkpoint that follows it is
        # written, so that after a power loss the rows are never behind the checkpoint.
        finite = {k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in row.items()}
        with open(self.file(METRICS_FILE), "a") as f:
            f.write(json.dumps(finite) + "\n")
            f.flush()
            os.fsync(f.fileno())

    def keep_metrics(self, iterations: int) -> None:
        """Keeps the first ``iterations`` rows (those the checkpoint covers)."""
        path = self.file(METRICS_FILE)
        try:
            lines = path.read_text().splitlines(keepends=True) if path.exists() else []
        except UnicodeDecodeError as exc:
            raise RunError(f"{path} is corrupted (not UTF-8 text: {exc}); the run is left as it is: "
                           "train it again in another --out") from None  # fmt: skip
        write_text(path, "".join(lines[:iterations]))

    # -- arrays ----------------------------------------------------------------------------

    def read_checkpoint(self) -> dict[str, np.ndarray]:
        path = self.file(CHECKPOINT_FILE)
        if not path.is_file():
            raise RunError(f"{self.path} has no checkpoint to resume from ({CHECKPOINT_FILE})")
        return self._read_npz(path, "start a new run in another directory")

    def write_checkpoint(self, arrays: Mapping[str, np.ndarray]) -> None:
        write_npz(self.file(CHECKPOINT_FILE), dict(arrays))

    def read_policy(self, which: str = "selected") -> dict[str, np.ndarray]:
        """The weights of the ``selected`` or ``last`` network, by name (``W1``, ``W2``)."""
        if which not in POLICIES:
            raise RunError(f"unknown policy {which!r}; accepted: selected, last or an iteration number")
        path = self.file(POLICY_FILE)
        if not path.is_file():
            raise RunError(
                f"{self.path} has no {POLICY_FILE}: its training has not finished (resume it with --resume)"
            )
        arrays = self._read_npz(path, "train the run again")
        weights = {k.split("/", 1)[1]: v for k, v in arrays.items() if k.startswith(which + "/")}
        check_weights(weights, f"{path}'s {which} policy", "train the run again")
        return weights

    def write_policy(self, selected: Mapping[str, np.ndarray], last: Mapping[str, np.ndarray]) -> None:
        arrays = {f"selected/{k}": v for k, v in selected.items()}
        write_npz(self.file(POLICY_FILE), arrays | {f"last/{k}": v for k, v in last.items()})

    def model_file(self, name: str = MODEL_FILE) -> Path:
        """``model.zip`` (or ``name``, e.g. ``selected.zip``) of a reinforcement-learning run, with a
        clear error if it is missing."""
        path = self.file(name)
        if not path.is_file():
            raise RunError(f"{self.path} has no {name}: its training has not reached a checkpoint")
        return path

    def write_model(self, save: Callable[[Path], object], name: str = MODEL_FILE) -> None:
        """Writes ``model.zip`` (or ``name``) atomically: ``save(path)`` writes a model to a temporary
        path."""
        with AtomicFile(self.file(name), ".zip") as target:
            save(target.tmp)

    @staticmethod
    def _read_npz(path: Path, remedy: str) -> dict[str, np.ndarray]:
        if not zipfile.is_zipfile(path):
            raise RunError(f"{path} is corrupted (not an .npz archive); {remedy}")
        try:
            with np.load(path, allow_pickle=False) as data:
                return {k: data[k] for k in data.files}
        except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
            raise RunError(f"{path} is corrupted ({exc}); {remedy}") from None

    # -- reward and evaluations ----------------------------------------------------------

    @property
    def has_reward(self) -> bool:
        return self.file(REWARD_FILE).is_file()

    def read_reward(self) -> dict[str, Any]:
        """The selected reward as written by :meth:`write_reward`."""
        path = self.file(REWARD_FILE)
        if not path.is_file():
            raise RunError(f"{self.path} has no {REWARD_FILE}: its training has not finished")
        return _json_object(path)

    def write_reward(self, reward: Mapping[str, Any]) -> None:
        write_text(self.file(REWARD_FILE), json.dumps(dict(reward), indent=1))

    def read_evaluations(self) -> dict[str, Any]:
        """``eval.json``: each evaluation's metrics by key (``{}`` before the first)."""
        path = self.file(EVAL_FILE)
        if not path.exists():
            return {}
        evaluations = _json_object(path)
        bad = [key for key, value in evaluations.items() if not isinstance(value, dict)]
        if bad:
            raise RunError(f"{path} is corrupted: entry {bad[0]!r} is not an evaluation's metrics (a JSON "
                           "object); move the file away to evaluate again")  # fmt: skip
        return evaluations

    def add_evaluation(self, key: str, result: Mapping[str, Any]) -> None:
        """Stores ``result`` under ``key`` in ``eval.json``, keeping the other entries; evaluations of
        one run in several processes wait for each other here, so that none loses another's entry."""
        with DirectoryLock(self.file(EVAL_FILE), "eval", wait=True):
            evaluations = {**self.read_evaluations(), key: dict(result)}
            write_text(self.file(EVAL_FILE), json.dumps(evaluations, indent=1))


def _is_seed(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _record_type_problem(record: Mapping[str, Any]) -> str | None:
    """What in a run record has the wrong type (the keys every reader takes as they are), or None."""
    if not _is_seed(record["seed"]):
        return f"seed = {record['seed']!r}, not a whole number >= 0"
    if record["demos"] is not None and not isinstance(record["demos"], str):
        return f"demos = {record['demos']!r}, not a path"
    for key in ("demo_seeds", "validation_seeds", "train_seeds"):
        seeds = record.get(key, [])
        if not isinstance(seeds, list) or not all(_is_seed(s) for s in seeds):
            return f"{key} is not a list of arena seeds"
    return None


def check_weights(weights: Mapping[str, np.ndarray], what: str, fix: str) -> None:
    """Refuses a network's weights (``W1``, ``W2``) that are missing, not 2-d or not finite."""
    for name in ("W1", "W2"):
        w = weights.get(name)
        if w is None or np.ndim(w) != 2 or not np.issubdtype(np.asarray(w).dtype, np.floating):
            raise RunError(f"{what} is corrupted: no 2-d float array {name}; {fix}")
        if not np.all(np.isfinite(w)):
            raise RunError(f"{what} is corrupted: {name} is not finite; {fix}")


def _json_object(path: Path) -> dict[str, Any]:
    """The JSON object in ``path``; a RunError naming the file if it is not readable JSON or not an
    object."""
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RunError(f"{path} is corrupted: {exc}") from None
    if not isinstance(value, dict):
        what = f"{type(value).__name__} {str(value)[:40]!r}"
        raise RunError(f"{path} is corrupted: it holds {what}, not a JSON object")
    return value
