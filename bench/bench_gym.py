"""The Gymnasium adapter's overhead: decisions per second through ``gymnasium.make`` against the
raw dm_env ``env.step`` underneath.

Two environments of the same task and seed run in lockstep, driven by the rule policy (the raw
one's phi(s) decides, so both take the same actions in the same arenas); each decision is timed
on both, alternately, so that machine noise hits both alike. The Gymnasium side is what a user
gets from ``gymnasium.make("nirl_mj/Navigate-v0")`` (its OrderEnforcing and PassiveEnvChecker
wrappers included), with the full Dict observation and with ``observation="features"``. Resets
are excluded. One process, one core. Writes docs/PERFORMANCE.md.

    python bench/bench_gym.py [--decisions 3000]
"""

from __future__ import annotations

import argparse
import time

import gymnasium
import numpy as np

import nirl_mj
from nirl_mj.experts.policies import rule_policy

try:
    from report import markdown_table, write_section
except ImportError:  # run as a module
    from bench.report import markdown_table, write_section


def measure(decisions: int, observation: str | None, seed: int = 0) -> dict:
    """Seconds of ``env.step`` on the raw and the Gymnasium environment over ``decisions``."""
    raw = nirl_mj.make_env("navigate", seed=seed)
    gym = gymnasium.make("nirl_mj/Navigate-v0", observation=observation)
    raw.random_state.seed(seed)
    timestep = raw.reset()
    gym.reset(seed=seed)
    spent = {"raw": 0.0, "gym": 0.0}
    paired = []  # per decision: (raw seconds, gym seconds) of the same physics
    episodes = 0
    for i in range(decisions):
        if timestep.last():
            episodes += 1
            raw.random_state.seed(seed + episodes)
            timestep = raw.reset()
            gym.reset(seed=seed + episodes)
        action = np.int64(rule_policy(timestep.observation["features"]))
        # Alternate which goes first: neither always meets a warm or a cold cache.
        envs = [("raw", raw), ("gym", gym)]
        results = {}
        took = {}
        for name, env in envs if i % 2 else envs[::-1]:
            t0 = time.perf_counter()
            results[name] = env.step(action)
            took[name] = time.perf_counter() - t0
            spent[name] += took[name]
        paired.append((took["raw"], took["gym"]))
        timestep, out = results["raw"], results["gym"]
        assert out[2] or out[3] or not timestep.last()  # lockstep: the same episode ends
    raw_t, gym_t = np.array(paired).T
    return {"raw": decisions / spent["raw"], "gym": decisions / spent["gym"], "episodes": episodes,
            "overhead_us": 1e6 * float(np.median(gym_t - raw_t)),
            "median_raw_us": 1e6 * float(np.median(raw_t))}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--decisions", type=int, default=3000)
    args = parser.parse_args()
    rows = []
    for observation in (None, "features"):
        m = measure(args.decisions, observation)
        label = "full Dict" if observation is None else f'observation="{observation}"'
        rows.append([label, f"{m['raw']:.0f}", f"{m['gym']:.0f}", f"{m['gym'] / m['raw']:.3f}",
                     f"{m['overhead_us']:.0f} us ({100 * m['overhead_us'] / m['median_raw_us']:.1f} %)",
                     str(m["episodes"])])  # fmt: skip
        print(rows[-1])
    body = (
        f"navigate (20 obstacles, 2 m/s, tyre), rule policy, {args.decisions} decisions per row, the two "
        "environments in lockstep, each decision timed on both (resets excluded):\n\n"
        + markdown_table(
            [
                "Gymnasium observation",
                "raw env.step (decisions/s)",
                "gymnasium.make (decisions/s)",
                "ratio",
                "paired overhead",
                "episodes",
            ],
            rows,
        )  # fmt: skip
        + "\n\nThe ratio of totals carries the machine's noise (each decision's physics is timed twice, "
        "moments apart); the paired overhead, the median over decisions of (Gymnasium - raw) on the same "
        "physics, is what the adapter costs. The adapter copies the observations (composer may hand out "
        "buffers it overwrites) and builds `info`; Gymnasium's OrderEnforcing and PassiveEnvChecker "
        "wrappers add two calls."
    )
    write_section("Gymnasium adapter (bench/bench_gym.py)", body)


if __name__ == "__main__":
    main()
