"""What the robot remembers of its own rays, and where that memory says to head when stuck.

:class:`RayMemory` keeps a world-frame grid of ray hits (0.25 m cells; the free stretch of
every ray clears the cells it passes, so obstacles that moved away are forgotten), counts the
decisions spent in each 1 m planning cell, and tracks progress towards the target:

- **Stuck.** When the distance to the target has not improved by 0.5 m for ``stuck_steps``
  decisions, it escapes, until it is 1 m closer to the target than where it got stuck (the
  leaving rule of the Bug algorithms, so every escape ends with progress).
- **Escape bearing.** While escaping, it plans on its memory (Dijkstra on 1 m cells in a
  41 m x 41 m window around the robot, cells near remembered hits expensive, every decision
  spent in a cell making it dearer, the straight-line distance to the target as the cost
  beyond the window) and gives the bearing of a point a few metres down that path. A path is
  kept unless new obstacles were seen (at most every other decision), the visit costs have
  grown for 5 decisions, or the robot strayed from it or reached its end.

It reads only what the robot has: its range rays, its pose and the target position (the pose is
the simulator's, exact: odometry without drift).
Two users: the sensor expert (``nirl_mj.experts.sensor``) steers by it when stuck, and the
task's ``sensing.guide = "memory"`` option puts the escape bearing into phi's sector V, so
that a memoryless policy on phi(s) can leave the pockets a memoryless rule cannot.
Cost: an update is a few small numpy calls (~0.1 ms); a plan ~1 ms, only while escaping.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from nirl_mj.data.features import N_SENSORS
from nirl_mj.sim.drive import BODY_RADIUS
from nirl_mj.sim.sensing import ray_angles

__all__ = ["CELL", "STUCK_STEPS", "RayMemory"]

CELL = 0.25  # memory grid cell side, metres
STUCK_STEPS = 10  # decisions without 0.5 m of progress before the robot counts as stuck
_COARSE = 4  # memory cells per planning cell side (1 m planning cells)
_PLAN_CELL = CELL * _COARSE  # planning cell side, metres
_PAD = 30.0  # memory grid margin around start and target, metres
_WINDOW = 20  # planning window half-side, planning cells (the window is 41 x 41 m)
_WAYPOINT = 6  # planning cells down the path to the escape waypoint (6-8.5 m)

# Planning-grid costs per metre: a cell holding a remembered hit, its
# neighbours, free or unknown cells.
_COST_HIT = 1000.0
_COST_NEAR = 20.0
_COST_FREE = 1.0
# Extra cost per decision already spent in a planning cell: a plan that led
# into a trap gets more expensive every time, so repeated escapes go elsewhere.
_COST_VISIT = 3.0
_EIGHT = np.ones((3, 3), dtype=bool)


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


class RayMemory:
    """The robot's memory of its rays, its progress, and its escape plan (see the module doc).

    Args:
        stuck_steps: decisions without 0.5 m of progress before it escapes.

    Call :meth:`reset` with the first observation, then :meth:`update` once per decision (the
    first observation included), then :meth:`escape_bearing` on the decisions where
    :attr:`escaping` is true.
    """

    def __init__(self, stuck_steps: int = STUCK_STEPS) -> None:
        self.stuck_steps = int(stuck_steps)
        self.occ = np.zeros((1, 1), dtype=bool)

    def reset(self, pose: np.ndarray, target: np.ndarray, rays: np.ndarray) -> None:
        """Forgets everything and starts a grid around the start and the target.

        pose (x m, y m, yaw rad); target (2,) m; rays (9 k,) clearances from the outline (m),
        capped at the sensing range.
        """
        pose = np.asarray(pose, dtype=np.float64)
        target = np.asarray(target, dtype=np.float64)
        rays = np.asarray(rays, dtype=np.float64)
        self.target = target.copy()
        self._angles = ray_angles(rays.size // N_SENSORS)
        # The sensing range is not observed as such: readings are capped at it,
        # so the largest reading seen is the range (or a little less).
        self.range = float(rays.max())
        self._ray_samples = np.arange(BODY_RADIUS, self.range + BODY_RADIUS, CELL)
        lo = np.minimum(pose[:2], target) - _PAD
        hi = np.maximum(pose[:2], target) + _PAD
        # Whole planning cells, so the coarse grid is an exact block reduction.
        n = np.ceil((hi - lo) / _PLAN_CELL).astype(int) * _COARSE
        self.origin = lo
        self.occ = np.zeros((n[1], n[0]), dtype=bool)  # [row = y, column = x]
        self._visits = np.zeros((n[1] // _COARSE, n[0] // _COARSE))
        self.steps = -1  # index of the current decision, 0 at the first update
        self._best = math.inf
        self._last_progress = 0
        self.escaping = False
        self._escape_best = math.inf
        self._path: np.ndarray | None = None  # escape path, world metres (P, 2)
        self._planned_at = -1
        self._hits_since_plan = 0

    def update(self, xy: np.ndarray, yaw: float, rays: np.ndarray) -> None:
        """One decision's observation: remembers the rays, counts the visit, tracks progress.

        xy (2,) m, yaw rad (the task's ``pose``, exact); rays (9 k,) m as in :meth:`reset`.
        """
        self.steps += 1
        self._remember(xy, yaw, rays)
        self._visits[self._coarse_cell(xy)] += 1.0
        to_target = self.target - xy
        self._track_progress(math.hypot(to_target[0], to_target[1]))

    # -- the grid of hits ------------------------------------------------------------------

    def _flat_cells(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat indices into the memory grid of world points ``x``, ``y`` (m, same shape),
        clipped to the grid (the grid reaches far beyond anything the robot can see)."""
        ny, nx = self.occ.shape
        j = np.clip(((x - self.origin[0]) * (1.0 / CELL)).astype(np.int64), 0, nx - 1)
        i = np.clip(((y - self.origin[1]) * (1.0 / CELL)).astype(np.int64), 0, ny - 1)
        return i * nx + j

    def _remember(self, xy: np.ndarray, yaw: float, rays: np.ndarray) -> None:
        """Clears the cells each ray saw through and marks the cells it hit."""
        angle = self._angles + yaw
        cos, sin = np.cos(angle), np.sin(angle)
        reach = rays + BODY_RADIUS  # from the robot's centre
        flat = self.occ.reshape(-1)  # a view: writes go to the grid
        # Free space: samples every cell side along each ray, stopping a cell
        # and a half short of the hit so that a surface is not cleared by its
        # own ray (clearing is what forgets obstacles that moved away).
        free = self._ray_samples[None, :] < (reach - 1.5 * CELL)[:, None]
        x = xy[0] + np.multiply.outer(cos, self._ray_samples)[free]
        y = xy[1] + np.multiply.outer(sin, self._ray_samples)[free]
        flat[self._flat_cells(x, y)] = False
        hit = rays < self.range - 1e-6
        if hit.any():
            cells = self._flat_cells(xy[0] + cos[hit] * reach[hit], xy[1] + sin[hit] * reach[hit])
            self._hits_since_plan += int(np.count_nonzero(~flat[cells]))
            flat[cells] = True

    def nearby_hits(self, xy: np.ndarray, radius: float) -> np.ndarray:
        """Centres (N, 2) m of remembered hit cells within a square of half-side ``radius`` m."""
        ny, nx = self.occ.shape
        j0 = max(0, int((xy[0] - radius - self.origin[0]) / CELL))
        j1 = min(nx, int((xy[0] + radius - self.origin[0]) / CELL) + 1)
        i0 = max(0, int((xy[1] - radius - self.origin[1]) / CELL))
        i1 = min(ny, int((xy[1] + radius - self.origin[1]) / CELL) + 1)
        if j0 >= j1 or i0 >= i1:
            return np.empty((0, 2))
        i, j = np.nonzero(self.occ[i0:i1, j0:j1])
        return np.stack(
            [self.origin[0] + (j + j0 + 0.5) * CELL, self.origin[1] + (i + i0 + 0.5) * CELL], axis=1
        )

    # -- progress and escape ---------------------------------------------------------------

    def _track_progress(self, distance: float) -> None:
        """Switches to escape after ``stuck_steps`` decisions without 0.5 m of progress,
        back once 1 m closer to the target than where it got stuck."""
        if distance < self._best - 0.5:
            self._best = distance
            self._last_progress = self.steps
        if self.escaping:
            if distance < self._escape_best - 1.0:
                self.escaping = False
                self._best = distance
                self._last_progress = self.steps
        elif self.steps - self._last_progress >= self.stuck_steps:
            self.escaping = True
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
        block = self.occ[i0 * _COARSE : i1 * _COARSE, j0 * _COARSE : j1 * _COARSE]
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
        cx = self.origin[0] + (np.arange(j0, j1) + 0.5) * _PLAN_CELL
        cy = self.origin[1] + (np.arange(i0, i1) + 0.5) * _PLAN_CELL
        beyond = np.hypot(cx[None, :] - self.target[0], cy[:, None] - self.target[1]) / _PLAN_CELL
        # A path ends at the target or leaves the window: with a consistent
        # estimate beyond, any cell inside would score no better than staying.
        total = dist.reshape(h, w) + _COST_FREE * beyond + _inner(h, w)
        ti, tj = self._coarse_cell(self.target)
        if i0 <= ti < i1 and j0 <= tj < j1:
            total[ti - i0, tj - j0] = dist[(ti - i0) * w + (tj - j0)]
        node = int(np.argmin(total))
        cells = [node]
        while cells[-1] != start and pred[cells[-1]] >= 0:
            cells.append(int(pred[cells[-1]]))
        cells = np.array(cells[::-1])
        self._path = np.stack([cx[cells % w], cy[cells // w]], axis=1)
        self._planned_at = self.steps
        self._hits_since_plan = 0

    def _coarse_cell(self, point: np.ndarray) -> tuple[int, int]:
        """Planning cell (row, column) of a world point (m), clipped to the grid."""
        ny, nx = self._visits.shape
        i = min(max(int((point[1] - self.origin[1]) // _PLAN_CELL), 0), ny - 1)
        j = min(max(int((point[0] - self.origin[0]) // _PLAN_CELL), 0), nx - 1)
        return i, j

    def escape_bearing(self, xy: np.ndarray, yaw: float) -> float:
        """Bearing (degrees counter-clockwise from the front) of a waypoint ~6 m down the
        escape path; call once per decision while :attr:`escaping` (it may replan)."""
        # Replan only when the path may be stale: new obstacles were seen (at
        # most every other decision), the visit costs have grown for a few
        # decisions, the robot has strayed from the path or come to its end.
        since = self.steps - self._planned_at
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
            wx, wy = self.target
        return math.degrees(math.atan2(wy - xy[1], wx - xy[0]) - yaw)
