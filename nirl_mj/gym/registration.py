"""Gymnasium ids for the shipped task files: ``nirl_mj/Navigate-v0`` for ``tasks/navigate.toml``.

Imported by ``import nirl_mj`` when Gymnasium is installed (Gymnasium 1.x has no plugin entry
points: an id exists once registered), so it imports nothing heavier than Gymnasium's registry
and the task-file reader. Every id takes ``task=NAME_OR_PATH`` (any task file) and the other
keyword arguments of :class:`~nirl_mj.gym.env.NavigationEnv`.
"""

from __future__ import annotations

import tomllib

from gymnasium.envs.registration import register, registry

from nirl_mj.sim.spec import TASKS_DIR

NAMESPACE = "nirl_mj"
ENTRY_POINT = "nirl_mj.gym.env:NavigationEnv"


def task_names() -> list[str]:
    """The task files under ``tasks/`` (not experiment files, which have a top-level ``kind``)."""
    names = []
    for path in sorted(TASKS_DIR.glob("*.toml")):
        try:
            data = tomllib.loads(path.read_text())
        except (OSError, tomllib.TOMLDecodeError):
            continue  # a broken file is reported when it is used, not at import
        if "kind" not in data:
            names.append(path.stem)
    return names


def env_id(task: str) -> str:
    """``navigate`` -> ``nirl_mj/Navigate-v0``; ``my_task`` -> ``nirl_mj/MyTask-v0``."""
    return f"{NAMESPACE}/{''.join(part.capitalize() for part in task.split('_'))}-v0"


def register_envs() -> list[str]:
    """Registers an id per shipped task file (again: nothing); returns the ids."""
    ids = []
    for name in task_names():
        ids.append(env_id(name))
        if ids[-1] not in registry:
            # No TimeLimit: the task has its own step budget, which ends an episode as truncated.
            register(id=ids[-1], entry_point=ENTRY_POINT, kwargs={"task": name})
    return ids
