"""How faithfully each drive fidelity executes the six actions, through the environment.

On an empty floor at 1, 2 and 3 m/s with the task's default (auto) timestep:
the steady forward speed error, the heading change of a 60-degree turn taken
from cruise, and the end-pose gap to the ``planar`` drive after a fixed
20-action sequence, as a share of the distance travelled. Writes
docs/PERFORMANCE.md.

    python bench/drive_accuracy.py
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from nirl_mj.sim import spec as specs
from nirl_mj.sim.task import make_env

try:
    from report import markdown_table, write_section
except ImportError:  # run as a module
    from bench.report import markdown_table, write_section

SEQUENCE = [0, 1, 0, 2, 0, 0, 3, 4, 0, 5, 5, 0, 1, 1, 0, 3, 0, 2, 4, 0]
START = (20.0, 50.0)


def _task(drive: str, speed: float) -> specs.TaskSpec:
    return specs.from_dict(
        {
            "arena": {"static_obstacles": 0, "start": list(START), "start_yaw": 0, "target": [90, 50]},
            "robot": {"drive": drive},
            "control": {"speed": speed},
        }
    )


def _poses(task: specs.TaskSpec, actions: list[int]) -> np.ndarray:
    env = make_env(task, seed=0)
    timestep = env.reset()
    poses = [timestep.observation["pose"].copy()]
    for a in actions:
        timestep = env.step(a)
        poses.append(timestep.observation["pose"].copy())
    return np.array(poses)


def measure(drive: str, speed: float) -> dict:
    task = _task(drive, speed)
    cruise = _poses(task, [0] * 8)
    v = (cruise[-1, 0] - cruise[-3, 0]) / (2 * task.control.decision_period)
    turn = _poses(task, [0] * 4 + [2, 0])
    end = _poses(task, SEQUENCE)[-1]
    reference = _poses(_task("planar", speed), SEQUENCE)[-1]
    travelled = math.hypot(reference[0] - START[0], reference[1] - START[1])
    return {
        "drive": drive,
        "speed": speed,
        "timestep": task.physics_timestep,
        "speed_error": v / speed - 1.0,
        "turn60": math.degrees(turn[-1, 2] - turn[-3, 2]),
        "end_gap": math.hypot(*(end[:2] - reference[:2])) / travelled,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args()
    rows = []
    for drive in ("tyre", "rollers", "planar"):
        for speed in (1.0, 2.0, 3.0):
            r = measure(drive, speed)
            rows.append([drive, f"{speed:.0f}", str(r["timestep"]), f"{r['speed_error']:+.2%}",
                         f"{r['turn60']:.1f}", f"{r['end_gap']:.2%}"])  # fmt: skip
            print(" | ".join(rows[-1]))
    table = markdown_table(
        [
            "drive",
            "speed (m/s)",
            "timestep (s)",
            "forward speed error",
            "60-degree turn (deg)",
            "end pose vs planar",
        ],
        rows,
    )
    body = (
        "Empty floor, the task's default (auto) timestep; the turn is taken from cruise and measured "
        "over its decision and the next; the end-pose gap is after a fixed 20-action sequence, as a "
        "share of the distance travelled.\n\n" + table
    )
    if not args.no_write:
        write_section("Drive accuracy (bench/drive_accuracy.py)", body)


if __name__ == "__main__":
    main()
