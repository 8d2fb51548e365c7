"""The MuJoCo Warp backend: decisions per second over N worlds, and its agreement with the CPU task.

Two measurements, one process:

1. **Speed**: N worlds of ``navigate`` (20 obstacles, 2 m/s, tyre), each in its own arena, driven
   by the rule policy on their phi(s) for ``--decisions`` decisions after one untimed warm-up
   decision (Warp compiles its kernels there). ``decisions_per_s`` sums over worlds: decisions
   taken by running worlds over the wall time of :meth:`WarpWorlds.step` plus the policy.
   For comparison, the same policy on the dm_control task, one world, in this process.
2. **Agreement** (:func:`nirl_mj.experiments.backend_check.compare_with_cpu`): the rule policy
   drives the CPU task once in each of ``--episodes`` arenas, and its actions are replayed in Warp
   worlds: ``same_outcome`` counts the episodes whose outcome matches, ``same_first_features``
   those whose first 10 decisions' phi(s) match exactly.

    python bench/bench_backend.py --device cuda                       # 1, 64, 1024, 8192 worlds
    python bench/bench_backend.py --device cpu --worlds 4 --quick --json   # a few minutes on 2 cores

Without ``--quick`` it writes its section of docs/PERFORMANCE.md; ``--json`` prints one JSON line
(the last world count's speed and the agreement) as the last line.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from nirl_mj.experiments.backend_check import compare_with_cpu
from nirl_mj.experts.policies import PolicyAgent, rule_policy
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import make_env
from nirl_mj.sim.warp_worlds import WarpWorlds

try:
    from report import markdown_table, write_section
except ImportError:  # run as a module
    from bench.report import markdown_table, write_section

TASK = "navigate"
FIRST_SEED = 50_000  # arenas of no table: a benchmark only


def speed(worlds: int, device: str, decisions: int) -> dict:
    """Decisions per second summed over ``worlds`` worlds (the rule policy, each world in its arena)."""
    t0 = time.perf_counter()
    sim = WarpWorlds(TASK, worlds, device)
    sim.reset(range(worlds), range(FIRST_SEED, FIRST_SEED + worlds))
    sim.step([rule_policy(phi) for phi in sim.observation["features"]])  # warm-up: kernels compile here
    setup = time.perf_counter() - t0
    taken, spent = 0, 0.0
    for _ in range(decisions):
        t0 = time.perf_counter()
        running = int(np.count_nonzero(sim.outcomes == 0))
        sim.step([rule_policy(phi) for phi in sim.observation["features"]])
        spent += time.perf_counter() - t0
        taken += running
    return {"worlds": worlds, "decisions": taken, "seconds": spent, "decisions_per_s": taken / spent,
            "setup_s": setup}  # fmt: skip


def cpu_speed(decisions: int) -> float:
    """Decisions per second of the dm_control task on one core, the same policy."""
    env = make_env(TASK)
    agent = PolicyAgent(rule_policy, "rule")
    taken, spent, seed = 0, 0.0, FIRST_SEED
    while taken < decisions:
        t0 = time.perf_counter()
        taken += len(run_episode(env, agent, seed))
        spent += time.perf_counter() - t0
        seed += 1
    return taken / spent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--device", choices=("cpu", "cuda"), default="cuda")
    parser.add_argument("--worlds", type=int, nargs="+", default=[1, 64, 1024, 8192])
    parser.add_argument("--decisions", type=int, default=None, help="timed decisions (default 20; quick: 3)")
    parser.add_argument(
        "--episodes",
        type=int,
        default=None,
        help="episodes of the agreement check (default 200; quick: the last world count)",
    )
    parser.add_argument("--quick", action="store_true", help="tiny settings; writes no docs")
    parser.add_argument("--json", action="store_true", help="print one JSON line last")  # fmt: skip
    args = parser.parse_args()
    decisions = args.decisions or (3 if args.quick else 20)
    episodes = args.episodes or (args.worlds[-1] if args.quick else 200)
    rows, last = [], {}
    for n in args.worlds:
        last = speed(n, args.device, decisions)
        rows.append(
            [str(n), f"{last['decisions_per_s']:.0f}", f"{last['decisions']}", f"{last['setup_s']:.0f}"]
        )
        print(
            f"{n} worlds: {last['decisions_per_s']:.0f} decisions/s (setup {last['setup_s']:.0f} s)",
            flush=True,
        )
    cpu = cpu_speed(200 if args.quick else 2000)
    print(f"dm_control task, one world: {cpu:.0f} decisions/s", flush=True)
    agreement_worlds = min(args.worlds[-1], episodes)
    check = compare_with_cpu(
        TASK,
        range(FIRST_SEED, FIRST_SEED + episodes),
        agreement_worlds,
        args.device,
        on_batch=lambda done, total: print(f"agreement: {done}/{total} episodes", flush=True),
    )
    summary = {
        "device": args.device,
        "worlds": last["worlds"],
        "decisions_per_s": round(last["decisions_per_s"], 1),
        "cpu_task_decisions_per_s": round(cpu, 1),
        "episodes": check["episodes"],
        "same_outcome": check["same_outcome"],
        "same_first_features": check["same_first_features"],
        "same_length": check["same_length"],
        "same_last_features": check["same_last_features"],
        "mismatches": check["mismatches"],
    }
    if not args.quick:
        where = {"cpu": "Warp's CPU device: these figures only show that the backend works; its speed "
                        "on a GPU is not measured here",
                 "cuda": "a GPU (the card is in the machine line)"}[args.device]  # fmt: skip
        body = (
            f"Device: {where}. Task {TASK}, rule policy, every world in its own arena; {decisions} timed "
            f"decisions after one warm-up decision (kernel compilation and the resets are in `setup`).\n\n"
            + markdown_table(["worlds", "decisions/s (all worlds)", "decisions timed", "setup (s)"], rows)
            + f"\n\nThe dm_control task, one world on one core, same process: **{cpu:.0f}** decisions/s.\n\n"
            f"Agreement with the CPU task on {check['episodes']} arenas (the rule's actions on the CPU "
            f"task replayed in {agreement_worlds} Warp worlds): same outcome **{check['same_outcome']}**, "
            f"same phi(s) for the first 10 decisions **{check['same_first_features']}**, same length "
            f"{check['same_length']}, same final phi(s) {check['same_last_features']}; mismatches (seed, "
            f"CPU, Warp): {check['mismatches'] or 'none'}."
        )  # fmt: skip
        write_section("MuJoCo Warp backend (bench/bench_backend.py)", body)
    if args.json:
        print(json.dumps(summary))


if __name__ == "__main__":
    main()
