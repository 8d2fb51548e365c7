"""Wrappers for learning on the navigation environments."""

from __future__ import annotations

from collections.abc import Callable

import gymnasium


class ArenaSeeds(gymnasium.Wrapper):
    """Every reset without a seed draws the arena of ``arena_seed(k)`` for the k-th such reset
    (k from ``start``), and remembers it in :attr:`used`: a learner's training arenas come from
    a known stream, which held-out tests can skip (``nirl_mj.experiments.seeds``)."""

    def __init__(self, env: gymnasium.Env, arena_seed: Callable[[int], int], start: int = 0) -> None:
        super().__init__(env)
        self._arena_seed = arena_seed
        self.used: list[int] = []
        self._next = start

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if seed is None:
            seed = self._arena_seed(self._next)
            self._next += 1
            self.used.append(seed)
        return self.env.reset(seed=seed, options=options)
