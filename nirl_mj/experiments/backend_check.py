"""The Warp backend against the dm_control task: same arenas, same actions, how often they agree.

What ``bench/bench_backend.py`` reports as ``same_outcome`` and ``same_first_features``, and what
``tests/test_warp_worlds.py`` holds the backend to (:mod:`nirl_mj.sim.warp_worlds`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from nirl_mj.experts.policies import PolicyAgent
from nirl_mj.sim.episode import action_command, run_episode
from nirl_mj.sim.spec import TaskSpec, load_task
from nirl_mj.sim.task import Outcome, make_env
from nirl_mj.sim.warp_worlds import WarpWorlds


def compare_with_cpu(
    task: str | TaskSpec,
    seeds: Sequence[int],
    worlds: int,
    device: str = "cpu",
    first: int = 10,
    on_batch: Callable[[int, int], None] | None = None,
) -> dict:
    """The backend against the dm_control task on the same arenas and actions: the rule policy drives
    the CPU task once in the arena of each seed, and its actions are replayed in Warp worlds,
    ``worlds`` episodes at a time (a Warp world whose episode outlives its CPU twin's actions goes on
    with action 0 until it ends or reaches the step budget).

    Returns ``episodes``; ``same_outcome`` (episodes whose Warp outcome is the CPU's);
    ``same_first_features`` (episodes whose phi(s) match exactly for the first ``first`` decisions,
    or all of them in a shorter episode); ``same_length``; ``same_last_features`` (episodes of the
    same length whose final phi(s), the state the episode ended in, match); ``decisions`` (Warp
    decisions summed over worlds); ``seconds`` (Warp's wall time, resets included); ``mismatches``
    (seed, CPU outcome, Warp outcome). ``on_batch(done, total)`` is called after every batch."""
    spec = load_task(task)
    env = make_env(spec)
    agent = PolicyAgent.named("rule")
    cpu = [run_episode(env, agent, int(s)) for s in seeds]
    sim = WarpWorlds(spec, worlds, device)
    command = action_command(spec)
    result = {"episodes": len(cpu), "same_outcome": 0, "same_first_features": 0, "same_length": 0,
              "same_last_features": 0, "decisions": 0, "seconds": 0.0, "mismatches": []}  # fmt: skip
    for start in range(0, len(cpu), worlds):
        batch = cpu[start : start + worlds]
        t0 = time.perf_counter()
        used = list(range(len(batch)))
        sim.reset(used, [t.arena_seed for t in batch])
        same = [np.array_equal(sim.observation["features"][w], t.features[0]) for w, t in enumerate(batch)]
        ended = [None] * len(batch)
        k = 0
        while any(e is None for e in ended):
            actions = [command(t.actions[k] if k < len(t) else 0)[1] for t in batch]
            actions += [command(0)[1]] * (worlds - len(batch))
            live = [w for w in used if ended[w] is None]
            sim.step(actions)
            result["decisions"] += len(live)
            k += 1
            for w in live:
                t = batch[w]
                if k <= min(first, len(t)) and not np.array_equal(
                    sim.observation["features"][w], t.features[k]
                ):
                    same[w] = False
                if sim.outcomes[w] != int(Outcome.RUNNING):
                    last = np.array_equal(sim.observation["features"][w], t.features[-1])
                    ended[w] = (Outcome(int(sim.outcomes[w])).name.lower(), k, last)
        result["seconds"] += time.perf_counter() - t0
        for w, t in enumerate(batch):
            outcome, length, last = ended[w]
            result["same_first_features"] += bool(same[w])
            result["same_length"] += length == len(t)
            result["same_last_features"] += length == len(t) and last
            if outcome == t.outcome:
                result["same_outcome"] += 1
            else:
                result["mismatches"].append((t.arena_seed, t.outcome, outcome))
        if on_batch:
            on_batch(min(start + worlds, len(cpu)), len(cpu))
    return result
