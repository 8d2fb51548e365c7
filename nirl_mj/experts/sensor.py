"""The sensor-limited demonstrator: drives on what the robot senses and remembers.

:class:`SensorExpert` reads nothing but ``timestep.observation``: phi(s) as the
task computes it from the sensors (``features``), the per-ray clearances
``rays``, the odometry ``pose`` and the ``target`` position. It never looks at
the arena, the task or the physics, so everything it knows about obstacles it
has seen with its own rays. Its demonstrations are meant for learners that see
only phi(s), so its ordinary decisions are a function of phi(s), and memory is
used only to keep it safe and to get it out of pockets:

- **Rule on phi(s) (ordinary decisions).** The same rule as
  :func:`nirl_mj.experts.policies.rule_policy`: each forward arc is judged by the
  danger levels phi shows along its chord and at its final heading (danger 5
  or more, i.e. under 2.33 m of clearance by default, rules it out); the rest
  are scored by their deviation from the centre of the target sector V plus a
  penalty growing with danger. With every arc ruled out it backs off (if
  the rear sensors leave room; otherwise it takes the arc with the most
  clearance to remembered hits).
- **Memory veto (rare).** Every ray hit is written into a world-frame grid
  (0.25 m cells); the free stretch of every ray clears the cells it passes,
  so obstacles that moved away are forgotten. Before an arc is driven, the
  remembered hits along it and along the best follow-up arc (a two-decision
  look-ahead) must stay a hard margin away from the robot's outline; this
  catches what the coarse danger levels cannot show (an edge between two
  rays, an obstacle that has slipped behind the rear sensors). A vetoed arc
  gives way to the rule's next choice.
- **Escape (rare).** The rule has no memory, so it can circle in a pocket or
  dither in front of a wide obstacle. When the distance to the target has not
  improved by 0.5 m for ``stuck_steps`` decisions, it plans on its memory
  (Dijkstra on 1 m cells in a 41 m x 41 m window around the robot, cells near
  remembered hits expensive, the straight-line distance to the target as the
  cost beyond the window) and steers for a point a few metres down that path,
  judging arcs by their geometric clearance to remembered hits, until it is
  1 m closer to the target than where it got stuck (the leaving rule of the
  Bug algorithms, so every escape ends with progress). Every decision spent
  in a cell makes planning through it dearer, so a plan that leads back into
  the same trap loses to the alternatives. A path is followed without
  replanning unless new obstacles were seen (at most every other decision),
  the visit costs have grown for 5 decisions, or the robot strayed from it or
  reached its end.

Cost (2 m/s, 100 m arenas): an ordinary decision is a few small numpy calls
(~0.1 ms); a window plan costs ~1 ms and happens only while escaping.
"""

from __future__ import annotations

import functools
import math

import dm_env
import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from nirl_mj.data import features
from nirl_mj.sim import drive
from nirl_mj.sim.sensing import ray_angles

__all__ = ["SensorExpert"]


_BACKWARD = 5
_N_FORWARD = 5  # actions 0..4 drive forward along an arc
_TURNS_DEG = np.array([0.0, 30.0, 60.0, -30.0, -60.0])

_CELL = 0.25  # memory grid cell side, metres
_COARSE = 4  # memory cells per planning cell side (1 m planning cells)
_PLAN_CELL = _CELL * _COARSE  # planning cell side, metres
_PAD = 30.0  # memory grid margin around start and target, metres
_WINDOW = 20  # planning window half-side, planning cells (the window is 41 x 41 m)
_WAYPOINT = 6  # planning cells down the path to the escape waypoint (6-8.5 m)
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

# The rule on phi(s), as nirl_mj.experts.policies.rule_policy, in table form so that
# one decision costs a handful of numpy calls. Directions (degrees) of the
# sensors in phi's danger block [S1, S2, S3, S4, S7, S8, S9].
_PHI_SENSOR_DEG = np.degrees(features.SENSOR_ANGLES[list(features.FEATURE_SENSORS)])
_RULE_RULED_OUT = 5.0  # danger level from which the rule rules an arc out


def _angle_gap_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| wrapped to [0, 180] degrees, broadcast over a[:, None] and b[None, :]."""
    return np.abs((a[:, None] - b[None, :] + 180.0) % 360.0 - 180.0)


# Danger seen along action a from phi sensor j is danger_j - _RULE_FADE[a, j]:
# a sensor's level fades by two levels per 40 degrees away from its cone's
# centre, taken at the arc's chord (half its turn) and at its final heading.
_RULE_FADE = (
    2.0
    / 40.0
    * np.minimum(
        _angle_gap_deg(_TURNS_DEG / 2.0, _PHI_SENSOR_DEG), _angle_gap_deg(_TURNS_DEG, _PHI_SENSOR_DEG)
    )
)
# Deviation of each action's heading change from the centre of target sector
# V = 1..9 (row V - 1), in units of 60 degrees.
_RULE_DEVIATION = _angle_gap_deg(np.arange(features.N_SENSORS) * 40.0, _TURNS_DEG) / 60.0


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


@functools.lru_cache(maxsize=8)
def _lattice(ny: int, nx: int) -> tuple[sparse.csr_matrix, np.ndarray]:
    """8-connected grid graph on (ny, nx) cells with edge lengths in cells, and the
    destination cell of every stored edge (for per-cell costs)."""
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
    return graph, graph.indices.copy()


@functools.lru_cache(maxsize=8)
def _inner(h: int, w: int) -> np.ndarray:
    """(h, w): 0 on a grid's border cells, ``inf`` inside (added to rule the inside out)."""
    inner = np.zeros((h, w))
    inner[1:-1, 1:-1] = np.inf
    return inner


def _wrap_deg(angle: np.ndarray | float) -> np.ndarray | float:
    """Angle in degrees wrapped to [-180, 180)."""
    return (angle + 180.0) % 360.0 - 180.0


def rule_scores(phi: np.ndarray) -> np.ndarray:
    """Scores (5,) of the forward actions under :func:`nirl_mj.experts.policies.rule_policy`
    (lower is better, ``inf`` ruled out); all ``inf`` means the rule backs off."""
    danger = np.max(phi[None, 0:7] - _RULE_FADE, axis=1)
    region = int(phi[7])
    penalty = np.maximum(danger - 2.0, 0.0) ** 2 / 4.0
    return np.where(danger >= _RULE_RULED_OUT, np.inf, _RULE_DEVIATION[region - 1] + penalty)


class SensorExpert:
    """Drives on phi(s), its own sensor readings, its odometry and the target position only.

    Args:
        speed: forward speed (m/s) if known; ``None`` estimates the travel per
            decision from the odometry (the largest step seen so far, 1 m until
            the robot has moved).
        decision_period: seconds per decision (only used with ``speed``).
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
        stuck_steps: int = 10,
    ) -> None:
        self._speed = speed
        self._period = decision_period
        self._hard = hard_margin
        self._soft = soft_clearance
        self._stuck_steps = stuck_steps
        self._look_ahead = _look_ahead_table(decision_period)
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
        self._k = rays.size // features.N_SENSORS
        self._angles = ray_angles(self._k)
        # The sensing range is not observed as such: readings are capped at it,
        # so the largest reading seen is the range (or a little less).
        self._range = float(rays.max())
        self._ray_samples = np.arange(drive.BODY_RADIUS, self._range + drive.BODY_RADIUS, _CELL)
        lo = np.minimum(pose[:2], target) - _PAD
        hi = np.maximum(pose[:2], target) + _PAD
        # Whole planning cells, so the coarse grid is an exact block reduction.
        n = np.ceil((hi - lo) / _PLAN_CELL).astype(int) * _COARSE
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
        self._path: np.ndarray | None = None  # escape path, world metres (P, 2)
        self._planned_at = -1
        self._hits_since_plan = 0
        self._visits = np.zeros((n[1] // _COARSE, n[0] // _COARSE))
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
        self._track_progress(math.hypot(to_target[0], to_target[1]))
        if self._escape:
            action = self._choose(xy, yaw, rays, self._escape_bearing(xy, yaw))
        else:
            action = self._follow_rule(xy, yaw, rays, np.asarray(obs["features"], dtype=np.float64))
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
        step = math.hypot(xy[0] - self._last_xy[0], xy[1] - self._last_xy[1])
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
        reach = rays + drive.BODY_RADIUS  # from the robot's centre
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
            self._path = None

    def _plan(self, xy: np.ndarray) -> None:
        """Cheapest path (1 m cells, world metres) from the robot to the cell of a window
        around it that minimises path cost + straight-line distance to the target."""
        ny, nx = self._visits.shape
        ci, cj = self._coarse_cell(xy)
        i0, i1 = max(0, ci - _WINDOW), min(ny, ci + _WINDOW + 1)
        j0, j1 = max(0, cj - _WINDOW), min(nx, cj + _WINDOW + 1)
        h, w = i1 - i0, j1 - j0
        block = self._occ[i0 * _COARSE : i1 * _COARSE, j0 * _COARSE : j1 * _COARSE]
        hit = block.reshape(h, _COARSE, w, _COARSE).any(axis=(1, 3))
        near = ndimage.binary_dilation(hit, structure=_EIGHT)
        cost = (
            np.where(hit, _COST_HIT, np.where(near, _COST_NEAR, _COST_FREE))
            + _COST_VISIT * self._visits[i0:i1, j0:j1]
        ).ravel()
        graph, dest = _lattice(h, w)
        # An edge costs what entering its destination cell costs.
        weighted = sparse.csr_matrix(
            (graph.data * cost[dest], graph.indices, graph.indptr), shape=graph.shape
        )
        start = (ci - i0) * w + (cj - j0)
        dist, pred = csgraph.dijkstra(weighted, directed=True, indices=start, return_predecessors=True)
        # Beyond the window the way to the target is unknown: count it as free
        # space in a straight line (cells, like the path costs).
        cx = self._origin[0] + (np.arange(j0, j1) + 0.5) * _PLAN_CELL
        cy = self._origin[1] + (np.arange(i0, i1) + 0.5) * _PLAN_CELL
        beyond = np.hypot(cx[None, :] - self._target[0], cy[:, None] - self._target[1]) / _PLAN_CELL
        # A path ends at the target or leaves the window: with a consistent
        # estimate beyond, any cell inside would score no better than staying.
        total = dist.reshape(h, w) + _COST_FREE * beyond + _inner(h, w)
        ti, tj = self._coarse_cell(self._target)
        if i0 <= ti < i1 and j0 <= tj < j1:
            total[ti - i0, tj - j0] = dist[(ti - i0) * w + (tj - j0)]
        node = int(np.argmin(total))
        cells = [node]
        while cells[-1] != start and pred[cells[-1]] >= 0:
            cells.append(int(pred[cells[-1]]))
        cells = np.array(cells[::-1])
        self._path = np.stack([cx[cells % w], cy[cells // w]], axis=1)
        self._planned_at = self._steps
        self._hits_since_plan = 0

    def _coarse_cell(self, point: np.ndarray) -> tuple[int, int]:
        """Planning cell (row, column) of a world point (m), clipped to the grid."""
        ny, nx = self._visits.shape
        i = min(max(int((point[1] - self._origin[1]) // _PLAN_CELL), 0), ny - 1)
        j = min(max(int((point[0] - self._origin[0]) // _PLAN_CELL), 0), nx - 1)
        return i, j

    def _escape_bearing(self, xy: np.ndarray, yaw: float) -> float:
        """Bearing (deg, from the front) of a waypoint ~6 m down the escape path."""
        # Replan only when the path may be stale: new obstacles were seen (at
        # most every other decision), the visit costs have grown for a few
        # decisions, the robot has strayed from the path or come to its end.
        since = self._steps - self._planned_at
        replan = self._path is None or (self._hits_since_plan > 0 and since >= 2) or since >= 5
        if not replan:
            off = np.hypot(*(self._path - xy).T)
            nearest = int(np.argmin(off))
            replan = off[nearest] > 2.0 * _PLAN_CELL or nearest >= len(self._path) - 2
        if replan:
            self._plan(xy)
            off = np.hypot(*(self._path - xy).T)
            nearest = int(np.argmin(off))
        wx, wy = self._path[min(nearest + _WAYPOINT, len(self._path) - 1)]
        if abs(wx - xy[0]) + abs(wy - xy[1]) < 0.5 * _PLAN_CELL:
            wx, wy = self._target
        return math.degrees(math.atan2(wy - xy[1], wx - xy[0]) - yaw)

    # -- geometric choice (escapes, and when the rule is boxed in) ------------------------

    def _rear_clear(self, rays: np.ndarray) -> bool:
        """The rear sensors (S5, S6) leave room to back off for one decision."""
        return float(rays[4 * self._k : 6 * self._k].min()) > 0.5 * self._step_length + self._hard

    def _gaps(self, xy: np.ndarray, yaw: float, radius: float) -> np.ndarray | None:
        """Gap (5,) m between the robot's outline and the remembered hits along each
        forward arc and its best follow-up arc; ``None`` if no hit lies within
        ``radius`` m (square) of the robot."""
        hits = self._nearby_hits(xy, radius)
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
        if self._steps < self._tabu_until:
            safe[self._tabu] = False
        if not safe.any():
            # Boxed in: back off if the rear sensors (S5, S6) leave room.
            if self._rear_clear(rays):
                return _BACKWARD
            return int(np.argmax(gap))
        penalty = 2.0 * np.maximum(1.0 - gap / self._soft, 0.0) ** 2
        score = np.where(safe, deviation + penalty, np.inf)
        return int(np.argmin(score))
