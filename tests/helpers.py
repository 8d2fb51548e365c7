"""Shared pieces of the learning tests: the open arena the short runs learn in, and their measure."""

import contextlib
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from nirl_mj.data.trajectory import Trajectory
from nirl_mj.sim import spec

ROOT = Path(__file__).resolve().parents[1]

# An open arena (no obstacle inside the walls) the rule expert crosses in ~28 decisions: short runs
# of every learner reach the target there, and a uniform random policy does not.
OPEN = spec.replace(
    spec.load_task("navigate"),
    arena={"size": (30.0, 30.0), "start": (5.0, 5.0), "target": (25.0, 25.0), "static_obstacles": 0},
    robot={"drive": "planar"},
)


def random_trajectory(rng: np.random.Generator, n: int, outcome: str) -> Trajectory:
    """n decisions of random phi(s) (valid ranges) and actions, ending in ``outcome``."""
    phi = np.zeros((n + 1, 16), dtype=np.float32)
    phi[:, :7] = rng.integers(0, 8, size=(n + 1, 7))
    phi[:, 7] = rng.integers(1, 10, size=n + 1)
    phi[:, 8] = rng.integers(0, 2, size=n + 1)
    phi[:, 9:] = rng.integers(0, 2, size=(n + 1, 7))
    task = {"arena": {"target": [90.0, 90.0]}, "control": {"speed": 2.0, "decision_period": 0.5}}
    return Trajectory(features=phi, actions=rng.integers(0, 6, size=n), ranges=np.zeros((n + 1, 9)),
                      poses=np.zeros((n + 1, 3)), times=0.5 * np.arange(n + 1),
                      arena_seed=int(rng.integers(1e9)), task=task, speed=2.0, outcome=outcome,
                      demonstrator="test")  # fmt: skip


# The tables of a tiny experiment file: a 30 m arena with 3 obstacles on the planar drive, episodes of
# ~30 decisions, 2 demonstrations; seconds per cell, big enough that the policies differ.
TINY_TABLES = """
[set.arena]
size = [30.0, 30.0]
start = [5.0, 5.0]
target = [25.0, 25.0]
static_obstacles = 3
[set.robot]
drive = "planar"
[demos]
episodes = 2
"""
TINY_CONFIG = """[config]
episodes = 1
trajectories_per_episode = 2
validation_arenas = 2
"""
"""NIRL's 1 iteration of 2 rollouts, for the tiny experiments."""


def cell_times(out: Path) -> dict[str, int]:
    """The finished cells of the experiment in ``out``, by file name: their modification times (ns)."""
    return {p.name: p.stat().st_mtime_ns for p in (out / "cells").glob("*.json")}


def killed_after_cells(argv: list[str], out: Path, cells: int, seconds: float = 180.0) -> dict[str, int]:
    """Runs ``nirl-mj ARGV`` in a process of its own and kills it (SIGKILL: no clean-up runs) once
    ``out`` holds ``cells`` finished cells (``seconds`` only bound a test that would hang); returns
    :func:`cell_times` of what it left."""
    process = subprocess.Popen([sys.executable, "-m", "nirl_mj.cli", *argv], cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    deadline = time.monotonic() + seconds
    while len(list((out / "cells").glob("*.json"))) < cells and time.monotonic() < deadline:
        time.sleep(0.02)
    process.send_signal(signal.SIGKILL)
    process.wait()
    return cell_times(out)


def progress(trajectories: list[Trajectory]) -> float:
    """Mean share of the start-to-target distance covered by the end of each episode (1: arrived)."""
    shares = []
    for t in trajectories:
        target = np.asarray(t.task["arena"]["target"])
        start, end = (np.hypot(*(t.poses[i, :2] - target)) for i in (0, -1))
        shares.append(1.0 if t.success else (start - end) / start)
    return float(np.mean(shares))


def sleeping_cell(pid_file: str) -> int:
    """An executor cell that writes its process id to ``pid_file`` and then sleeps (for ever, as far
    as a test goes): the worker an executor test kills the parent of."""
    import os
    import time

    with open(pid_file, "w") as f:
        f.write(str(os.getpid()))
    time.sleep(600)
    return 0


def damaged_bytes(raw: bytes, data) -> bytes:
    """``raw`` truncated, with a byte flipped, or replaced by JSON of another shape (drawn from
    hypothesis's ``data``)."""
    import json

    from hypothesis import strategies as st

    raw = bytearray(raw)
    how = data.draw(st.sampled_from(["truncate", "flip", "json"]))
    if how == "truncate":
        return bytes(raw[: data.draw(st.integers(0, len(raw) - 1))])
    if how == "flip":
        raw[data.draw(st.integers(0, len(raw) - 1))] ^= data.draw(st.integers(1, 255))
        return bytes(raw)
    return json.dumps(data.draw(st.sampled_from([[], [1, 2], None, "x", 3.5, {"a": [1]}]))).encode()


def rule_experiment(folder: Path, methods: str = '["rule"]') -> tuple[Path, list[str]]:
    """A tiny compare experiment of reference ``methods`` (2 runs of 1 test, 8-decision budget,
    the planar drive) written in ``folder``: its output directory and the command that runs it."""
    spec = folder / "e.toml"
    spec.write_text(f'kind = "compare"\nruns = 2\ntests = 1\nmethods = {methods}\n'
                    '[set.robot]\ndrive = "planar"\n[set.control]\nstep_budget = 8\n'
                    '[demos]\nepisodes = 1\nexpert = "rule"\n')  # fmt: skip
    out = folder / "out"
    return out, ["compare", "--task", str(spec), "--out", str(out), "--quiet", "--executor", "serial"]


def replay(env, episode, seed: int) -> tuple[dict, list, list]:
    """A Minari ``episode``'s actions driven again in ``env`` from arena ``seed``: every observation
    by key (the reset's first), the rewards and the (terminated, truncated) pairs."""
    obs, _ = env.reset(seed=seed)
    replayed = {key: [value] for key, value in obs.items()}
    rewards, ends = [], []
    for action in episode.actions:
        obs, reward, terminated, truncated, _ = env.step(action)
        rewards.append(reward)
        ends.append((terminated, truncated))
        for key, value in obs.items():
            replayed[key].append(value)
    return replayed, rewards, ends


def run_dataset_doc(path: Path) -> dict:
    """Every python block of docs/DATASET.md executed, in order, on the dataset ``path`` (named
    demos.npz: the quick start reads it from the working directory, so it runs in path's folder,
    the numpy reader as ``path``); returns the blocks' namespace."""
    assert path.name == "demos.npz", path
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "DATASET.md").read_text(), re.S)
    assert len(blocks) >= 2
    namespace = {"path": path}
    with contextlib.chdir(path.parent):
        for block in blocks:
            exec(block, namespace)  # noqa: S102 - our own documentation
    return namespace
