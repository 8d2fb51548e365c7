"""Transitions: the pairs (s, a, s') of trajectories, one row each, as every learner reads them.

NIRL's loop fits its SARSA / Q targets on them (``nirl_mj.learn.loop``), and GAIL's and AIRL's
discriminators classify them (``nirl_mj.experiments.adversarial``): one class, so that both read
an episode's end the same way. A row is ``terminal`` where its trajectory ended in a terminal
state (an arrival, a collision or a physics error, ``TERMINAL_OUTCOMES``); a timeout is a
truncation, and its last row bootstraps. An *absorbing* row is the pair (s_a, ., s_a) of the
absorbing state that follows a terminal one (Kostrikov et al. 2019): its states and action are
zeros and never read.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from nirl_mj.data.features import N_FEATURES
from nirl_mj.data.trajectory import TERMINAL_OUTCOMES, Trajectory, require_discrete


@dataclass(frozen=True)
class Transitions:
    """Rows of (s, a, s'): ``phi`` (N, 16) phi(s) (or the inputs a network reads, :meth:`mapped`),
    ``action`` (N,), ``next_phi`` (N, 16) phi(s') (the episode's end s_T on a terminal row),
    ``next_action`` (N,) the action taken in s' (-1 on a trajectory's last row), ``terminal`` (N,)
    bool, ``terminal_value`` (N,) the value the outcome reading gives a terminal row's end (0 unless
    built with an arrival value: ``learn/terminal.py``), ``progress`` (N,) the travel towards the
    target in units of one decision's travel (only the progress control reads it; else 0),
    ``remaining`` (N,) the rows from this one to its trajectory's end, this one included (n-step
    targets stop there), and ``absorbing`` (N,) bool."""

    phi: np.ndarray
    action: np.ndarray
    next_phi: np.ndarray
    next_action: np.ndarray
    terminal: np.ndarray
    terminal_value: np.ndarray
    progress: np.ndarray
    remaining: np.ndarray
    absorbing: np.ndarray

    def __len__(self) -> int:
        return len(self.action)

    @classmethod
    def pairs(
        cls, phi: np.ndarray, action: np.ndarray, next_phi: np.ndarray, terminal: np.ndarray
    ) -> Transitions:
        """Rows of single steps (a vectorised environment's): no next action, none absorbing."""
        n = len(action)
        return cls(phi, action, next_phi, np.full(n, -1, np.int64), np.asarray(terminal, bool), np.zeros(n),
                   np.zeros(n), np.ones(n, np.int64), np.zeros(n, bool))  # fmt: skip

    @classmethod
    def empty(cls, width: int = N_FEATURES) -> Transitions:
        return cls.pairs(np.zeros((0, width)), np.zeros(0, np.int64), np.zeros((0, width)), np.zeros(0, bool))

    @classmethod
    def absorbing_pairs(cls, count: int, width: int = N_FEATURES) -> Transitions:
        """``count`` rows (s_a, ., s_a): zeros, terminal and absorbing."""
        zeros = np.zeros((count, width), np.float32)
        ones = np.ones(count, bool)
        rows = cls.pairs(zeros, np.zeros(count, np.int64), zeros, ones)
        return dataclasses.replace(rows, absorbing=ones)

    @classmethod
    def of(
        cls,
        trajectories: Sequence[Trajectory],
        arrival_value: float = 0.0,
        progress: bool = False,
        absorbing: bool = False,
    ) -> Transitions:
        """The rows of ``trajectories``; an ``arrival_value`` other than 0 reads each episode's
        outcome (the task's: an arrival ends worth it, any other end 0), ``progress`` the robot's
        poses and the task's target (the progress control's reward), and ``absorbing`` adds one
        absorbing row after each terminal trajectory."""
        require_discrete(trajectories)
        parts = []
        for t in trajectories:
            n = len(t)
            if n == 0:
                continue
            terminal = np.zeros(n, bool)
            value = np.zeros(n)
            if t.outcome in TERMINAL_OUTCOMES:
                terminal[-1] = True
                if arrival_value:
                    value[-1] = arrival_value if t.outcome == "target" else 0.0
            travel = np.zeros(n)
            if progress:
                target = np.asarray(t.task["arena"]["target"], dtype=np.float64)
                distance = np.hypot(*(t.poses[:, :2] - target).T)
                per_step = t.task["control"]["speed"] * t.task["control"]["decision_period"]
                travel = (distance[:-1] - distance[1:]) / per_step
            next_action = np.append(t.actions[1:], -1).astype(int)
            parts.append(cls(t.features[:-1], t.actions.astype(int), t.features[1:], next_action, terminal,
                             value, travel, np.arange(n, 0, -1), np.zeros(n, bool)))  # fmt: skip
            if absorbing and terminal[-1]:
                parts.append(cls.absorbing_pairs(1, t.features.shape[1]))
        return cls.concat(parts) if parts else cls.empty()

    @classmethod
    def concat(cls, parts: Sequence[Transitions]) -> Transitions:
        return cls(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in dataclasses.fields(cls)))

    def take(self, rows: np.ndarray | slice) -> Transitions:
        """The rows ``rows`` (indices or a slice)."""
        return Transitions(*(getattr(self, f.name)[rows] for f in dataclasses.fields(self)))

    def mapped(self, inputs: Callable[[np.ndarray], np.ndarray]) -> Transitions:
        """The same rows with ``inputs`` applied to ``phi`` and ``next_phi`` (an absorbing row's
        zeros stay zeros: they are never read)."""
        phi, next_phi = (np.where(self.absorbing[:, None], 0.0, inputs(v)).astype(np.float32)
                         for v in (self.phi, self.next_phi))  # fmt: skip
        return dataclasses.replace(self, phi=phi, next_phi=next_phi)

    def arrays(self) -> dict[str, np.ndarray]:
        """Every field by name (for a checkpoint's .npz)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> Transitions:
        """The rows saved by :meth:`arrays`; a field saved before it existed takes the value that
        reproduces those rows (``remaining`` 1: one-step rows; ``absorbing`` False)."""
        n = len(arrays["action"])
        fallbacks = {"remaining": np.ones(n, np.int64), "absorbing": np.zeros(n, bool)}
        return cls(*(np.array(arrays[f.name]) if f.name in arrays else fallbacks[f.name]
                     for f in dataclasses.fields(cls)))  # fmt: skip
