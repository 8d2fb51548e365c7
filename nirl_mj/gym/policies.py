"""Experts and reference policies as ``policy(observation) -> action`` for a Gymnasium loop.

An expert (``nirl_mj.experts``) is a ``sim.episode.Agent``: reset with the dm_env environment
and its first ``TimeStep``, then asked for an action per ``TimeStep``. :class:`ExpertPolicy`
wraps one so that it takes the observation a ``NavigationEnv`` returns (the full Dict)::

    env = gymnasium.make("nirl_mj/Navigate-v0")
    policy = ExpertPolicy("sensor")
    obs, info = env.reset(seed=0)
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        if terminated or truncated:
            break

A new episode is recognised by ``steps == 0`` in the observation, which resets the expert (the
sensor expert forgets its memory). The sensor expert and the reference policies read the
observation only; the planner reads the arena, and the noisy expert draws its episode's noise
seed from the environment's random state, so both need ``env`` (the Gymnasium environment
they drive). The reference policies (``rule``, ``forward``) need ``features`` only and also take
the bare phi(s) array (an environment made with ``observation="features"``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import dm_env
import numpy as np

from nirl_mj.experts import EXPERT_KINDS, make_expert
from nirl_mj.experts.policies import POLICIES
from nirl_mj.sim.drive import action_share

_NEEDS_ENV = ("planner", "noisy")
_PER_ENVIRONMENT = ("the {kind} expert reads its environment: for a vector environment make one ExpertPolicy "
                    "per environment, each given its own env")  # fmt: skip


def _task_of(env) -> tuple[Any, bool]:
    """The task of ``env`` (None without one) and whether ``env`` is a vector environment (Gymnasium's
    or Stable-Baselines3's: the task of its first environment; they share one)."""
    if env is None:
        return None, False
    task = getattr(getattr(env, "unwrapped", None), "task_spec", None)
    if task is not None:
        return task, False
    if hasattr(env, "get_attr"):
        return env.get_attr("task_spec")[0], True
    raise ValueError(f"env={type(env).__name__}: not a nirl_mj environment (gymnasium.make('nirl_mj/...')) "
                     "or a vector environment of them")  # fmt: skip


class ExpertPolicy:
    """The expert ``kind`` (:data:`nirl_mj.experts.EXPERT_KINDS`) as ``policy(obs) -> action``.

    ``env``: the Gymnasium environment the policy drives (its ``unwrapped.dm_env``), required by
    the planner and the noisy expert; given the ``env`` of a task with continuous actions, the
    policy answers each discrete choice as its continuous twin, float32 shares
    (:func:`nirl_mj.sim.drive.action_share`, as ``nirl-mj demos`` records them). ``options``
    configure the noisy one (``base``, ``slip``, ``random``, ``seed``:
    :func:`nirl_mj.experts.make_expert`).
    """

    def __init__(self, kind: str, env=None, **options) -> None:
        if kind not in EXPERT_KINDS:
            raise ValueError(f"unknown expert {kind!r}: accepted: {', '.join(EXPERT_KINDS)}")
        if (kind in _NEEDS_ENV or options.get("base") == "planner") and env is None:
            raise ValueError(f"the {kind} expert reads the environment: give env=the Gymnasium environment")
        task, vector = _task_of(env)
        if vector and (kind in _NEEDS_ENV or options.get("base") == "planner"):
            raise ValueError(_PER_ENVIRONMENT.format(kind=kind))
        self.kind = kind
        self._options = options
        self._expert = make_expert(kind, **options)
        self._batch: list = []
        self._env = None if vector else env
        self._continuous = task is not None and task.control.actions == "continuous"

    def __call__(self, observation: Mapping[str, np.ndarray]) -> int | np.ndarray:
        if not isinstance(observation, Mapping) or "steps" not in observation:
            raise ValueError(
                f"the {self.kind} expert takes the full Dict observation of a nirl_mj environment "
                "(made without observation=...)"
            )
        if np.ndim(observation["steps"]) == 2:  # a vector environment's batch: one expert per environment
            return self._act_batch(observation)
        return self._act(self._expert, observation)

    def _act(self, expert, observation: Mapping[str, np.ndarray]) -> int:
        if int(observation["steps"][0]) == 0:
            timestep = dm_env.restart(observation)
            expert.reset(self._dm_env(), timestep)
        else:
            timestep = dm_env.transition(0.0, observation)
        action = int(expert.act(timestep))
        return action_share(action) if self._continuous else action

    def _act_batch(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
        if self.kind in _NEEDS_ENV or self._options.get("base") == "planner":
            raise ValueError(_PER_ENVIRONMENT.format(kind=self.kind))
        n = len(observation["steps"])
        while len(self._batch) < n:  # each environment's expert keeps its own memory between steps
            self._batch.append(make_expert(self.kind, **self._options))
        return np.array(
            [self._act(self._batch[i], {k: v[i] for k, v in observation.items()}) for i in range(n)]
        )

    def _dm_env(self):
        return None if self._env is None else self._env.unwrapped.dm_env


def reference_policy(name: str, env=None):
    """A reference policy of :data:`nirl_mj.experts.policies.POLICIES` (``rule``, ``forward``) as
    ``policy(obs) -> action``; ``obs`` is the Dict observation or phi(s) (16,) itself. Given the
    ``env`` it drives, of a task with continuous actions, it acts with its discrete choice's continuous
    twin, normalised as the environment's action space is (:func:`nirl_mj.sim.drive.action_share`)."""
    if name not in POLICIES:
        raise ValueError(f"unknown reference policy {name!r}: accepted: {', '.join(sorted(POLICIES))}")
    on_phi = POLICIES[name]
    task, _ = _task_of(env)
    continuous = task is not None and task.control.actions == "continuous"

    def act(phi: np.ndarray) -> int | np.ndarray:
        action = int(on_phi(phi))
        return action_share(action) if continuous else action  # shares of env.unwrapped.action_scale

    def policy(observation: Mapping[str, np.ndarray] | np.ndarray) -> int | np.ndarray:
        phi = np.asarray(observation["features"] if isinstance(observation, Mapping) else observation)
        if phi.ndim == 2:  # a vector environment's batch: one action per environment
            return np.array([act(row) for row in phi])
        return act(phi)

    policy.__name__ = name
    return policy
