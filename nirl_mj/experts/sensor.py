"""The sensor-limited demonstrator: drives on what the robot senses and remembers.

:class:`SensorExpert` reads nothing but ``timestep.observation``: the per-ray
clearances ``rays``, the odometry ``pose`` and the ``target`` position. It
never looks at the arena, the task or the physics, so everything it knows
about obstacles it has seen with its own rays. It behaves like a careful
driver watching the sensors, in two layers:

- **Memory.** Every ray hit is written into a world-frame grid (0.25 m
  cells); the free stretch of every ray clears the cells it passes, so
  obstacles that moved away are forgotten. Unknown space counts as free.
- **Local choice (every decision).** Like :func:`nirl_mj.policies.rule_policy`:
  head for the target's 40-degree sector, turn away when obstacles are close.
  The closeness is measured on the remembered hits along each action's arc
  and along the best follow-up arc (a two-decision look-ahead, so it never
  enters a spot it cannot drive on from); actions whose arcs come closer than
  a hard margin are ruled out, the rest pay a penalty that grows as the
  clearance shrinks. With nothing left it backs off, and keeps off the arc
  that led in for a few decisions, so it backs far enough to turn instead of
  driving straight back into the same spot.
- **Escape (rare).** The local rule has no memory, so it can circle in a
  pocket or dither in front of a wide obstacle. When the distance to the
  target has not improved for ``stuck_steps`` decisions it plans on its
  memory (Dijkstra on a 1 m grid, cells near remembered hits expensive) and
  steers for a waypoint a few metres down that plan, until it is clearly
  closer to the target than where it got stuck (the leaving rule of the Bug
  algorithms, so every escape ends with progress). Every decision spent in a
  cell makes planning through it dearer, so a plan that leads back into the
  same trap loses to the alternatives.

Cost: a decision costs ~0.1 ms (a few dozen small numpy calls); an escape
plan (~5-10 ms) happens in a few percent of the episodes only.

Heading for the target *sector* (not the exact bearing) and turning on
closeness keeps its actions a function of what phi(s) shows most of the
time, which is what makes its demonstrations learnable.
"""

from __future__ import annotations

import functools
import math

import dm_env
import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from nirl_mj import drive, features
from nirl_mj.sensing import ray_angles

__all__ = ["SensorExpert"]

ROBOT_RADIUS = 0.225
"""Radius of the Robotino's outline, metres (as ``nirl_mj.task.BODY_RADIUS``; repeated so
that this module does not import MuJoCo)."""

_BACKWARD = 5
_N_FORWARD = 5  # actions 0..4 drive forward along an arc
_TURNS_DEG = np.array([0.0, 30.0, 60.0, -30.0, -60.0])

_CELL = 0.25  # memory grid cell side, metres
_COARSE = 4  # memory cells per planning cell side (1 m planning cells)
_PAD = 30.0  # memory grid margin around start and target, metres
# Distance from a cell centre to any point of its cell, metres: a remembered
# hit may lie this much closer than its cell centre.
_CELL_SLACK = _CELL * math.sqrt(0.5)

# Samples along one decision's arc (fractions of the decision period) and
# along the follow-up arc.
_FIRST_SAMPLES = (10, 20, 30, 40, 50)
_SECOND_SAMPLES = (17, 34, 50)

# Planning-grid costs per metre: a cell holding a remembered hit, its
# neighbours, free or unknown cells.
_COST_HIT = 1000.0
_COST_NEAR = 20.0
_COST_FREE = 1.0
# Extra cost per decision already spent in a planning cell: a plan that led
# into a trap gets more expensive every time, so repeated escapes go elsewhere.
_COST_VISIT = 3.0
_EIGHT = np.ones((3, 3), dtype=bool)


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
def _look_ahead_table(decision_period: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample points of every one- and two-decision forward sequence, robot frame, unit travel.

    Returns ``first`` (5, F, 2) points along the first arc and ``second``
    (5, 5, S, 2) points along the follow-up arc b after first arc a (metres
    for one metre of travel per decision).
    """
    points, yaw = _unit_arcs(decision_period)
    first = points[:, [i - 1 for i in _FIRST_SAMPLES]]
    follow = points[:, [i - 1 for i in _SECOND_SAMPLES]]  # (5, S, 2)
    end = points[:, -1]  # (5, 2)
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (5, 2, 2)
    second = end[:, None, None, :] + np.einsum("aij,bsj->absi", rot, follow)
    return first, second


@functools.lru_cache(maxsize=4)
def _lattice(ny: int, nx: int) -> tuple[sparse.csr_matrix, np.ndarray]:
    """8-connected grid graph on (ny, nx) cells with edge lengths in cells, and the
    source cell of every stored edge (for per-cell costs)."""
    idx = np.arange(ny * nx).reshape(ny, nx)
    rows, cols, lengths = [], [], []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = idx[max(0, -di) : ny - max(0, di), max(0, -dj) : nx - max(0, dj)].ravel()
        b = idx[max(0, di) : ny - max(0, -di), max(0, dj) : nx - max(0, -dj)].ravel()
        length = math.hypot(di, dj)
        rows += [a, b]
        cols += [b, a]
        lengths += [np.full(a.size, length)] * 2
    graph = sparse.csr_matrix(
        (np.concatenate(lengths), (np.concatenate(rows), np.concatenate(cols))), shape=(ny * nx, ny * nx)
    )
    graph.sort_indices()
    source = np.repeat(np.arange(ny * nx), np.diff(graph.indptr))
    return graph, source


def _wrap_deg(angle: np.ndarray | float) -> np.ndarray | float:
    """Angle in degrees wrapped to [-180, 180)."""
    return (angle + 180.0) % 360.0 - 180.0


class SensorExpert:
    """Drives on its own sensor readings, its odometry and the target position only.

    Args:
        speed: forward speed (m/s) if known; ``None`` estimates the travel per
            decision from the odometry (the largest step seen so far, 1 m until
            the robot has moved).
        decision_period: seconds per decision (only used with ``speed``).
        hard_margin: closest allowed gap (m) between the robot's outline and a
            remembered hit along the look-ahead arcs.
        soft_clearance: gap (m) below which an action pays a danger penalty.
        stuck_steps: decisions without 0.5 m of progress before it plans an escape.
    """

    kind = "sensor"

    def __init__(
        self,
        speed: float | None = None,
        decision_period: float = 0.5,
        hard_margin: float = 0.25,
        soft_clearance: float = 1.5,
        stuck_steps: int = 10,
    ) -> None:
        self._speed = speed
        self._period = decision_period
        self._hard = hard_margin
        self._soft = soft_clearance
        self._stuck_steps = stuck_steps
        self._first, self._second = _look_ahead_table(decision_period)
        self._occ = np.zeros((1, 1), dtype=bool)

    # -- episode -------------------------------------------------------------------------

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        """Forgets everything and starts a memory grid around the start and the target.

        Keeps nothing from ``env``: only the first observation is read.
        """
        obs = timestep.observation
        pose = np.asarray(obs["pose"], dtype=np.float64)
        target = np.asarray(obs["target"], dtype=np.float64)
        rays = np.asarray(obs["rays"], dtype=np.float64)
        self._target = target.copy()
        self._angles = ray_angles(rays.size // features.N_SENSORS)
        # The sensing range is not observed as such: readings are capped at it,
        # so the largest reading seen is the range (or a little less).
        self._range = float(rays.max())
        self._ray_samples = np.arange(ROBOT_RADIUS, self._range + ROBOT_RADIUS, _CELL)
        lo = np.minimum(pose[:2], target) - _PAD
        hi = np.maximum(pose[:2], target) + _PAD
        # Whole planning cells, so the coarse grid is an exact block reduction.
        n = np.ceil((hi - lo) / (_CELL * _COARSE)).astype(int) * _COARSE
        self._origin = lo
        self._occ = np.zeros((n[1], n[0]), dtype=bool)  # [row = y, column = x]
        self._step_length = self._speed * self._period if self._speed else 1.0
        self._fixed_step = self._speed is not None
        self._last_xy = pose[:2].copy()
        self._steps = 0
        self._best = math.inf
        self._last_progress = 0
        self._escape = False
        self._escape_best = math.inf
        self._cost_to_go: np.ndarray | None = None
        self._planned_at = -1
        self._hits_since_plan = 0
        ny, nx = self._occ.shape[0] // _COARSE, self._occ.shape[1] // _COARSE
        self._visits = np.zeros((ny, nx))
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
        self._remember(xy, yaw, rays)
        self._visits[self._coarse_cell(xy)] += 1.0

        to_target = self._target - xy
        distance = float(math.hypot(to_target[0], to_target[1]))
        self._track_progress(distance)
        if self._escape:
            goal_bearing = self._escape_bearing(xy, yaw)
            quantise = False
        else:
            goal_bearing = math.degrees(math.atan2(to_target[1], to_target[0]) - yaw)
            quantise = True
        action = self._choose(xy, yaw, rays, goal_bearing, quantise)
        if action == _BACKWARD:
            # The last forward arc led into a spot too tight to go on from:
            # keep off it for a few decisions, so the robot backs off far
            # enough to turn instead of driving straight back in.
            self._tabu = self._last_forward
            self._tabu_until = self._steps + 4
        else:
            self._last_forward = action
        self._steps += 1
        return action

    # -- memory --------------------------------------------------------------------------

    def _observe_motion(self, xy: np.ndarray) -> None:
        """Updates the travel per decision (m) from odometry when the speed is not given."""
        step = float(np.hypot(*(xy - self._last_xy)))
        self._last_xy = xy.copy()
        if not self._fixed_step and step > self._step_length:
            self._step_length = step

    def _flat_cells(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat indices into the memory grid of world points ``x``, ``y`` (m, same shape),
        clipped to the grid (the grid reaches far beyond anything the robot can see)."""
        ny, nx = self._occ.shape
        j = np.clip(((x - self._origin[0]) * (1.0 / _CELL)).astype(np.int64), 0, nx - 1)
        i = np.clip(((y - self._origin[1]) * (1.0 / _CELL)).astype(np.int64), 0, ny - 1)
        return i * nx + j

    def _remember(self, xy: np.ndarray, yaw: float, rays: np.ndarray) -> None:
        """Clears the cells each ray saw through and marks the cells it hit.

        ``rays`` (9 k,) clearances from the outline (m), capped at the range.
        """
        angle = self._angles + yaw
        cos, sin = np.cos(angle), np.sin(angle)
        reach = rays + ROBOT_RADIUS  # from the robot's centre
        flat = self._occ.reshape(-1)  # a view: writes go to the grid
        # Free space: samples every cell side along each ray, stopping a cell
        # and a half short of the hit so that a surface is not cleared by its
        # own ray (clearing is what forgets obstacles that moved away).
        free = self._ray_samples[None, :] < (reach - 1.5 * _CELL)[:, None]
        x = xy[0] + np.multiply.outer(cos, self._ray_samples)[free]
        y = xy[1] + np.multiply.outer(sin, self._ray_samples)[free]
        flat[self._flat_cells(x, y)] = False
        hit = rays < self._range - 1e-6
        if hit.any():
            cells = self._flat_cells(xy[0] + cos[hit] * reach[hit], xy[1] + sin[hit] * reach[hit])
            self._hits_since_plan += int(np.count_nonzero(~flat[cells]))
            flat[cells] = True

    def _nearby_hits(self, xy: np.ndarray, radius: float) -> np.ndarray:
        """Centres (N, 2) m of remembered hit cells within a square of half-side ``radius`` m."""
        ny, nx = self._occ.shape
        j0 = max(0, int((xy[0] - radius - self._origin[0]) / _CELL))
        j1 = min(nx, int((xy[0] + radius - self._origin[0]) / _CELL) + 1)
        i0 = max(0, int((xy[1] - radius - self._origin[1]) / _CELL))
        i1 = min(ny, int((xy[1] + radius - self._origin[1]) / _CELL) + 1)
        if j0 >= j1 or i0 >= i1:
            return np.empty((0, 2))
        i, j = np.nonzero(self._occ[i0:i1, j0:j1])
        return np.stack(
            [self._origin[0] + (j + j0 + 0.5) * _CELL, self._origin[1] + (i + i0 + 0.5) * _CELL], axis=1
        )

    # -- escape --------------------------------------------------------------------------

    def _track_progress(self, distance: float) -> None:
        """Switches to escape after ``stuck_steps`` decisions without 0.5 m of progress,
        back once 1 m closer to the target than where it got stuck."""
        if distance < self._best - 0.5:
            self._best = distance
            self._last_progress = self._steps
        if self._escape:
            if distance < self._escape_best - 1.0:
                self._escape = False
                self._best = distance
                self._last_progress = self._steps
        elif self._steps - self._last_progress >= self._stuck_steps:
            self._escape = True
            self._escape_best = self._best
            self._cost_to_go = None

    def _plan(self) -> None:
        """Cost-to-go (m-equivalent) to the target over the remembered hits, on 1 m cells."""
        ny, nx = self._occ.shape[0] // _COARSE, self._occ.shape[1] // _COARSE
        hit = self._occ.reshape(ny, _COARSE, nx, _COARSE).any(axis=(1, 3))
        near = ndimage.binary_dilation(hit, structure=_EIGHT)
        cost = (
            np.where(hit, _COST_HIT, np.where(near, _COST_NEAR, _COST_FREE)) + _COST_VISIT * self._visits
        ).ravel()
        graph, source = _lattice(ny, nx)
        # Reverse search from the target: an edge u -> v of the reversed path
        # costs what entering u costs on the way to the target.
        weighted = sparse.csr_matrix(
            (graph.data * cost[source], graph.indices, graph.indptr), shape=graph.shape
        )
        ti, tj = self._coarse_cell(self._target)
        self._cost_to_go = csgraph.dijkstra(weighted, directed=True, indices=ti * nx + tj).reshape(ny, nx)
        self._planned_at = self._steps
        self._hits_since_plan = 0

    def _coarse_cell(self, point: np.ndarray) -> tuple[int, int]:
        """Planning cell (row, column) of a world point (m), clipped to the grid."""
        size = _CELL * _COARSE
        ny, nx = self._occ.shape[0] // _COARSE, self._occ.shape[1] // _COARSE
        i = min(max(int((point[1] - self._origin[1]) // size), 0), ny - 1)
        j = min(max(int((point[0] - self._origin[0]) // size), 0), nx - 1)
        return i, j

    def _escape_bearing(self, xy: np.ndarray, yaw: float) -> float:
        """Bearing (deg, from the front) of a waypoint ~6 m down the memory plan."""
        # Replan when new obstacles were seen (at most every other decision)
        # and every few decisions anyway, as the visit costs grow.
        since = self._steps - self._planned_at
        if self._cost_to_go is None or (self._hits_since_plan > 0 and since >= 2) or since >= 5:
            self._plan()
        field = self._cost_to_go
        ny, nx = field.shape
        i, j = self._coarse_cell(xy)
        for _ in range(6):
            best = (field[i, j], i, j)
            for di in (-1, 0, 1):
                for dj in (-1, 0, 1):
                    a, b = i + di, j + dj
                    if 0 <= a < ny and 0 <= b < nx and field[a, b] < best[0]:
                        best = (field[a, b], a, b)
            if best[1] == i and best[2] == j:
                break
            i, j = best[1], best[2]
        size = _CELL * _COARSE
        wx = self._origin[0] + (j + 0.5) * size
        wy = self._origin[1] + (i + 0.5) * size
        if abs(wx - xy[0]) + abs(wy - xy[1]) < 1e-9:
            wx, wy = self._target
        return math.degrees(math.atan2(wy - xy[1], wx - xy[0]) - yaw)

    # -- local choice --------------------------------------------------------------------

    def _choose(self, xy: np.ndarray, yaw: float, rays: np.ndarray, bearing: float, quantise: bool) -> int:
        """Scores the five forward arcs by heading and clearance; backward if none is safe.

        ``bearing`` (deg, counter-clockwise from the front) is where to head;
        with ``quantise`` it is first snapped to the centre of its 40-degree
        sector, as phi(s) shows it.
        """
        if quantise:
            width = math.degrees(features.SECTOR_WIDTH)
            bearing = width * round(_wrap_deg(bearing) / width)
        deviation = np.abs(_wrap_deg(bearing - _TURNS_DEG)) / 60.0
        d = self._step_length
        hits = self._nearby_hits(xy, 2.0 * d + self._soft + 1.0)
        if hits.shape[0] == 0:
            return int(np.argmin(deviation))
        c, s = math.cos(yaw), math.sin(yaw)
        rot = np.array([[c, s], [-s, c]])  # robot frame -> world, for row vectors
        first = xy + (self._first * d) @ rot  # (5, F, 2)
        second = xy + (self._second * d) @ rot  # (5, 5, S, 2)
        gap_first = self._clearance(first, hits).min(axis=1)  # (5,)
        gap_second = self._clearance(second, hits).min(axis=2).max(axis=1)  # (5,)
        gap = np.minimum(gap_first, gap_second)
        safe = gap >= self._hard
        if self._steps < self._tabu_until:
            safe[self._tabu] = False
        if not safe.any():
            # Boxed in: back off if the rear sensors (S5, S6) leave room.
            k = rays.size // features.N_SENSORS
            if rays[4 * k : 6 * k].min() > 0.5 * d + self._hard:
                return _BACKWARD
            return int(np.argmax(gap))
        penalty = 2.0 * np.maximum(1.0 - gap / self._soft, 0.0) ** 2
        score = np.where(safe, deviation + penalty, np.inf)
        return int(np.argmin(score))

    @staticmethod
    def _clearance(points: np.ndarray, hits: np.ndarray) -> np.ndarray:
        """Gap (m) between the robot's outline at each of ``points`` (..., 2) and the
        nearest remembered hit (N, 2); shape (...)."""
        flat = points.reshape(-1, 2)
        d2 = ((flat[:, None, :] - hits[None, :, :]) ** 2).sum(axis=2).min(axis=1)
        return (np.sqrt(d2) - ROBOT_RADIUS - _CELL_SLACK).reshape(points.shape[:-1])
