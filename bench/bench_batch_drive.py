"""The Warp worlds' host cost of planning a decision's wheel commands, per world, on the CPU.

At 16,384 worlds on an H200 the commands took 27 % of a decision's wall time
(docs/results/gpu_backend/h200_speed.log), when ``WarpWorlds.step`` planned each world's commands
with its own :class:`~nirl_mj.sim.drive.DriveController` in a Python loop. This benchmark times
that loop against :class:`~nirl_mj.sim.drive.BatchDriveController`, which ``WarpWorlds`` uses
since, on the same actions: the sensor expert's, replayed from ``--episodes`` demonstrations, and
uniform random ones (its worst case), for the ``tyre`` and ``planar`` drives; both give the same
commands bit for bit (checked here too). Host-only: no simulator, no GPU.

    python bench/bench_batch_drive.py                  # 1,024 and 16,384 worlds, ~2 min
    python bench/bench_batch_drive.py --quick          # 64 worlds; writes no docs
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from nirl_mj.experiments.demos import ExpertConfig, collect
from nirl_mj.sim.drive import BatchDriveController, DriveController, body_twist
from nirl_mj.sim.spec import load_task
from nirl_mj.sim.task import checked_action, checked_actions

try:
    from report import markdown_table, write_section
except ImportError:  # run as a module
    from bench.report import markdown_table, write_section


def streams(
    demos: list[np.ndarray], n: int, decisions: int, seed: int
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Actions (decisions, n) and episode starts (decisions, n) of two streams: ``expert``, each world
    replaying demonstrations one after another from a random point of its first; ``random``,
    uniform actions in episodes of 60-180 decisions (the worst case: many distinct pairs)."""
    rng = np.random.default_rng(seed)
    expert, starts = np.zeros((decisions, n), np.int64), np.zeros((decisions, n), bool)
    for w in range(n):
        demo, t = demos[rng.integers(len(demos))], int(rng.integers(60))
        for k in range(decisions):
            if t >= len(demo):
                demo, t, starts[k, w] = demos[rng.integers(len(demos))], 0, True
            expert[k, w], t = demo[t], t + 1
    random_starts = rng.random((decisions, n)) < 1 / 120
    return {"expert": (expert, starts), "random": (rng.integers(0, 6, (decisions, n)), random_starts)}


def time_both(
    actions: np.ndarray, starts: np.ndarray, planar: bool, args: tuple[float, float, float, float]
) -> tuple[float, float]:
    """Seconds of the per-world loop and of the batch controller over ``actions`` (decisions, N),
    each world's controllers reset where ``starts`` says (untimed)."""
    decisions, n = actions.shape
    n_cmd = round(args[1] / args[2])
    loop_out, batch_out = np.zeros((n_cmd, n, 3), np.float32), np.zeros((n_cmd, n, 3), np.float32)
    plans: dict = {}
    drives = [DriveController(cache=plans) for _ in range(n)]
    batch = BatchDriveController(n, *args, convert=body_twist if planar else None)
    worlds = np.arange(n)
    loop_s = batch_s = 0.0
    for k in range(decisions):
        for w in np.flatnonzero(starts[k]).tolist():
            drives[w].reset()
        batch.reset(np.flatnonzero(starts[k]))
        t0 = time.perf_counter()
        row = actions[k].tolist()
        for w in range(n):  # WarpWorlds.step before the batch controller
            plan = drives[w].plan(checked_action(row[w]), *args)
            loop_out[:, w] = body_twist(plan) if planar else plan
        t1 = time.perf_counter()
        batch.plan(worlds, checked_actions(actions[k], worlds), batch_out)
        batch_s += time.perf_counter() - t1
        loop_s += t1 - t0
        if not np.array_equal(loop_out, batch_out):
            raise AssertionError(f"decision {k}: the batch controller's commands differ from the loop's")
    return loop_s, batch_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", type=int, nargs="+", default=None, help="default 1024 16384 (quick: 64)")
    parser.add_argument("--decisions", type=int, default=40)
    parser.add_argument("--episodes", type=int, default=30, help="sensor-expert demonstrations replayed")
    parser.add_argument("--quick", action="store_true", help="tiny settings; writes no docs")
    args = parser.parse_args()
    task = load_task("navigate")
    control = task.control
    plan_args = (control.speed, control.decision_period, control.command_period, control.max_accel)
    demos = [t.actions.astype(np.int64) for t in collect(task, ExpertConfig("sensor"), args.episodes, seed=0)]
    rows = []
    for n in args.worlds or ([64] if args.quick else [1024, 16384]):
        for stream, (actions, starts) in streams(demos, n, args.decisions, seed=n).items():
            for planar in (False, True):
                loop_s, batch_s = time_both(actions, starts, planar, plan_args)
                per = 1e6 / (n * args.decisions)
                drive = "planar" if planar else "tyre"
                line = f"{n} worlds, {stream} actions, {drive}: loop {loop_s * per:.2f} us, batch "
                print(
                    line + f"{batch_s * per:.2f} us per world-decision ({loop_s / batch_s:.1f}x)", flush=True
                )
                rows.append([str(n), stream, drive, f"{loop_s * per:.2f}", f"{batch_s * per:.2f}",
                             f"{loop_s / batch_s:.1f}x"])  # fmt: skip
    if not args.quick:
        write_section(
            "Warp worlds' drive commands (bench/bench_batch_drive.py)",
            f"Host time to plan one decision's wheel commands, per world, over {args.decisions} decisions, "
            "one process; actions: `expert`, the sensor expert's (each world replaying "
            f"{args.episodes} demonstrations one after another, its controllers reset at each start), "
            "or `random`, uniform (episodes of about 120 decisions: many distinct pairs, the worst "
            "case). The batch controller's commands are checked equal to the loop's at every decision.\n\n"
            + markdown_table(
                [
                    "worlds",
                    "actions",
                    "drive",
                    "per-world loop (us)",
                    "BatchDriveController (us)",
                    "speed-up",
                ],
                rows,
            ),  # fmt: skip
        )


if __name__ == "__main__":
    main()
