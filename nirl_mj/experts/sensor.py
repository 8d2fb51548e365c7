"""The sensor-limited demonstrator: drives on what the robot senses and remembers.

:class:`SensorExpert` reads nothing but ``timestep.observation``: phi(s) as the
task computes it from the sensors (``features``), the per-ray clearances
``rays``, the ``pose`` (the simulator's, exact: odometry without drift) and the
``target`` position. It never looks at the arena, the task or the physics, so
everything it knows about obstacles it has seen with its own rays. Its
demonstrations are meant for learners that see only phi(s), so its ordinary
decisions are a function of phi(s), and memory is used only to keep it safe and
to get it out of pockets:

- **Rule on phi(s) (ordinary decisions).** The same rule as
  :func:`nirl_mj.experts.policies.rule_policy`: each forward arc is judged by the
  danger levels phi shows along its chord and at its final heading (danger 5
  or more, i.e. under 2.33 m of clearance by default, rules it out); the rest
  are scored by their deviation from the centre of the target sector V plus a
  penalty growing with danger. With every arc ruled out it backs off (if
  the rear sensors leave room; otherwise it takes the arc with the most
  clearance to remembered hits).
- **Memory veto (rare).** Every ray hit is written into a world-frame grid
  (:class:`nirl_mj.sim.memory.RayMemory`, 0.25 m cells; the free stretch of every
  ray clears the cells it passes). Before an arc is driven, the
  remembered hits along it and along the best follow-up arc (a two-decision
  look-ahead) must stay a hard margin away from the robot's outline; this
  catches what the coarse danger levels cannot show (an edge between two
  rays, an obstacle that has slipped behind the rear sensors). A vetoed arc
  gives way to the rule's next choice.
- **Escape (rare).** The rule has no memory, so it can circle in a pocket or
  dither in front of a wide obstacle. When the memory says it is stuck (no 0.5 m
  of progress for ``stuck_steps`` decisions), it steers for the memory's escape
  bearing (a waypoint a few metres down a path planned on the remembered hits,
  :meth:`nirl_mj.sim.memory.RayMemory.escape_bearing`), judging arcs by their
  geometric clearance to remembered hits, until it is 1 m closer to the target
  than where it got stuck (the leaving rule of the Bug algorithms).

Cost (2 m/s, 100 m arenas): an ordinary decision is a few small numpy calls
(~0.1 ms); a window plan costs ~1 ms and happens only while escaping.
"""

from __future__ import annotations

import functools
import math

import dm_env
import numpy as np

from nirl_mj.data import features
from nirl_mj.experts.policies import rule_scores
from nirl_mj.sim import drive
from nirl_mj.sim.memory import CELL, STUCK_STEPS, RayMemory

__all__ = ["SensorExpert"]


_BACKWARD = 5
_N_FORWARD = 5  # actions 0..4 drive forward along an arc
_TURNS_DEG = np.array([0.0, 30.0, 60.0, -30.0, -60.0])

# Distance from a cell centre to any point of its cell, metres: a remembered
# hit may lie this much closer than its cell centre.
_CELL_SLACK = CELL * math.sqrt(0.5)

# Samples along one decision's arc (fractions of the decision period) and
# along the follow-up arc.
_FIRST_SAMPLES = (10, 20, 30, 40, 50)
_SECOND_SAMPLES = (17, 34, 50)


@functools.lru_cache(maxsize=4)
def _unit_arcs(decision_period: float) -> tuple[np.ndarray, np.ndarray]:
    """Poses along the five forward actions for one metre of travel per decision.

    Returns ``points`` (5, 50, 2): positions (m) in the robot frame at the end of
    each command period (10 ms) of the decision, and ``yaw`` (5,) the heading
    change of each action (rad). Positions scale linearly with the travel per
    decision, so one table serves every speed.
    """
    speed = 1.0 / decision_period
    cmd_dt = decision_period / 50.0
    points = np.empty((_N_FORWARD, 50, 2))
    yaw = np.empty(_N_FORWARD)
    for a in range(_N_FORWARD):
        # The task's default rim acceleration; the wheel rate limit at the start
        # of a decision only delays a turn slightly, which the margins absorb.
        twist = drive.action_profile(a, speed, decision_period, cmd_dt, max_accel=4.0)
        theta = np.cumsum(twist[:, 2]) * cmd_dt
        mid = theta - 0.5 * twist[:, 2] * cmd_dt  # heading in the middle of each period
        points[a, :, 0] = np.cumsum(twist[:, 0] * np.cos(mid)) * cmd_dt
        points[a, :, 1] = np.cumsum(twist[:, 0] * np.sin(mid)) * cmd_dt
        yaw[a] = theta[-1]
    return points, yaw


@functools.lru_cache(maxsize=2)
def _look_ahead_table(decision_period: float) -> np.ndarray:
    """Sample points of every one- and two-decision forward sequence, robot frame, unit travel.

    Returns (5, F + 5 S, 2): for first arc a, the F points along it, then the S
    points along each follow-up arc b = 0..4 (metres for one metre of travel
    per decision). One table lets one distance computation serve both arcs.
    """
    points, yaw = _unit_arcs(decision_period)
    first = points[:, [i - 1 for i in _FIRST_SAMPLES]]  # (5, F, 2)
    follow = points[:, [i - 1 for i in _SECOND_SAMPLES]]  # (5, S, 2)
    end = points[:, -1]  # (5, 2)
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (5, 2, 2)
    second = end[:, None, None, :] + np.einsum("aij,bsj->absi", rot, follow)  # (5, 5, S, 2)
    return np.concatenate([first, second.reshape(_N_FORWARD, -1, 2)], axis=1)


def _wrap_deg(angle: np.ndarray | float) -> np.ndarray | float:
    """Angle in degrees wrapped to [-180, 180)."""
    return (angle + 180.0) % 360.0 - 180.0


class SensorExpert:
    """Drives on phi(s), its own sensor readings, its odometry and the target position only.

    Args:
        speed: forward speed (m/s) if known; ``None`` estimates the travel per
            decision from the odometry (the largest step seen so far, at least 1 m).
        decision_period: seconds per decision (the look-ahead arcs' duration).
        hard_margin: closest allowed gap (m) between the robot's outline and a
            remembered hit along the look-ahead arcs.
        soft_clearance: gap (m) below which an arc pays a danger penalty while
            escaping.
        stuck_steps: decisions without 0.5 m of progress before it plans an escape.
    """

    kind = "sensor"

    def __init__(
        self,
        speed: float | None = None,
        decision_period: float = 0.5,
        hard_margin: float = 0.25,
        soft_clearance: float = 1.5,
        stuck_steps: int = STUCK_STEPS,
    ) -> None:
        self._speed = speed
        self._period = decision_period
        self._hard = hard_margin
        self._soft = soft_clearance
        self._look_ahead = _look_ahead_table(decision_period)
        self._memory = RayMemory(stuck_steps)

    # -- episode -------------------------------------------------------------------------

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        """Forgets everything and starts a memory grid around the start and the target.

        Keeps nothing from ``env``: only the first observation is read.
        """
        obs = timestep.observation
        pose = np.asarray(obs["pose"], dtype=np.float64)
        rays = np.asarray(obs["rays"], dtype=np.float64)
        self._memory.reset(pose, np.asarray(obs["target"], dtype=np.float64), rays)
        self._k = rays.size // features.N_SENSORS
        self._step_length = self._speed * self._period if self._speed else 1.0
        self._fixed_step = self._speed is not None
        self._last_xy = pose[:2].copy()
        self._last_forward = 0
        self._tabu = -1
        self._tabu_until = -1

    def act(self, timestep: dm_env.TimeStep) -> int:
        """The action 0..5 for this timestep (see the module doc)."""
        obs = timestep.observation
        pose = np.asarray(obs["pose"], dtype=np.float64)
        rays = np.asarray(obs["rays"], dtype=np.float64)
        xy, yaw = pose[:2], float(pose[2])
        self._observe_motion(xy)
        self._memory.update(xy, yaw, rays)
        if self._memory.escaping:
            action = self._choose(xy, yaw, rays, self._memory.escape_bearing(xy, yaw))
        else:
            action = self._follow_rule(xy, yaw, rays, np.asarray(obs["features"], dtype=np.float64))
        if action == _BACKWARD:
            # The last forward arc led into a spot too tight to go on from:
            # keep off it for a few decisions, so the robot backs off far
            # enough to turn instead of driving straight back in.
            self._tabu = self._last_forward
            self._tabu_until = self._memory.steps + 4
        else:
            self._last_forward = action
        return action

    def _observe_motion(self, xy: np.ndarray) -> None:
        """Updates the travel per decision (m) from odometry when the speed is not given."""
        step = math.hypot(xy[0] - self._last_xy[0], xy[1] - self._last_xy[1])
        self._last_xy = xy.copy()
        if not self._fixed_step and step > self._step_length:
            self._step_length = step

    # -- ordinary decisions: the rule on phi(s) -------------------------------------------

    def _follow_rule(self, xy: np.ndarray, yaw: float, rays: np.ndarray, phi: np.ndarray) -> int:
        """The rule's choice on ``phi`` (16,), among the arcs the memory does not veto."""
        score = rule_scores(phi)
        # Only hits within two decisions' travel plus the margins can veto an arc.
        gaps = self._gaps(
            xy, yaw, 2.0 * self._step_length + self._hard + 2.0 * _CELL_SLACK + drive.BODY_RADIUS
        )
        if gaps is not None:
            score = np.where(gaps >= self._hard, score, np.inf)
        best = int(np.argmin(score))
        if math.isfinite(score[best]):
            return best
        if self._rear_clear(rays):
            return _BACKWARD
        # Boxed in at the back too: the geometric choice, which finds the
        # roomiest way out (it may still back off).
        return self._choose(xy, yaw, rays, None)

    # -- geometric choice (escapes, and when the rule is boxed in) ------------------------

    def _rear_clear(self, rays: np.ndarray) -> bool:
        """The rear sensors (S5, S6) leave room to back off for one decision."""
        return float(rays[4 * self._k : 6 * self._k].min()) > 0.5 * self._step_length + self._hard

    def _gaps(self, xy: np.ndarray, yaw: float, radius: float) -> np.ndarray | None:
        """Gap (5,) m between the robot's outline and the remembered hits along each
        forward arc and its best follow-up arc; ``None`` if no hit lies within
        ``radius`` m (square) of the robot."""
        hits = self._memory.nearby_hits(xy, radius)
        if hits.shape[0] == 0:
            return None
        c, s = math.cos(yaw), math.sin(yaw)
        rot = np.array([[c, s], [-s, c]])  # robot frame -> world, for row vectors
        points = xy + (self._look_ahead * self._step_length) @ rot  # (5, F + 5 S, 2)
        flat = points.reshape(-1, 2)
        d2 = ((flat[:, None, :] - hits[None, :, :]) ** 2).sum(axis=2).min(axis=1)
        gap = (np.sqrt(d2) - drive.BODY_RADIUS - _CELL_SLACK).reshape(_N_FORWARD, -1)
        n_first = len(_FIRST_SAMPLES)
        gap_second = gap[:, n_first:].reshape(_N_FORWARD, _N_FORWARD, -1).min(axis=2).max(axis=1)
        return np.minimum(gap[:, :n_first].min(axis=1), gap_second)

    def _choose(self, xy: np.ndarray, yaw: float, rays: np.ndarray, bearing: float | None) -> int:
        """Scores the five forward arcs by heading and clearance; backward if none is safe.

        ``bearing`` (deg, counter-clockwise from the front) is where to head;
        ``None`` scores clearance only.
        """
        if bearing is None:
            deviation = np.zeros(_N_FORWARD)
        else:
            deviation = np.abs(_wrap_deg(bearing - _TURNS_DEG)) / 60.0
        gap = self._gaps(xy, yaw, 2.0 * self._step_length + self._soft + 1.0)
        if gap is None:
            return int(np.argmin(deviation))
        safe = gap >= self._hard
        if self._memory.steps < self._tabu_until:  # the decision's index, from 0
            safe[self._tabu] = False
        if not safe.any():
            # Boxed in: back off if the rear sensors (S5, S6) leave room.
            if self._rear_clear(rays):
                return _BACKWARD
            return int(np.argmax(gap))
        penalty = 2.0 * np.maximum(1.0 - gap / self._soft, 0.0) ** 2
        score = np.where(safe, deviation + penalty, np.inf)
        return int(np.argmin(score))
