"""The task's observations: every one a bounded array of rank 1, with its real range.

Each observation is a ``dm_env.specs.BoundedArray`` whose bounds follow from the
task spec (arena size, sensing range, step budget), so that wrappers (Gymnasium's
``Box``, a normaliser) know the range without guessing. Scalars are shape (1,), not
0-d: libraries built on Gymnasium (Stable-Baselines3's checker and its
``MultiInputPolicy``) index and concatenate observations and fail on 0-d arrays,
and one shape on both interfaces keeps a recorded observation the same wherever
it was read. Integer observations (danger levels, wall flags, outcome, steps) keep
integer dtypes.
"""

from __future__ import annotations

import math

import numpy as np
from dm_control.composer.observation import observable
from dm_env import specs

from nirl_mj.data import features
from nirl_mj.sim.drive import BODY_RADIUS
from nirl_mj.sim.spec import TaskSpec

NAMES = ("features", "ranges", "rays", "danger", "wall", "pose", "target", "target_distance",
         "target_bearing", "outcome", "steps")  # fmt: skip
"""Every observation, in the order the task declares them."""

N_OUTCOMES = 5  # nirl_mj.sim.task.Outcome: RUNNING, TARGET, COLLISION, TIMEOUT, PHYSICS_ERROR


def feature_bounds() -> tuple[np.ndarray, np.ndarray]:
    """phi(s)'s per-component range, two float32 arrays of shape (16,): danger 0..7, sector V
    1..9, the detection flag I and the wall flags U 0..1 (layout ``features.FEATURE_NAMES``)."""
    n = len(features.FEATURE_SENSORS)
    low = np.array([0.0] * n + [1.0, 0.0] + [0.0] * n, dtype=np.float32)
    high = np.array([7.0] * n + [float(features.N_SENSORS), 1.0] + [1.0] * n, dtype=np.float32)
    return low, high


def observation_specs(spec: TaskSpec) -> dict[str, specs.BoundedArray]:
    """The bounded spec of every observation of a task, by name (module doc; units: metres,
    radians)."""
    sensing = spec.sensing.range
    width, height = spec.arena.size
    n_rays = features.N_SENSORS * spec.robot.rays_per_sensor
    phi_low, phi_high = feature_bounds()
    yaw = yaw_limit(spec)

    def bounded(name: str, shape: tuple[int, ...], dtype, low, high) -> specs.BoundedArray:
        return specs.BoundedArray(shape, dtype, np.broadcast_to(np.asarray(low, dtype), shape),
                                  np.broadcast_to(np.asarray(high, dtype), shape), name)  # fmt: skip

    # A clearance is a hit's distance from the robot's centre minus its radius, clamped at 0 by
    # sensing; the bound keeps -radius, what the unclamped difference could reach.
    out = [
        bounded("features", (features.N_FEATURES,), np.float32, phi_low, phi_high),
        bounded("ranges", (features.N_SENSORS,), np.float64, -BODY_RADIUS, sensing),
        bounded("rays", (n_rays,), np.float64, -BODY_RADIUS, sensing),
        bounded("danger", (features.N_SENSORS,), np.int8, 0, 7),
        bounded("wall", (features.N_SENSORS,), np.int8, 0, 1),
        bounded("pose", (3,), np.float64, [0.0, 0.0, -yaw], [width, height, yaw]),
        bounded("target", (2,), np.float64, 0.0, [width, height]),
        bounded("target_distance", (1,), np.float64, 0.0, math.hypot(width, height)),
        bounded("target_bearing", (1,), np.float64, -math.pi, math.pi),
        bounded("outcome", (1,), np.int32, 0, N_OUTCOMES - 1),
        bounded("steps", (1,), np.int32, 0, spec.step_budget),
    ]
    return {s.name: s for s in out}


def yaw_limit(spec: TaskSpec) -> float:
    """The largest |yaw| (radians) the ``pose`` observation can hold.

    ``tyre`` and ``rollers`` robots are free bodies whose yaw is read from a quaternion, in
    [-pi, pi]. A ``planar`` robot's yaw is its yaw joint's angle, which accumulates turns (it is
    continuous: no jump at +-pi): at most the start yaw plus 90 degrees per decision of the step
    budget (the sharpest action turns 60). It is not wrapped, so that every result computed from
    it stays what it was.
    """
    if spec.robot.drive != "planar":
        return math.pi
    start = spec.arena.start_yaw
    start = abs(float(start)) if not isinstance(start, str) else 0.0
    return max(math.pi, start) + spec.step_budget * math.pi / 2


def arena_pose(pose: np.ndarray, width: float, height: float) -> np.ndarray:
    """``pose`` (x, y, yaw) with x and y clipped to the arena (only a physics failure, which ends
    the episode, can put the robot outside). A pose inside is returned unchanged, bit for bit."""
    x, y, yaw = (float(v) for v in pose)
    return np.array([min(max(x, 0.0), width), min(max(y, 0.0), height), yaw])


class Bounded(observable.Generic):
    """composer's ``Generic`` observable with a declared spec: the environment's observation spec
    keeps its bounds, and every value is written into a buffer of the spec's dtype."""

    def __init__(self, raw_observation_callable, spec: specs.BoundedArray) -> None:
        super().__init__(raw_observation_callable)
        self._spec = spec
        self.enabled = True

    @property
    def array_spec(self) -> specs.BoundedArray:
        return self._spec
