"""Demonstrators: who drives the robot when demonstrations are recorded.

An expert is reset at the start of every episode with the environment and its
first timestep, then asked for one action (0..5) per timestep. What it may
look at differs: the planner reads the whole arena through ``env``; the
sensor-based expert only ever reads ``timestep.observation``.
"""

from __future__ import annotations

from typing import Protocol

import dm_env


class Expert(Protocol):
    """The interface every demonstrator implements."""

    kind: str
    """Short name recorded with every trajectory, e.g. ``"planner"``."""

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        """Called after ``env.reset()``, before the first :meth:`act` of an episode."""

    def act(self, timestep: dm_env.TimeStep) -> int:
        """The action 0..5 for the current timestep."""
