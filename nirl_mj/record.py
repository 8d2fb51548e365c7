"""Rerun recordings of what the robot did (rerun-sdk 0.41 API).

A trajectory stores its arena's seed and task spec, not the arena itself; the
arena is regenerated exactly as the environment drew it
(:func:`layout_of`). Entity paths, for demonstration i:

- ``demos/{i:03d}/arena/obstacles`` boxes and ``.../cylinders`` (static), the
  border walls, start and target;
- ``demos/{i:03d}/path`` the robot's path as a line strip (static);
- ``demos/{i:03d}/robot`` the robot's position on the ``step`` timeline, and
  ``demos/{i:03d}/action`` the action taken at that step.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import rerun as rr

from nirl_mj.drive import BODY_RADIUS
from nirl_mj.features import ACTION_NAMES
from nirl_mj.layout import Layout, generate_layout
from nirl_mj.spec import from_dict
from nirl_mj.trajectory import Trajectory

_OBSTACLE = (150, 150, 160)
_WALL = (90, 90, 100)
_PATH = {
    "target": (40, 170, 60),
    "collision": (220, 50, 40),
    "timeout": (230, 160, 30),
    "physics_error": (150, 0, 150),
}


def layout_of(trajectory: Trajectory) -> Layout:
    """The arena the trajectory ran in, regenerated from its seed and task spec."""
    spec = from_dict(trajectory.task, "trajectory task")
    return generate_layout(spec.arena, np.random.RandomState(trajectory.arena_seed), robot_radius=BODY_RADIUS)


def _yaw_quaternions(yaw: np.ndarray) -> np.ndarray:
    """(N,) radians about +z -> (N, 4) quaternions in Rerun's xyzw order."""
    return np.stack([np.zeros_like(yaw), np.zeros_like(yaw), np.sin(yaw / 2), np.cos(yaw / 2)], axis=1)


def log_layout(rec: rr.RecordingStream, path: str, layout: Layout, height: float = 1.0) -> None:
    """Logs an arena as static 3-D geometry under ``path`` (metres)."""
    boxes = [o for o in layout.obstacles if o.shape == "box"]
    cylinders = [o for o in layout.obstacles if o.shape == "cylinder"]
    if boxes:
        rec.log(
            f"{path}/obstacles",
            rr.Boxes3D(
                centers=[(o.x, o.y, height / 2) for o in boxes],
                half_sizes=[(o.size[0], o.size[1], height / 2) for o in boxes],
                quaternions=_yaw_quaternions(np.array([o.yaw for o in boxes])),
                colors=[_WALL if o.is_wall else _OBSTACLE for o in boxes],
                fill_mode="solid",
            ),
            static=True,
        )
    if cylinders:
        rec.log(
            f"{path}/cylinders",
            rr.Cylinders3D(
                centers=[(o.x, o.y, height / 2) for o in cylinders],
                radii=[o.size[0] for o in cylinders],
                lengths=[height] * len(cylinders),
                quaternions=_yaw_quaternions(np.zeros(len(cylinders))),
                colors=[_OBSTACLE] * len(cylinders),
                fill_mode="solid",
            ),
            static=True,
        )
    w, h = layout.size
    rec.log(
        f"{path}/border",
        rr.LineStrips3D([[(0, 0, 0), (w, 0, 0), (w, h, 0), (0, h, 0), (0, 0, 0)]], colors=[_WALL]),
        static=True,
    )
    rec.log(
        f"{path}/start_target",
        rr.Points3D(
            [(*layout.start, 0.0), (*layout.target, 0.0)],
            colors=[(40, 90, 220), (40, 170, 60)],
            radii=[0.5, 1.0],
            labels=["start", "target"],
        ),
        static=True,
    )


def log_trajectory(rec: rr.RecordingStream, path: str, trajectory: Trajectory) -> None:
    """Logs the path (static) and, per decision on the ``step`` timeline, the robot and its action."""
    xy = trajectory.poses[:, :2]
    points = np.column_stack([xy, np.full(len(xy), 0.1)])
    rec.log(
        f"{path}/path",
        rr.LineStrips3D([points], colors=[_PATH[trajectory.outcome]], radii=[0.1]),
        static=True,
    )
    for t, point in enumerate(points):
        rec.set_time("step", sequence=t)
        rec.log(f"{path}/robot", rr.Points3D([point], radii=[BODY_RADIUS], colors=[(230, 230, 230)]))
        if t < len(trajectory.actions):
            rec.log(f"{path}/action", rr.TextLog(ACTION_NAMES[trajectory.actions[t]]))
    rec.reset_time()


def record_demonstrations(path: str | os.PathLike, trajectories: Sequence[Trajectory]) -> Path:
    """Writes a ``.rrd`` with every demonstration's arena, path and actions, atomically."""
    return record_run(path, trajectories, (), {})


def log_training(rec: rr.RecordingStream, metrics: Sequence[dict], prefix: str = "training") -> None:
    """Training scalars (margin, cost, weight changes, accuracies, success) on the ``episode`` timeline."""
    keys = ("margin", "cost", "dw1", "dw2", "demo_accuracy", "demo_balanced_accuracy", "success_rate",
            "collision_rate", "validation_success", "policy_entropy", "reward_spread")  # fmt: skip
    for row in metrics:
        rec.set_time("episode", sequence=int(row["episode"]))
        for key in keys:
            value = row.get(key)
            if value is not None and np.isfinite(value):
                rec.log(f"{prefix}/{key}", rr.Scalars(float(value)))
    rec.reset_time()


def record_run(
    path: str | os.PathLike,
    demos: Sequence[Trajectory],
    metrics: Sequence[dict],
    evaluations: dict[str, Sequence[Trajectory]],
    max_paths: int = 10,
) -> Path:
    """Writes a run's recording, atomically: the demonstrations, the training scalars, and
    up to ``max_paths`` evaluation episodes of each policy (``eval/<policy slug>/<i>``)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    rec = rr.RecordingStream("nirl-mj")
    rec.save(tmp)
    try:
        for i, trajectory in enumerate(demos):
            log_layout(rec, f"demos/{i:03d}/arena", layout_of(trajectory))
            log_trajectory(rec, f"demos/{i:03d}", trajectory)
        log_training(rec, metrics)
        for name, trajectories in evaluations.items():
            slug = re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")  # entity paths take no spaces
            for i, trajectory in enumerate(trajectories[:max_paths]):
                log_layout(rec, f"eval/{slug}/{i:03d}/arena", layout_of(trajectory))
                log_trajectory(rec, f"eval/{slug}/{i:03d}", trajectory)
        rec.flush()
        rec.disconnect()
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
