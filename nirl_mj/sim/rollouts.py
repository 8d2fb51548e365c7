"""One rollout interface for every backend: an agent driven once in the arena of each seed.

``rollouts(agent, seeds) -> trajectories`` (in the order of ``seeds``) is what the learners'
loop (:data:`nirl_mj.learn.loop.Rollouts`), validation and evaluation call. Two backends give it:

- ``cpu`` (the default and the reference): the dm_control task, one episode after another
  through :func:`~nirl_mj.sim.episode.run_episode`, exactly as before this interface existed;
- ``warp``: N worlds at once on MuJoCo Warp (:class:`~nirl_mj.sim.warp_worlds.WarpWorlds`, the
  ``warp`` extra), for agents that act on phi(s) alone (reference policies, learners' networks).
  Same arenas, same starts, float32 physics: not bit-identical to ``cpu`` (docs/PERFORMANCE.md).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import dm_env
import numpy as np

from nirl_mj.data.trajectory import Trajectory
from nirl_mj.sim.episode import Agent, run_episode
from nirl_mj.sim.spec import TaskSpec
from nirl_mj.sim.task import make_env
from nirl_mj.sim.warp_worlds import DEVICES, WarpWorlds

Rollouts = Callable[[Agent, Sequence[int]], list[Trajectory]]

BACKENDS = ("cpu", "warp")


@dataclass(frozen=True)
class Backend:
    """Where episodes run: ``name`` one of :data:`BACKENDS`; for ``warp`` the number of ``worlds``
    stepped at once and the Warp ``device`` (``cpu`` or ``cuda``)."""

    name: str = "cpu"
    worlds: int = 64
    device: str = "cuda"

    def __post_init__(self) -> None:
        if self.name not in BACKENDS:
            raise ValueError(f"backend {self.name!r}: accepted: {', '.join(BACKENDS)}")
        if isinstance(self.worlds, bool) or not isinstance(self.worlds, int | np.integer) or self.worlds < 1:
            raise ValueError(f"worlds must be a positive integer, got {self.worlds!r}")
        object.__setattr__(self, "worlds", int(self.worlds))
        if self.device not in DEVICES:
            raise ValueError(f"device {self.device!r}: accepted: {', '.join(DEVICES)}")

    def to_dict(self) -> dict:
        """What a run record keeps of it (nothing is kept for ``cpu``: records stay as they were)."""
        return {"name": self.name, "worlds": self.worlds, "device": self.device}


CPU = Backend()
"""The default backend."""


def cpu_rollouts(env: dm_env.Environment) -> Rollouts:
    """The reference backend: ``env`` (a task's dm_control environment), one episode at a time."""
    return lambda agent, seeds: [run_episode(env, agent, s) for s in seeds]


def make_rollouts(backend: Backend, task: TaskSpec, env: dm_env.Environment | None = None) -> Rollouts:
    """The rollouts of ``backend`` for ``task``; ``env`` is reused by the ``cpu`` backend (built from
    ``task`` when not given). The ``warp`` backend's worlds are built once, here (a minute of kernel
    compilation the first time on a machine)."""
    if backend.name == "cpu":
        return cpu_rollouts(env if env is not None else make_env(task))
    return WarpWorlds(task, backend.worlds, backend.device).rollouts
