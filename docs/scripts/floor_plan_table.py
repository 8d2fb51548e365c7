"""Success per floor-plan family for every method of Table I (issue 16's layout-family experiment).

Each method's runs 0..R-1 as Table I trained them (trained on random clutter only) are tested
unchanged on each family: ``random`` (Table I's test task: 20 obstacles, 2 m/s) and the structured
families of ``tasks/structured.toml`` (``arena.floor_plan``: corridors, pockets, clusters, blocks,
rooms, slalom; 5 random obstacles besides, 2 m/s). Run r of every method is tested on the same N
held-out arenas per family (test seed r, as Table I's run r), and the sensor expert (with its
privileged range rays) drives the same arenas. Methods and where their runs come from:

- a trained run of a compare experiment: ``NAME=DIR`` (``DIR/0``, ``DIR/1``, ... are its runs;
  IRL runs and RL runs, GAIL and AIRL included);
- ``BC`` and ``DAgger``: trained here as Table I trains them (the experiment's demonstrations,
  training seed r; DAgger with the sensor expert), since their policies are not kept on disk;
- ``rule``, ``forward`` and ``sensor`` (the expert): no training.

    python docs/scripts/floor_plan_table.py --demos OUT/demos.npz --out DIR [--runs 5] [--tests 10]
        [--workers 2] [--guide target|memory] [NAME=RUNS_DIR ...]

``--guide memory`` tests every method with ``sensing.guide = "memory"`` (phi's sector V points at
the robot's memory's escape waypoint while it is stuck; the expert drives the same either way), and
trains DAgger with it. BC learns from ``--demos`` and trained runs come as they were trained: give
demonstrations and runs recorded with the same guide (not checked here).

Writes DIR/families.json (every cell, and the methods in order), families.csv, families.md and
families.png (bars: the average over runs, whiskers from the worst to the best run). A cell is one
(method, run) and computed once: rerunning with the same DIR resumes; nothing is overwritten.

    python docs/scripts/floor_plan_table.py --redraw DIR    # the tables and figure again, from DIR's cells
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
from pathlib import Path

import numpy as np

from nirl_mj.data.atomic import write_figure, write_text
from nirl_mj.data.dataset import load_dataset
from nirl_mj.data.lock import DirectoryLock, LockedError
from nirl_mj.experiments.definition import load_experiment
from nirl_mj.experiments.evaluation import metrics_of
from nirl_mj.experiments.seeds import held_out_seeds
from nirl_mj.sim import spec as specs
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import make_env

FAMILIES = ("random", "corridors", "pockets", "clusters", "blocks", "rooms", "slalom")
BUILT_HERE = ("BC", "DAgger", "rule", "forward", "sensor")


def family_task(family: str, guide: str = "target") -> specs.TaskSpec:
    """``random``: Table I's test task (tasks/table1.toml); else tasks/structured.toml with that
    family; ``guide`` is the tasks' ``sensing.guide`` (what phi's sector V points at)."""
    if family == "random":
        return specs.replace(load_experiment("table1").test_task, sensing={"guide": guide})
    structured = specs.load_task("structured")
    return specs.replace(structured, arena={"floor_plan": family}, sensing={"guide": guide})


def agent_for(method: str, run: int, runs_dir: str | None, demos_path: str, guide: str = "target"):
    """(an Agent for run_episode, the arena seeds its training saw)."""
    from nirl_mj.experts.policies import PolicyAgent

    if runs_dir is not None:
        from nirl_mj.experiments.subjects import run_subject

        subject = run_subject(Path(runs_dir) / str(run))
        return PolicyAgent(subject.policy, method), set(subject.seen)
    demos = load_dataset(demos_path)
    seen = {t.arena_seed for t in demos}
    if method == "sensor":
        from nirl_mj.experts import make_expert

        return make_expert("sensor"), set()
    if method == "BC":
        from nirl_mj.learn.bc import behaviour_cloning

        return PolicyAgent(behaviour_cloning(demos, seed=run), method), seen
    if method == "DAgger":
        from nirl_mj.experiments.dagger import train_dagger

        task = specs.replace(load_experiment("table1").task, sensing={"guide": guide})
        policy, arenas = train_dagger(task, demos, run, "sensor")
        return PolicyAgent(policy, method), seen | set(arenas)
    from nirl_mj.experts.policies import POLICIES

    return PolicyAgent(POLICIES[method], method), set()


def cell(args: tuple) -> dict:
    """One (method, run): its success on every family."""
    method, run, runs_dir, demos_path, tests, guide = args
    agent, seen = agent_for(method, run, runs_dir, demos_path, guide)
    seeds = held_out_seeds(run, tests, set())
    if seen & set(seeds):  # the test domain is disjoint by construction; checked anyway
        raise RuntimeError(f"{method} run {run}: test arenas seen in training: {sorted(seen & set(seeds))}")
    out = {"method": method, "run": run, "seeds": seeds}
    for family in FAMILIES:
        env = make_env(family_task(family, guide))
        out[family] = metrics_of([run_episode(env, agent, s) for s in seeds])
    return out


def tables(cells: list[dict], methods: list[str], out: Path) -> None:
    def success(m: str, f: str) -> list[float]:
        return [100 * c[f]["success_rate"] for c in cells if c["method"] == m]

    lines = ["| method | " + " | ".join(FAMILIES) + " |", "|---|" + "---|" * len(FAMILIES)]
    rows = ["method,family,runs,success_avg,success_best,success_worst"]
    for m in methods:
        cols = []
        for f in FAMILIES:
            v = success(m, f)
            cols.append(f"{np.mean(v):.0f} ({min(v):.0f}-{max(v):.0f})" if v else "-")
            if v:
                rows.append(f"{m},{f},{len(v)},{np.mean(v):.1f},{max(v):.0f},{min(v):.0f}")
        lines.append(f"| {m} | " + " | ".join(cols) + " |")
    write_text(out / "families.md", "\n".join(lines) + "\n")
    write_text(out / "families.csv", "\n".join(rows) + "\n")

    import matplotlib

    from nirl_mj.inspect.canvas import subplots

    fig, ax = subplots(figsize=(10, 4.2), dpi=110)
    # tab20's dark shades first (ten hues), then its light ones: no two of the first ten share a hue
    palette = matplotlib.colormaps["tab20"]

    def colours(k: int):
        return palette((2 * k) % 20 + (2 * k) // 20 % 2)

    width = 0.8 / len(methods)
    x = np.arange(len(FAMILIES))
    for k, m in enumerate(methods):
        values = [success(m, f) for f in FAMILIES]
        mean = [np.mean(v) if v else 0.0 for v in values]
        low = [mean[i] - (min(v) if v else 0.0) for i, v in enumerate(values)]
        high = [(max(v) if v else 0.0) - mean[i] for i, v in enumerate(values)]
        ax.bar(x + (k - (len(methods) - 1) / 2) * width, mean, width, label=m, yerr=[low, high],
               color=colours(k), error_kw={"elinewidth": 0.6, "capsize": 1.5})  # fmt: skip
    ax.set_xticks(x, FAMILIES)
    ax.set_ylabel("success (%)")
    ax.set_ylim(0, 105)
    runs = max(c["run"] for c in cells) + 1
    arenas = len(cells[0]["seeds"])
    ax.set_title(f"success per floor-plan family: {runs} runs x {arenas} arenas per bar (whiskers: worst to "
                 "best run)", fontsize=10)  # fmt: skip
    ax.legend(fontsize=7, ncol=len(methods), loc="upper center", bbox_to_anchor=(0.5, -0.08))
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    write_figure(out / "families.png", fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--demos", help="the experiment's demos.npz")
    parser.add_argument("--out", type=Path)
    parser.add_argument("--redraw", type=Path, metavar="DIR",
                        help="compute nothing: DIR's tables and figure from its families.json")  # fmt: skip
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--tests", type=int, default=10, help="arenas per family and run")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--guide", choices=("target", "memory"), default="target",
                        help="the test tasks' sensing.guide (default: target, the paper's phi)")  # fmt: skip
    parser.add_argument("--methods", default=",".join(BUILT_HERE), help="of: " + ",".join(BUILT_HERE))
    parser.add_argument("trained", nargs="*", help="NAME=RUNS_DIR")
    args = parser.parse_args()
    if args.redraw:
        redraw(args.redraw, parser)
        return
    if not (args.demos and args.out):
        parser.error("--demos and --out are required (or --redraw DIR)")
    sources: dict[str, str | None] = {}
    for item in args.trained:
        name, _, directory = item.partition("=")
        if not directory or not Path(directory).is_dir():
            parser.error(f"{item!r}: expected NAME=RUNS_DIR with RUNS_DIR a directory of runs 0, 1, ...")
        sources[name] = directory
    for name in filter(None, args.methods.split(",")):
        if name not in BUILT_HERE:
            parser.error(f"--methods: unknown {name!r}; accepted: {', '.join(BUILT_HERE)}")
        sources[name] = None
    args.out.mkdir(parents=True, exist_ok=True)
    try:
        with DirectoryLock(args.out, "floor_plan_table"):  # families.json is read once, then rewritten
            compute(args, sources, parser)
    except LockedError as exc:
        parser.exit(2, f"floor_plan_table: {exc}\n")


def redraw(folder: Path, parser: argparse.ArgumentParser) -> None:
    """The tables and figure of ``folder`` from its stored cells, the methods in their stored order
    (files written before it was stored: the order of families.md's rows)."""
    store = folder / "families.json"
    if not store.is_file():
        parser.error(f"{store}: not found")
    done = json.loads(store.read_text())
    methods = done.get("methods")
    if methods is None:  # "| NAME | ..." after the header and its rule (a name may hold commas)
        rows = (folder / "families.md").read_text().splitlines()[2:]
        methods = [row.split("|")[1].strip() for row in rows if row.startswith("|")]
    with DirectoryLock(folder, "floor_plan_table"):
        tables(done["cells"], methods, folder)


def compute(
    args: argparse.Namespace, sources: dict[str, str | None], parser: argparse.ArgumentParser
) -> None:
    """The cells ``--out`` lacks, each stored as it finishes, then the tables."""
    store = args.out / "families.json"
    done = json.loads(store.read_text()) if store.is_file() else {"tests": args.tests, "cells": []}
    done.setdefault("guide", "target")  # files written before --guide existed
    if not done["cells"]:
        done["guide"] = args.guide
    if (done["tests"], done["guide"]) != (args.tests, args.guide):
        held = f"--tests {done['tests']} --guide {done['guide']}"
        parser.error(f"{store} holds cells of {held}; use another --out")
    finished = {(c["method"], c["run"]) for c in done["cells"]}
    work = [(m, r, d, args.demos, args.tests, args.guide)
            for r in range(args.runs) for m, d in sources.items() if (m, r) not in finished]  # fmt: skip
    with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
        for k, result in enumerate(pool.imap_unordered(cell, work), 1):
            done["cells"].append(result)
            write_text(store, json.dumps(done, indent=1))  # after every cell: interruptible
            rates = " ".join(f"{f[:4]} {100 * result[f]['success_rate']:.0f}" for f in FAMILIES)
            print(f"[{k}/{len(work)}] {result['method']} run {result['run']}: {rates}", flush=True)
    done["methods"] = list(sources)  # the figure's order, for --redraw
    write_text(store, json.dumps(done, indent=1))
    tables(done["cells"], done["methods"], args.out)
    print(f"wrote {args.out}/families.md, .csv, .png, .json")


if __name__ == "__main__":
    main()
