"""Wrappers for learning on the navigation environments."""

from __future__ import annotations

from collections.abc import Callable

import gymnasium

from nirl_mj.gym.arena_stream import ArenaStream


class ArenaSeeds(gymnasium.Wrapper):
    """Every reset without a seed draws the arena of ``arena_seed(k)`` for the k-th such reset
    (k from ``start``), and remembers it in :attr:`used`: a learner's training arenas come from
    a known stream, which held-out tests can skip (``nirl_mj.experiments.seeds``). Environments
    that share a ``stream`` (vectorised training) draw from it in turn, never the same arena. With
    ``replace_given``, a reset with a seed draws from the stream too: Stable-Baselines3 seeds the
    first reset of its i-th environment with its own seed + i, an arena outside the stream."""

    def __init__(
        self,
        env: gymnasium.Env,
        arena_seed: Callable[[int], int] | None = None,
        start: int = 0,
        stream: ArenaStream | None = None,
        replace_given: bool = False,
    ) -> None:
        super().__init__(env)
        if (arena_seed is None) == (stream is None) or (stream is not None and start):
            raise ValueError("ArenaSeeds takes an arena_seed function (and a start) or a shared stream")
        self.stream = stream if stream is not None else ArenaStream(arena_seed, start)
        self.replace_given = replace_given

    @property
    def used(self) -> list[int]:
        return self.stream.used

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if seed is None or self.replace_given:
            seed = self.stream.draw()
        return self.env.reset(seed=seed, options=options)
