"""The navigation task as a ``gymnasium.Env``: an own adapter over ``nirl_mj.sim.task.make_env``.

Why not Shimmy's ``DmControlCompatibilityV0``: it replaces composer's random state with
Gymnasium's generator (so ``reset(seed=s)`` does not draw the arena ``run_episode`` draws for arena
seed s, and our datasets could not be replayed), reports ``render_fps`` in the wrong unit, does
not know the task's outcome (no ``is_success``), and a second ``close()`` raises. This adapter is
the dm_env environment underneath plus the Gymnasium conventions:

- ``reset(seed=s)`` seeds composer's random state with s before the reset, as
  ``nirl_mj.sim.episode.run_episode`` does: the same seed, the same arena, bit for bit;
  ``reset()`` continues the stream.
- ``terminated`` when the episode ends with discount 0 (target, collision, physics error),
  ``truncated`` when it ends with discount 1 (the step budget ran out).
- ``info``: ``outcome`` (``"running"``, ``"target"``, ``"collision"``, ``"timeout"``,
  ``"physics_error"``), ``is_success`` (reached the target; Stable-Baselines3's Monitor and
  EvalCallback read it) and ``steps``.
- Actions: ``Discrete(6)``, or with ``[control] actions = "continuous"`` a float32 ``Box`` (2,) in
  [-1, 1] (normalised, as Gymnasium's checker and Stable-Baselines3 ask): the forward speed as a
  share of ``control.speed`` and the yaw rate as a share of the rate that turns 60 degrees in one
  decision (:attr:`NavigationEnv.action_scale`, m/s and rad/s), held for one decision; a value
  beyond [-1, 1] is clipped.
- ``render_mode="rgb_array"``: an offscreen (EGL) frame (height, width, 3) uint8 from a camera
  of the model; ``metadata["render_fps"]`` is one frame per decision (2 at 0.5 s).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np

from nirl_mj.gym.spaces import dict_space, space_of
from nirl_mj.sim.arena import OFFSCREEN_SIZE
from nirl_mj.sim.observations import NAMES
from nirl_mj.sim.spec import SpecError, TaskSpec, apply_overrides, from_dict, load_task
from nirl_mj.sim.task import Outcome, action_scale, make_env, share_twist

CAMERAS = ("robotino/top", "robotino/chase", "overview")
_RENDERED_IN: int | None = None  # the process that last rendered (a forked child inherits it)


class NavigationEnv(gymnasium.Env):
    """One navigation task (a name under ``tasks/``, a ``.toml`` path, a ``TaskSpec`` or its
    ``to_dict()``).

    ``set``: task overrides as on the command line (``["control.speed=3"]``). ``observation``:
    None for the Dict of every observation, a sequence of names for a Dict of those, or one
    name for that Box alone (e.g. ``"features"``, phi(s) (16,)). ``camera``, ``width``,
    ``height``: what ``render()`` shows.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 2.0}
    _spec: gymnasium.envs.registration.EnvSpec | None = None

    @property
    def spec(self) -> gymnasium.envs.registration.EnvSpec | None:
        """The spec ``gymnasium.make`` gave, its ``max_episode_steps`` the task's own step budget:
        the registered ids set none (no ``TimeLimit``), since the budget follows ``task=`` and
        ``set=``, and the task truncates there itself."""
        return self._spec

    @spec.setter
    def spec(self, value: gymnasium.envs.registration.EnvSpec | None) -> None:
        budget = self.task_spec.step_budget if hasattr(self, "task_spec") else None
        self._spec = None if value is None else dataclasses.replace(value, max_episode_steps=budget)

    def __init__(
        self,
        task: str | os.PathLike | TaskSpec | dict = "navigate",
        set: Sequence[str] = (),  # the command line's name for task overrides
        observation: str | Sequence[str] | None = None,
        render_mode: str | None = None,
        camera: str = "robotino/top",
        width: int = 640,
        height: int = 480,
    ) -> None:
        if isinstance(task, dict):  # TaskSpec.to_dict(): JSON, so it can sit in a (Minari) EnvSpec
            spec = from_dict(task, "task")
        elif isinstance(task, str | os.PathLike | TaskSpec):
            spec = load_task(task)
        else:
            raise SpecError(f"task={task!r}: accepted: a task name under tasks/, a .toml path, a TaskSpec "
                            "or its to_dict()")  # fmt: skip
        if isinstance(set, str):
            set = [set]
        spec = apply_overrides(spec, list(set))
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise SpecError(f"render_mode={render_mode!r}: accepted: None, 'rgb_array'")
        if camera not in CAMERAS:
            raise SpecError(f"camera={camera!r}: accepted: {', '.join(CAMERAS)}")
        buffer_w, buffer_h = OFFSCREEN_SIZE
        for name, value, most in (("width", width, buffer_w), ("height", height, buffer_h)):
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 1 <= value <= most:
                raise SpecError(f"{name}={value!r}: accepted: a whole number of pixels in 1..{most} "
                                f"(the offscreen buffer is {buffer_w} x {buffer_h})")  # fmt: skip
        # what pickling keeps: the task as resolved and the options (the simulation is rebuilt)
        self._init = {"task": spec.to_dict(), "observation": observation, "render_mode": render_mode,
                      "camera": camera, "width": width, "height": height}  # fmt: skip
        self._keys, self._single = _observation_keys(observation)
        self._ended: bool | None = None  # None: no episode yet
        self._env = make_env(spec)
        self.task_spec = spec
        self.render_mode, self._frame = render_mode, (height, width, camera)
        self.metadata = {**self.metadata, "render_fps": 1.0 / spec.control.decision_period}
        obs_spec = self._env.observation_spec()
        self.action_space = space_of(self._env.action_spec())
        self.action_scale: np.ndarray | None = None  # continuous: (m/s, rad/s) of an action of 1
        if isinstance(self.action_space, gymnasium.spaces.Box):
            self.action_scale = action_scale(spec)  # = the Box's bounds
            self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.observation_space = (
            space_of(obs_spec[self._keys[0]]) if self._single else dict_space(obs_spec, self._keys)
        )

    def __getstate__(self) -> dict:
        """A pickled environment keeps its task and options; it unpickles as a fresh one of the same
        task, to be reset, with the ``spec`` ``gymnasium.make`` gave it (the simulation itself does
        not pickle: Gymnasium's async vector environments and Ray send environments this way)."""
        return {**self._init, "_spec": self._spec}

    def __setstate__(self, state: dict) -> None:
        spec = state.pop("_spec", None)
        self.__init__(**state)
        self._spec = spec

    @property
    def dm_env(self):
        """The dm_env (composer) environment underneath: its ``physics``, ``task`` and ``random_state``."""
        if self._env is None:
            raise RuntimeError("the environment is closed")
        return self._env

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        env = self.dm_env
        if seed is not None:
            env.random_state.seed(seed)  # composer's own stream: the arena of arena seed `seed`
        timestep = env.reset()
        self._ended = False
        return self._observation(timestep.observation), self._info(timestep.observation)

    def step(self, action):
        if self._ended is not False:
            raise RuntimeError(
                "step() before reset(): call reset() first"
                if self._ended is None
                else "step() after the episode ended (terminated or truncated): call reset() first"
            )
        if self.action_scale is not None:
            action = self.twist(action)
        timestep = self.dm_env.step(action)
        self._ended = timestep.last()
        last = timestep.last()
        terminated = bool(last and timestep.discount == 0.0)
        observation = timestep.observation
        return (self._observation(observation), float(timestep.reward), terminated,
                bool(last and not terminated), self._info(observation))  # fmt: skip

    def twist(self, action) -> np.ndarray:
        """A normalised continuous action as the task's (forward speed m/s, yaw rate rad/s), clipped
        to [-1, 1] first."""
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (2,) or not np.all(np.isfinite(a)):
            hint = ("; a discrete action (ExpertPolicy and reference_policy answer with shares when "
                    "given env=this environment)") if a.shape == (1,) else ""  # fmt: skip
            raise ValueError(f"action {action!r}: expected two finite numbers in [-1, 1]{hint}")
        return share_twist(a, self.action_scale)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gymnasium.logger.warn("render() without render_mode: make the environment with "
                                  "render_mode='rgb_array'")  # fmt: skip
            return None
        global _RENDERED_IN
        if _RENDERED_IN not in (None, os.getpid()) and os.environ.get("MUJOCO_GL", "egl") == "egl":
            # forked (Linux's default for process vector environments) from a process that rendered:
            # the inherited EGL state would hang this call
            raise RuntimeError(
                "render() in a process forked from one that has rendered hangs MuJoCo's EGL context: start "
                "the workers with spawn (gymnasium.make_vec(..., vector_kwargs={'context': 'spawn'}), "
                "SubprocVecEnv(..., start_method='spawn'))"
            )
        height, width, camera = self._frame
        frame = self.dm_env.physics.render(height, width, camera_id=camera)
        _RENDERED_IN = os.getpid()
        return frame

    def close(self) -> None:
        """Frees the simulation; a second call does nothing."""
        if self._env is not None:
            self._env.close()
            self._env = None

    def _observation(self, observation: dict) -> dict | np.ndarray:
        # Copies: composer may hand out its buffers, which the next step overwrites.
        if self._single:
            return np.array(observation[self._keys[0]])
        return {key: np.array(observation[key]) for key in self._keys}

    @staticmethod
    def _info(observation: dict) -> dict[str, Any]:
        outcome = Outcome(int(observation["outcome"][0]))
        return {"outcome": outcome.name.lower(), "is_success": outcome == Outcome.TARGET,
                "steps": int(observation["steps"][0])}  # fmt: skip


def _observation_keys(observation: str | Sequence[str] | None) -> tuple[tuple[str, ...], bool]:
    """(names, whether one Box alone) for the ``observation`` argument."""
    if observation is None:
        return NAMES, False
    single = isinstance(observation, str)
    keys = (observation,) if single else tuple(observation)
    unknown = [k for k in keys if k not in NAMES]
    if unknown or not keys:
        raise SpecError(f"observation={observation!r}: accepted: one of or a list of {', '.join(NAMES)}")
    return keys, single
