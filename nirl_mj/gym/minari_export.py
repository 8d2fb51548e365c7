"""Datasets as Minari datasets, and back.

Our dataset files (docs/DATASET.md) keep phi(s), ranges, poses and actions, not every observation,
reward or episode end. But an episode is a function of its arena seed and its actions, so
:func:`export_minari` replays each trajectory's actions in a ``NavigationEnv`` reset with its
arena seed, into Minari's episode buffers (``EpisodeBuffer``, as its ``DataCollector`` fills them,
without the jax it needs): the Minari dataset gets the full observation Dict,
rewards, terminations, truncations and the environment's spec (its id and the task as a dict), so
``minari.load_dataset(ID).recover_environment()`` builds the same environment and the episodes
replay to the same observations bit for bit (the episode's seed is its arena seed). Continuous
actions keep their float32 shares (the environment's ``Box(-1, 1, (2,))``). Every
replayed state is checked against the file's phi(s), ranges and poses; a trajectory that does
not replay (recorded by another version of the simulation) is an error naming it.

:func:`load_minari` reads such a dataset back as trajectories (``nirl-mj train --demos
minari:ID``).
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import shutil
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from nirl_mj.data.lock import DirectoryLock, process_folder
from nirl_mj.data.trajectory import Trajectory, task_json
from nirl_mj.sim.spec import SpecError, from_dict
from nirl_mj.sim.task import Outcome

PREFIX = "minari:"
"""``--demos minari:ID`` names a local Minari dataset instead of a dataset file."""


class MinariError(ValueError):
    """A Minari dataset is missing, would be overwritten, or cannot hold or give our episodes."""


def export_minari(
    trajectories: Sequence[Trajectory],
    dataset_id: str,
    overwrite: bool = False,
    on_episode: Callable[[int], None] | None = None,
):
    """Writes ``trajectories`` (one task) as the local Minari dataset ``dataset_id``
    (``namespace/env/name-vN``, e.g. ``nirl_mj/navigate/sensor-v0``); returns the
    ``MinariDataset``. Refuses an existing dataset unless ``overwrite``."""
    _check_id(dataset_id)
    if not trajectories:
        raise MinariError("the dataset holds no trajectory")
    tasks = {task_json(t.task) for t in trajectories}
    if len(tasks) > 1:
        raise MinariError(f"the dataset holds {len(tasks)} tasks; a Minari dataset has one environment: "
                          "export each task's trajectories separately")  # fmt: skip
    from minari.storage.datasets_root_dir import get_dataset_path

    final = get_dataset_path(dataset_id)
    with DirectoryLock(final, "export"):  # one writer of the dataset
        _restore_old(final)
        return _export(trajectories, dataset_id, overwrite, on_episode, final)


def _export(trajectories, dataset_id: str, overwrite: bool, on_episode, final: Path):
    """:func:`export_minari` under its lock."""
    import gymnasium
    import minari
    from minari.storage.datasets_root_dir import get_dataset_path

    with warnings.catch_warnings():  # Minari warns of the half dataset we look for
        warnings.simplefilter("ignore")
        exists = dataset_id in minari.list_local_datasets()
    half = final.exists() and not exists  # an export killed while writing, before this version
    if (exists or half) and not overwrite:
        what = "exists" if exists else "holds a half-written dataset (an interrupted export)"
        raise MinariError(f"Minari dataset {dataset_id} {what}; pass --overwrite to replace it")
    task = trajectories[0].task
    env = gymnasium.make(_env_id(task), task=task)
    try:
        buffers = []
        for i, trajectory in enumerate(trajectories):
            buffers.append(_replay(env, trajectory, i))
            if on_episode:
                on_episode(i)
        demonstrators = sorted({t.demonstrator for t in trajectories})
        staging = _staging(get_dataset_path())
        try:
            with warnings.catch_warnings():  # author, e-mail, permalink, eval_env: optional, not ours
                warnings.filterwarnings("ignore", category=UserWarning, module="minari")
                with _datasets_path(staging):  # written where no reader looks, then moved into place
                    minari.create_dataset_from_buffers(
                        dataset_id,
                        buffers,
                        env=env,
                        algorithm_name=", ".join(demonstrators),
                        description=f"{len(trajectories)} episodes of nirl-mj task {task.get('name')} by "
                        f"{', '.join(demonstrators)}, replayed from their arena seeds and actions",
                        requirements=["nirl-mj[gym]"],
                    )
            _move_into_place(staging / dataset_id, final)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
        return minari.load_dataset(dataset_id)
    finally:
        env.close()


STAGING = ".nirl-mj-export-"
"""The prefix of an export's hidden folder under the datasets root (Minari lists no hidden folder),
followed by its process id."""


def _staging(root) -> Path:
    """A new hidden folder under the datasets root for one export; removes those of dead exports
    (killed while writing: never a dataset)."""
    return process_folder(root, STAGING)


@contextlib.contextmanager
def _datasets_path(path: Path):
    """Minari's datasets root set to ``path`` for the block (it reads the variable at every call)."""
    before = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(path)
    try:
        yield
    finally:
        if before is None:
            del os.environ["MINARI_DATASETS_PATH"]
        else:
            os.environ["MINARI_DATASETS_PATH"] = before


def _move_into_place(new: Path, final: Path) -> None:
    """Puts the complete dataset ``new`` at ``final``; an old one there is removed only after."""
    final.parent.mkdir(parents=True, exist_ok=True)
    if not final.exists():
        os.rename(new, final)
        return
    trash = _old_copies(final)[0].with_name(f".{final.name}.old-{os.getpid()}-{secrets.token_hex(4)}")
    os.rename(final, trash)
    os.rename(new, final)
    shutil.rmtree(trash, ignore_errors=True)


def _old_copies(final: Path) -> list[Path]:
    """The old datasets of ``final`` set aside by :func:`_move_into_place` (a placeholder path first,
    for the name of a new one): one is left only by an export killed between its two renames."""
    return [final.parent / f".{final.name}.old", *sorted(final.parent.glob(f".{final.name}.old-*"))]


def _restore_old(final: Path) -> None:
    """Puts back the old dataset an export killed between its two renames left aside (``final``
    missing): never both lost."""
    if not final.exists():
        for old in _old_copies(final)[1:]:
            os.rename(old, final)
            break


def _env_id(task: dict) -> str:
    """The registered id of a shipped task's name, else Navigate's (the task dict decides anyway)."""
    from nirl_mj.gym.registration import env_id, task_names

    return env_id(task.get("name")) if task.get("name") in task_names() else env_id("navigate")


def _replay(env, trajectory: Trajectory, index: int):
    """Runs ``trajectory``'s actions in ``env`` from its arena seed, checking every state; returns
    the episode as a Minari ``EpisodeBuffer``. (Built here: Minari's ``DataCollector`` needs jax.)"""
    from minari.data_collector import EpisodeBuffer

    seed = int(trajectory.arena_seed)
    obs, info = env.reset(seed=seed)
    _check_state(obs, trajectory, 0, index)
    observations = {key: [value] for key, value in obs.items()}
    infos = {key: [info[key]] for key in INFO_KEYS}
    rewards, terminations, truncations = [], [], []
    actions = _actions(trajectory)
    for t, action in enumerate(actions):
        if terminations[-1:] == [True] or truncations[-1:] == [True]:
            raise MinariError(f"trajectory {index} (arena {seed}) ended after {t} of its "
                              f"{len(trajectory)} decisions when replayed")  # fmt: skip
        obs, reward, terminated, truncated, info = env.step(action)
        _check_state(obs, trajectory, t + 1, index)
        for key in INFO_KEYS:
            infos[key].append(info[key])
        for key, value in obs.items():
            observations[key].append(value)
        rewards.append(reward)
        terminations.append(terminated)
        truncations.append(truncated)
    if not (terminations[-1:] == [True] or truncations[-1:] == [True]):
        raise MinariError(f"trajectory {index} (arena {seed}) does not end after its {len(trajectory)} "
                          "decisions (abandoned?); Minari keeps finished episodes only")  # fmt: skip
    return EpisodeBuffer(id=index, seed=seed, observations=observations, actions=actions, rewards=rewards,
                         terminations=terminations, truncations=truncations,
                         infos={k: _info_array(v) for k, v in infos.items()})  # fmt: skip


def _actions(trajectory: Trajectory) -> list:
    """The trajectory's actions as the environment's action space holds them: ``np.int64`` indices
    (``Discrete(6)``), or float32 (2,) shares (continuous actions, ``Box(-1, 1, (2,))``), exactly the
    file's."""
    if trajectory.action_kind == "continuous":
        return [np.array(a, dtype=np.float32) for a in trajectory.actions]
    return [np.int64(a) for a in trajectory.actions.tolist()]


INFO_KEYS = ("is_success", "outcome", "steps")
"""The environment's ``info`` kept in every Minari episode, one entry per step and one for the reset
(as Minari's own collector keeps it): ``is_success`` (bool), ``outcome`` (ASCII bytes: running,
target, collision, timeout, physics_error) and ``steps``."""


def _info_array(values: list) -> np.ndarray:
    """One info entry per step as Minari's HDF5 storage holds it: text as ASCII bytes."""
    array = np.asarray(values)
    return array.astype("S") if array.dtype.kind == "U" else array


def _check_state(obs: dict, trajectory: Trajectory, t: int, index: int) -> None:
    same = (
        np.array_equal(obs["features"], trajectory.features[t])
        and np.array_equal(obs["ranges"].astype(np.float32), trajectory.ranges[t])
        and np.array_equal(obs["pose"], trajectory.poses[t])
    )
    if not same:
        raise MinariError(f"trajectory {index} (arena {trajectory.arena_seed}) does not replay: state "
                          f"{t} differs from the file (recorded by another simulation version?)")  # fmt: skip


def load_minari(dataset_id: str) -> list[Trajectory]:
    """The episodes of the local Minari dataset ``dataset_id`` (written by :func:`export_minari`)
    as trajectories."""
    import minari

    _check_id(dataset_id)
    # minari's own lookup makes its datasets folder (~/.minari/datasets): a failing one must not
    given = os.environ.get("MINARI_DATASETS_PATH")  # minari's rule: set (even empty) is used
    root = Path(given) if given is not None else Path.home() / ".minari" / "datasets"
    if not root.is_dir():
        raise MinariError(f"no local Minari dataset {dataset_id!r} (no datasets folder {root}); write one "
                          "with nirl-mj export D.npz --to minari --id ID")  # fmt: skip
    try:  # the listing reads every local dataset's metadata, so it too meets a damaged one
        local = minari.list_local_datasets()
        if dataset_id not in local:
            names = ", ".join(sorted(local)) or "none"
            raise MinariError(f"no local Minari dataset {dataset_id!r} (local: {names}); write one with "
                              "nirl-mj export D.npz --to minari --id ID")  # fmt: skip
        return _trajectories(minari.load_dataset(dataset_id), dataset_id)
    except MinariError:
        raise
    except (OSError, KeyError, ValueError, TypeError, IndexError, AttributeError, RuntimeError) as exc:
        # h5py and minari raise these on a damaged store: name the dataset and where it lies
        from minari.storage import get_dataset_path

        where = get_dataset_path(dataset_id)
        raise MinariError(f"Minari dataset {dataset_id} ({where}) cannot be read: {exc}; write it again "
                          "with nirl-mj export D.npz --to minari --id ID --overwrite") from None  # fmt: skip


def _trajectories(dataset, dataset_id: str) -> list[Trajectory]:
    """The episodes of the loaded Minari ``dataset`` as trajectories."""
    env_spec = dataset.spec.env_spec
    if env_spec is None or not isinstance(env_spec.kwargs.get("task"), dict):
        raise MinariError(f"Minari dataset {dataset_id} was not written by nirl-mj (no task in its env spec)")
    try:
        spec = from_dict(env_spec.kwargs["task"], f"Minari dataset {dataset_id}")
    except SpecError as exc:
        raise MinariError(str(exc)) from None
    continuous = spec.control.actions == "continuous"
    seeds = [m["seed"] for m in dataset.storage.get_episode_metadata(dataset.episode_indices)]
    demonstrator = dataset.storage.metadata.get("algorithm_name") or "minari"
    out = []
    for episode, seed in zip(dataset.iterate_episodes(), seeds, strict=True):
        obs = episode.observations
        n = len(episode.actions)
        outcome = Outcome(int(obs["outcome"][-1, 0]))
        actions = (np.asarray(episode.actions, dtype=np.float32).reshape(n, 2) if continuous
                   else np.asarray(episode.actions, dtype=np.int8))  # fmt: skip
        out.append(Trajectory(
            features=obs["features"], actions=actions,
            ranges=obs["ranges"].astype(np.float32), poses=obs["pose"],
            times=np.arange(n + 1) * spec.control.decision_period, arena_seed=int(seed), task=spec,
            speed=spec.control.speed, outcome=outcome if outcome != Outcome.RUNNING else Outcome.TIMEOUT,
            demonstrator=demonstrator,
        ))  # fmt: skip
    return out


def _check_id(dataset_id: str) -> None:
    from minari.dataset.minari_dataset import parse_dataset_id

    if not re.fullmatch(r"[^/]+(/[^/]+)*-v\d+", dataset_id):  # Minari's own parser fails on no -vN
        raise MinariError(f"Minari dataset id {dataset_id!r}: expected [NAMESPACE/]NAME-vVERSION, "
                          "e.g. nirl_mj/navigate/sensor-v0")  # fmt: skip
    try:
        parse_dataset_id(dataset_id)
    except (ValueError, TypeError) as exc:
        raise MinariError(
            f"Minari dataset id {dataset_id!r}: {exc} (e.g. nirl_mj/navigate/sensor-v0)"
        ) from None
