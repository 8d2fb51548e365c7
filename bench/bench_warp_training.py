"""One NIRL training end to end on a backend, and its policy tested on the CPU task.

NIRL's default variant (60 iterations of 10 rollouts on the ``planar`` training drive) trains on
``--demos`` on the ``cpu`` backend (the dm_control task, one episode after another) or the ``warp``
one (``--worlds`` worlds on ``--device``); its selected policy is then tested on ``--tests``
held-out arenas of the CPU task (the reference), so the two backends' policies are compared on
the same arenas. A line per iteration gives the wall time since the start (the first includes
Warp's kernel compilation), so a run stopped early still says how fast it went; one JSON line
comes last (after a ``--resume``, its timings are this process's: ``resumed_at`` iterations were
done before). It imports the library, not the ``nirl-mj`` command (the GPU machine has no
rerun-sdk); ``bench/gpu_check.sh`` runs it on the CPU backend beside ``bench_backend.py`` and on
the GPU after it.

    python bench/bench_warp_training.py --demos D.npz --out RUN --backend warp --device cuda --worlds 10
    python bench/bench_warp_training.py --demos D.npz --out RUN --backend cpu
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from nirl_mj.data.dataset import DatasetError
from nirl_mj.data.rundir import RunDir, RunError
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.subjects import run_subject
from nirl_mj.experiments.training import train
from nirl_mj.learn.config import LearnerConfig
from nirl_mj.sim.rollouts import BACKENDS, Backend
from nirl_mj.sim.spec import load_task
from nirl_mj.sim.task import make_env
from nirl_mj.sim.warp_worlds import DEVICES


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--demos", required=True, help="a dataset of nirl-mj demos (.npz)")
    parser.add_argument("--out", required=True, help="the run's directory (new, or --resume)")
    parser.add_argument("--backend", choices=BACKENDS, default="warp")
    parser.add_argument("--device", choices=DEVICES, default="cuda")
    parser.add_argument(
        "--worlds", type=int, default=10, help="warp: worlds (default 10: an iteration's rollouts)"
    )
    parser.add_argument("--episodes", type=int, default=None, help="iterations (default: the variant's, 60)")
    parser.add_argument("--tests", type=int, default=100, help="held-out arenas of the CPU task (0: none)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--resume", action="store_true")
    args = parser.parse_args()
    backend = Backend(args.backend, args.worlds, args.device)
    if args.episodes is not None and args.episodes < 1:
        parser.error(f"--episodes must be at least 1, got {args.episodes}")
    config = LearnerConfig.preset("default", **({"episodes": args.episodes} if args.episodes else {}))
    before = RunDir(args.out).iterations_done() if args.resume and RunDir(args.out).is_run else 0
    start, stamps = time.perf_counter(), []

    def progress(m) -> None:
        stamps.append(time.perf_counter() - start)
        print(f"iteration {len(stamps)}: {stamps[-1]:.1f} s since the start, rollout success "
              f"{m.success_rate:.1f}", flush=True)  # fmt: skip

    task = load_task("navigate")
    try:
        record = train(args.out, task, args.demos, config, args.seed, args.resume, progress, backend)
    except (RunError, DatasetError, FileNotFoundError) as error:
        raise SystemExit(f"error: {error}") from None
    wall = time.perf_counter() - start
    steps = np.diff(stamps) if len(stamps) > 1 else np.array([])
    result = {
        "backend": backend.to_dict() if backend.name != "cpu" else {"name": "cpu"},
        "resumed_at": before,
        "iterations": len(stamps),
        "train_wall_s": round(wall, 1),
        "first_iteration_s": round(stamps[0], 1) if stamps else None,
        "median_iteration_s": round(float(np.median(steps)), 2) if steps.size else None,
        "selected_iteration": record["selected_iteration"],
    }
    if args.tests:
        subject = run_subject(args.out)
        t0 = time.perf_counter()
        seeds = subject.test_seeds(args.seed, args.tests)
        metrics, _ = evaluate(make_env(subject.task), subject.policy, seeds, "nirl")
        result |= {"tests": args.tests, "test_success": metrics["success_rate"],
                   "test_s": round(time.perf_counter() - t0, 1)}  # fmt: skip
    print(json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
