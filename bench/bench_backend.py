"""The MuJoCo Warp backend: decisions per second over N worlds, and its agreement with the CPU task.

Two measurements, one process:

1. **Speed**: N worlds of ``navigate`` (20 obstacles, 2 m/s, tyre), each in its own arena, driven
   by the rule policy on their phi(s) (its batch form, one numpy call for every world) for
   ``--decisions`` decisions after one untimed warm-up decision (Warp compiles its kernels there,
   and on a GPU the decision is captured as a CUDA graph). ``decisions_per_s`` sums over worlds:
   decisions taken by running worlds over the wall time of :meth:`WarpWorlds.step` plus the policy.
   On a GPU each world count runs twice: replaying the CUDA graph, then launch by launch
   (``graph=False``), which shows what the graph buys. Each row says where the timed wall went
   (:attr:`WarpWorlds.seconds`: host or device part, and the policy's batch), in percent. For
   comparison, the same policy on the dm_control task, one world, in this process.
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
import sys
import time

import numpy as np

from nirl_mj.experiments.backend_check import compare_with_cpu
from nirl_mj.experts.policies import PolicyAgent, rule_actions, rule_policy
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import make_env
from nirl_mj.sim.warp_worlds import WarpWorlds, check_device

try:
    from report import markdown_table, write_section
except ImportError:  # run as a module
    from bench.report import markdown_table, write_section

TASK = "navigate"
FIRST_SEED = 50_000  # arenas of no table: a benchmark only


def speed(worlds: int, device: str, decisions: int, graph: bool) -> dict:
    """Decisions per second summed over ``worlds`` worlds (the rule policy, each world in its arena),
    with the decision replayed as a CUDA graph or launched kernel by kernel."""
    t0 = time.perf_counter()
    sim = WarpWorlds(TASK, worlds, device, graph=graph)
    sim.reset(range(worlds), range(FIRST_SEED, FIRST_SEED + worlds))
    sim.step(rule_actions(sim.observation["features"]))  # warm-up: kernels compile, the graph is captured
    setup = time.perf_counter() - t0
    taken, spent, policy = 0, 0.0, 0.0
    before = dict(sim.seconds)
    for _ in range(decisions):
        t0 = time.perf_counter()
        running = int(np.count_nonzero(sim.outcomes == 0))
        actions = rule_actions(sim.observation["features"])
        policy += time.perf_counter() - t0
        sim.step(actions)
        spent += time.perf_counter() - t0
        taken += running
    parts = {name: sim.seconds[name] - before[name] for name in sim.seconds}
    parts["policy"] = policy
    split = {name: 100 * seconds / spent for name, seconds in parts.items() if seconds > 0}
    return {"worlds": worlds, "graph": sim.graphed, "graph_error": sim.graph_error, "decisions": taken,
            "seconds": spent, "decisions_per_s": taken / spent, "setup_s": setup, "split": split}  # fmt: skip


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
    parser.add_argument(
        "--device", choices=("cpu", "cuda"), default="cuda", help="Warp's device (default: cuda)"
    )
    parser.add_argument("--worlds", type=int, nargs="+", default=[1, 64, 1024, 8192])
    parser.add_argument("--decisions", type=int, default=None, help="timed decisions (default 20; quick: 3)")
    parser.add_argument(
        "--episodes",
        type=int,
        default=None,
        help="episodes of the agreement check (default 200; quick: the last world count)",
    )
    parser.add_argument(
        "--graph",
        choices=("both", "on", "off"),
        default="both",
        help="CUDA graph of a decision: both (graph, then launch by launch; default), on or off; "
        "the CPU device has no graphs (off)",
    )
    parser.add_argument("--quick", action="store_true",
                        help="tiny settings; writes no docs (else: PERFORMANCE.md's section)")  # fmt: skip
    parser.add_argument("--json", action="store_true", help="print one JSON line last")  # fmt: skip
    args = parser.parse_args()
    try:
        check_device(args.device)  # one line, not a traceback, for a device Warp cannot use here
    except (ValueError, RuntimeError) as exc:
        sys.exit(f"bench_backend.py: {exc}")
    if args.device == "cpu" and args.graph == "on":
        parser.error("--graph on: CUDA graphs need --device cuda; accepted on cpu: both, off")
    modes = (
        [False] if args.device == "cpu" else {"both": [True, False], "on": [True], "off": [False]}[args.graph]
    )
    decisions = args.decisions or (3 if args.quick else 20)
    episodes = args.episodes or (args.worlds[-1] if args.quick else 200)
    rows, last = [], {}
    for n in args.worlds:  # the first mode, then the agreement: the figures that matter come first
        last = speed(n, args.device, decisions, modes[0])
        rows.append(_row(last, modes[0]))
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
    if not args.quick:
        write_section("MuJoCo Warp backend (bench/bench_backend.py)",
                      _body(args.device, decisions, rows, cpu, check, agreement_worlds))  # fmt: skip
    for mode in modes[1:]:  # launch by launch, for comparison (the section is rewritten with it)
        rows += [_row(speed(n, args.device, decisions, mode), mode) for n in args.worlds]
        if not args.quick:
            write_section("MuJoCo Warp backend (bench/bench_backend.py)",
                          _body(args.device, decisions, rows, cpu, check, agreement_worlds))  # fmt: skip
    if args.json:
        print(json.dumps({
            "device": args.device, "worlds": last["worlds"], "graph": last["graph"],
            "decisions_per_s": round(last["decisions_per_s"], 1), "cpu_task_decisions_per_s": round(cpu, 1),
            **{key: check[key] for key in ("episodes", "same_outcome", "same_first_features", "same_length",
                                           "same_last_features", "mismatches")},
        }))  # fmt: skip


def _row(result: dict, wanted: bool) -> list[str]:
    """A table row of :func:`speed`'s result (printed as it comes)."""
    graph = "yes" if result["graph"] else (f"failed: {result['graph_error']}" if wanted else "no")
    split = ", ".join(f"{name} {share:.0f}" for name, share in result["split"].items())
    print(f"{result['worlds']} worlds, CUDA graph {graph}: {result['decisions_per_s']:.0f} decisions/s "
          f"(setup {result['setup_s']:.0f} s; % of the time: {split})", flush=True)  # fmt: skip
    return [str(result["worlds"]), graph, f"{result['decisions_per_s']:.0f}", f"{result['decisions']}",
            f"{result['setup_s']:.0f}", split]  # fmt: skip


def _card() -> str:
    """The CUDA card's name, as Warp reports it."""
    import warp as wp

    return str(wp.get_device("cuda").name)


def _body(device: str, decisions: int, rows: list, cpu: float, check: dict, agreement_worlds: int) -> str:
    """The PERFORMANCE.md section's text."""
    where = (
        f"a GPU, {_card()}"
        if device == "cuda"
        else "Warp's CPU device: these figures only show that the backend works; its speed on a GPU is "
        "not measured here"
    )
    return (
        f"Device: {where}. Task {TASK}, rule policy (its batch form), every world in its own arena; "
        f"{decisions} timed decisions after one warm-up decision (kernel compilation, the CUDA graph's "
        f"capture and the resets are in `setup`).\n\n"
        + markdown_table(["worlds", "CUDA graph", "decisions/s (all worlds)", "decisions timed", "setup (s)",
                          "% of the timed wall: part (WarpWorlds.seconds; policy: the rule's batch)"],
                         rows)
        + f"\n\nThe dm_control task, one world on one core, same process: **{cpu:.0f}** decisions/s.\n\n"
        f"Agreement with the CPU task on {check['episodes']} arenas (the rule's actions on the CPU "
        f"task replayed in {agreement_worlds} Warp worlds): same outcome **{check['same_outcome']}**, "
        f"same phi(s) for the first 10 decisions **{check['same_first_features']}**, same length "
        f"{check['same_length']}, same final phi(s) {check['same_last_features']}; mismatches (seed, "
        f"CPU, Warp): {check['mismatches'] or 'none'}."
    )  # fmt: skip


if __name__ == "__main__":
    main()
