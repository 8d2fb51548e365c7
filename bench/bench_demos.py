"""Demonstration throughput and what the experts' decisions cost.

For each expert on tasks/navigate.toml: trajectories and environment steps
(decisions) per second in one process, and the time spent in the expert's
``reset`` + ``act`` as a share of the time spent in ``env.step`` over the same
episodes (target: at most 10 %). Then the wall time of ``collect`` with 1 worker
(this process) and 2 (spawned processes; on a machine of 2 cores or more). Writes docs/PERFORMANCE.md.

    python bench/bench_demos.py [--episodes 20]
"""

from __future__ import annotations

import argparse
import time

from nirl_mj.experiments.demos import ExpertConfig, collect
from nirl_mj.experiments.executors import default_workers
from nirl_mj.experiments.seeds import episode_seed
from nirl_mj.experts import make_expert
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.spec import load_task
from nirl_mj.sim.task import make_env

try:
    from report import markdown_table, write_section
except ImportError:  # run as a module
    from bench.report import markdown_table, write_section


class _Timed:
    """Wraps an expert and an environment to time what each of them does."""

    def __init__(self, expert, env) -> None:
        self.expert, self.env = expert, env
        self.kind = expert.kind
        self.expert_time = self.env_time = 0.0
        self.steps = 0
        self._step = env.step
        env.step = self._timed_step

    def _timed_step(self, action):
        t0 = time.perf_counter()
        timestep = self._step(action)
        self.env_time += time.perf_counter() - t0
        self.steps += 1
        return timestep

    def reset(self, env, timestep) -> None:
        t0 = time.perf_counter()
        self.expert.reset(env, timestep)
        self.expert_time += time.perf_counter() - t0

    def act(self, timestep) -> int:
        t0 = time.perf_counter()
        action = self.expert.act(timestep)
        self.expert_time += time.perf_counter() - t0
        return action


def measure(kind: str, episodes: int) -> dict:
    spec = load_task("navigate")
    env = make_env(spec)
    timed = _Timed(make_expert(kind), env)
    t0 = time.perf_counter()
    successes = sum(run_episode(env, timed, episode_seed(0, i)).success for i in range(episodes))
    wall = time.perf_counter() - t0
    return {
        "expert": kind,
        "trajectories_per_s": episodes / wall,
        "steps_per_s": timed.steps / wall,
        "expert_ms_per_decision": 1e3 * timed.expert_time / timed.steps,
        "expert_share": timed.expert_time / timed.env_time,
        "success": successes / episodes,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args()
    rows = [measure(kind, args.episodes) for kind in ("sensor", "planner")]
    for r in rows:
        print(r)
    scaling = []
    for workers in sorted({1, min(2, default_workers())}):
        t0 = time.perf_counter()
        collect(load_task("navigate"), ExpertConfig("sensor"), args.episodes, seed=0, workers=workers)
        scaling.append((workers, time.perf_counter() - t0))
        print(f"collect, {workers} worker(s): {scaling[-1][1]:.1f} s")
    header = [
        "expert",
        "trajectories/s",
        "decisions/s",
        "expert ms/decision",
        "expert / env.step time",
        "success",
    ]
    experts = markdown_table(
        header,
        [
            [
                r["expert"],
                f"{r['trajectories_per_s']:.2f}",
                f"{r['steps_per_s']:.0f}",
                f"{r['expert_ms_per_decision']:.3f}",
                f"{r['expert_share']:.1%}",
                f"{r['success']:.0%}",
            ]
            for r in rows
        ],
    )
    workers = markdown_table(
        ["`collect` (sensor expert)", "wall time (s)", "speed-up"],
        [[f"{w} worker(s)", f"{sec:.1f}", f"{scaling[0][1] / sec:.2f}x"] for w, sec in scaling],
    )
    body = (
        f"{args.episodes} episodes of tasks/navigate.toml (tyre drive) per expert, one process; then "
        "`collect` with 1 worker (this process) and 2 (spawned; includes their start-up). Target: expert "
        "decisions at most 10 % of the simulation time.\n\n" + experts + "\n\n" + workers
    )
    if not args.no_write:
        write_section("Demonstrations (bench/bench_demos.py)", body)


if __name__ == "__main__":
    main()
