"""The arenas of a learner's training, drawn in order from a seed stream: plain Python, so that code
without the Gymnasium extra (an installed method that never drives, ``experiments.plugins``) can
hold one; ``gym.wrappers.ArenaSeeds`` resets its environments from it."""

from __future__ import annotations

from collections.abc import Callable


class ArenaStream:
    """The arenas of a learner's training: the k-th draw (k from ``start``) is ``arena_seed(k)``,
    whichever of several environments asks for it, and every draw is remembered in :attr:`used`."""

    def __init__(self, arena_seed: Callable[[int], int], start: int = 0) -> None:
        self._arena_seed = arena_seed
        self._next = start
        self.used: list[int] = []

    def draw(self) -> int:
        seed = self._arena_seed(self._next)
        self._next += 1
        self.used.append(seed)
        return seed
