"""Fault injection: kill -9 at random moments of train, rl, compare, demos, export and run, then resume.

For each command, a reference run to completion; then ``--kills`` times: the same command in a
fresh output, killed (SIGKILL: no clean-up runs) after a random delay drawn from the reference's
duration, then run again as a user would (``--resume`` where the command takes it; ``demos`` and
``export`` with ``--overwrite``; else the same command); its results must equal the reference's
bit for bit where compared, timing fields aside: a run's results.json and NIRL policy, a
comparison's cell records, a training's policy, checkpoint and metrics, an RL run's record and its
models' parameters (PPO on the task's reward, a checkpoint every 5,000 decisions, chosen on
validation arenas: a resume replays it from its seed), a dataset's arrays, an export's episodes,
steps and actions. Tiny settings (a 24 m arena, the planar drive), so a kill
lands anywhere: in start-up, in the middle of a write, or after the end. Prints one line per kill
and a summary; exit status 1 if any resume lost or changed anything.

    python bench/fault_injection.py [--kills 10] [--seed 0]      (6 commands x kills in all)
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TASK = [arg for kv in ("arena.size=[24.0, 24.0]", "arena.start=[4.0, 4.0]", "arena.target=[20.0, 20.0]",
                       "arena.static_obstacles=3", "arena.clear_radius=3.0", 'robot.drive="planar"')
        for arg in ("--set", kv)]  # fmt: skip
LEARNER = ["--config", "trajectories_per_episode=2", "--config", "validation_arenas=2", "--config",
           "replay_episodes=2"]  # fmt: skip
EXPERIMENT = """kind = "compare"
runs = 2
tests = 2
methods = ["NIRL", "BC", "rule"]
[set.arena]
size = [24.0, 24.0]
start = [4.0, 4.0]
target = [20.0, 20.0]
static_obstacles = 3
clear_radius = 3.0
[set.robot]
drive = "planar"
[demos]
episodes = 2
[config]
episodes = 2
trajectories_per_episode = 2
validation_arenas = 2
"""


def npz_digest(path: Path) -> str:
    import numpy as np

    h = hashlib.sha256()
    with np.load(path, allow_pickle=False) as data:
        for key in sorted(data.files):
            h.update(key.encode())
            h.update(np.ascontiguousarray(data[key]).tobytes())
    return h.hexdigest()


def without_times(value):
    """JSON without the fields that hold wall-clock times."""
    if isinstance(value, dict):
        return {k: without_times(v) for k, v in value.items() if k not in ("seconds", "attempts", "wall_s")}
    if isinstance(value, list):
        return [without_times(v) for v in value]
    return value


def train_result(out: Path) -> dict:
    return {"policy": npz_digest(out / "policy.npz"), "checkpoint": npz_digest(out / "checkpoint.npz"),
            "metrics": (out / "metrics.jsonl").read_text(),
            "selection": json.loads((out / "run.json").read_text())["selection"]}  # fmt: skip


def rl_result(out: Path) -> dict:
    import zipfile

    models = {}
    for path in sorted(out.glob("*.zip")):  # parameters and optimiser: a zip's own bytes hold its write time
        with zipfile.ZipFile(path) as archive:
            models[path.name] = {n: hashlib.sha256(archive.read(n)).hexdigest()
                                 for n in archive.namelist() if n.endswith(".pth")}  # fmt: skip
    return {"record": json.loads((out / "run.json").read_text()), **models}


def compare_result(out: Path) -> dict:
    return {p.name: without_times(json.loads(p.read_text())) for p in sorted((out / "cells").glob("*.json"))}


def demos_result(out: Path) -> dict:
    return {"demos": npz_digest(out)}


def run_result(out: Path) -> dict:
    results = without_times(json.loads((out / "results.json").read_text()))
    return {
        "results": json.dumps(results, sort_keys=True),
        "policy": npz_digest(out / "runs/NIRL/0/policy.npz"),
    }


def export_result(out: Path) -> dict:
    import minari

    dataset = minari.load_dataset(out.name)
    return {"episodes": dataset.total_episodes, "steps": dataset.total_steps,
            "actions": [list(map(int, e.actions)) for e in dataset.iterate_episodes()]}  # fmt: skip


def commands(
    work: Path,
) -> dict[str, tuple[Callable[[Path], list[str]], Callable[[Path], list[str]], Callable]]:
    """Per command: the first call, the call after a kill (the first with the flags a user adds to
    rerun it), and what its results are."""
    demos = work / "demos.npz"
    spec = work / "experiment.toml"
    spec.write_text(EXPERIMENT)
    nirl = [sys.executable, "-m", "nirl_mj.cli"]
    first = {
        "train": lambda o: [
            *nirl,
            "train",
            "--demos",
            str(demos),
            "--out",
            str(o),
            "--episodes",
            "3",
            *TASK,
            *LEARNER,
        ],  # fmt: skip
        "rl": lambda o: [
            *nirl,
            "rl",
            "--steps",
            "11000",
            "--envs",
            "2",
            "--selection",
            "validation_success",
            "--out",
            str(o),
            *TASK,
        ],  # fmt: skip
        "compare": lambda o: [*nirl, "compare", "--task", str(spec), "--out", str(o), "--workers", "2"],
        "demos": lambda o: [
            *nirl,
            "demos",
            "--episodes",
            "3",
            "--seed",
            "4",
            "--workers",
            "2",
            "--out",
            str(o),
            *TASK,
        ],  # fmt: skip
        "run": lambda o: [
            *nirl,
            "run",
            "--demos",
            "2",
            "--episodes",
            "2",
            "--tests",
            "2",
            "--workers",
            "2",
            "--out",
            str(o),
            *TASK,
        ],  # fmt: skip
        "export": lambda o: [*nirl, "export", str(demos), "--to", "minari", "--id", o.name],
    }

    def train_again(o: Path) -> list[str]:
        # as the refusal says: --resume once the run has started (its run.json), else the same command
        if (o / "run.json").is_file():
            return [*nirl, "train", "--demos", str(demos), "--out", str(o), "--resume"]
        return first["train"](o)

    def run_again(o: Path) -> list[str]:
        # as its refusal says: --resume once the job has written anything in --out, else the same command
        return [*first["run"](o), "--resume"] if o.is_dir() and any(o.iterdir()) else first["run"](o)

    def rl_again(o: Path) -> list[str]:
        if (o / "run.json").is_file():
            return [*nirl, "rl", "--out", str(o), "--resume"]
        return first["rl"](o)

    again = {"train": train_again, "rl": rl_again, "compare": first["compare"],
             "demos": lambda o: [*first["demos"](o), "--overwrite"],
             "run": run_again,
             "export": lambda o: [*first["export"](o), "--overwrite"]}  # fmt: skip
    results = {"train": train_result, "rl": rl_result, "compare": compare_result, "demos": demos_result,
               "run": run_result, "export": export_result}  # fmt: skip
    quiet = lambda call: lambda o: [*call(o), "--quiet"]  # noqa: E731
    return {name: (quiet(first[name]), quiet(again[name]), results[name]) for name in first}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kills", type=int, default=10, help="kills per command (default 10: 60 in all)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--only", default=None, help="comma-separated commands")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    failures, kills = [], 0
    with tempfile.TemporaryDirectory(prefix="nirl-mj-faults-") as tmp:
        work = Path(tmp)
        os.environ["MINARI_DATASETS_PATH"] = str(work / "minari")  # this process reads the exports too
        env = dict(os.environ)
        demos = [
            "demos",
            "--episodes",
            "2",
            "--seed",
            "1",
            "--workers",
            "1",
            "--out",
            str(work / "demos.npz"),
        ]
        subprocess.run(
            [sys.executable, "-m", "nirl_mj.cli", *demos, "--quiet", *TASK], check=True, cwd=ROOT, env=env
        )
        todo = commands(work)
        for name in args.only.split(",") if args.only else todo:
            first, again, result = todo[name]
            ref = work / "ns" / f"{name}-ref-v0" if name == "export" else work / f"{name}-ref"
            start = time.perf_counter()
            subprocess.run(first(ref), check=True, cwd=ROOT, env=env, stdout=subprocess.DEVNULL)
            took = time.perf_counter() - start
            reference = result(ref)
            for k in range(args.kills):
                out = work / "ns" / f"{name}-k{k}-v0" if name == "export" else work / f"{name}-k{k}"
                delay = rng.uniform(0.05, 0.95) * took
                process = subprocess.Popen(first(out), cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                                           stderr=subprocess.DEVNULL)  # fmt: skip
                time.sleep(delay)
                process.send_signal(signal.SIGKILL)
                process.wait()
                kills += 1
                done = subprocess.run(again(out), cwd=ROOT, env=env, capture_output=True, text=True)
                ok = done.returncode == 0 and result(out) == reference
                verdict = (
                    "identical" if ok else f"DIFFERENT ({done.returncode}: {done.stderr.strip()[-200:]})"
                )
                print(f"{name} kill {k} at {delay:.1f} s of {took:.1f}: {verdict}")
                if not ok:
                    failures.append(f"{name} kill {k}")
    print(
        f"{kills} kills, {kills - len(failures)} resumed identical"
        + (f"; failed: {failures}" if failures else "")
    )
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
