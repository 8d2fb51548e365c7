"""The map-aware demonstrator: a global cost-to-go field plus a short look-ahead over the six actions.

:class:`PlannerExpert` reads the whole arena (``env.task.layout`` for the static
obstacles, ``env.task.root_entity`` for the moving obstacles' current state)
but never the task's reward, and it acts only through the six discrete actions.

Per episode (:meth:`PlannerExpert.reset`) it computes a cost-to-go field from
the target: Dijkstra (``scipy.sparse.csgraph``) on an 8-connected occupancy
grid of the static obstacles inflated by the robot radius plus the arena's
``path_margin`` (the inflation under which the generator guarantees a path),
with cells close to obstacles made more expensive so that the plan runs down
the middle of gaps. To keep this cheap it first tries a 1 m grid (blocked
half a cell further out); it moves to 0.5 m and then to the generator's own
grid when the coarser one does not connect the start, when the robot finds
itself where the coarse grid sees no path, or when the cost-to-go at the robot
stops improving (re-planning). Between cell centres the field is read as one
Dijkstra step (min over the 4 surrounding centres of value + distance), which
has no spurious minima; blocked and unreachable cells hold their nearest
reachable cell's value plus a steep slope, so the field pushes out of them.

Per decision (:meth:`PlannerExpert.act`) it scores every two-decision action
sequence (36) with a kinematic model of the arcs: the exact wheel commands the
task's :class:`~nirl_mj.sim.drive.DriveController` would issue (profile, inverse
kinematics, rate limit), integrated through forward kinematics. Every
sequence is followed by braking (action 5 until the robot's forward velocity
changes sign, or action 0 if it was reversing), because the robot cannot stop
instantly: a sequence is only *safe* if the robot can still stop after it.
Safe means every sampled pose keeps ``margin`` metres between the robot's
outline and the static obstacles and the border walls, and ``moving_margin``
from the moving obstacles (predicted with constant velocity, bouncing off the
border walls). Among the
safe sequences it takes the first action of the one ending lowest on the cost
field (twice the value at the end point plus the field's slope along the
final heading times one decision's travel, so the heading counts), with a penalty
for passing close to obstacles. With no safe sequence
it takes the one with the largest clearance, which is usually backing off.

Speed: the arcs depend only on the speed, the timing and the wheel command
at the start of the decision, so the sequence tables are cached per wheel
state (a handful of states occur) in a module-level cache per speed; a
decision then costs a few vectorised numpy calls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import dm_env
import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from nirl_mj.sim import drive
from nirl_mj.sim.drive import BODY_RADIUS
from nirl_mj.sim.layout import Layout, OccupancyGrid, occupancy_grid

__all__ = ["PlannerExpert", "ArcModel", "arc_model", "CostField", "cost_field"]


_BACKWARD = 5
_FORWARD = 0
# 8-neighbourhood offsets (di, dj) with one direction per undirected edge.
_HALF_NEIGHBOURS = ((0, 1), (1, 0), (1, 1), (1, -1))


# -- kinematic model of the actions ---------------------------------------------------------


@dataclass(frozen=True)
class SequenceTable:
    """Every two-decision action sequence from one drive state, with braking appended.

    ``poses`` (S, N, 3): sampled robot poses ``(x, y, yaw)`` (m, m, rad) in the
    robot frame at the decision's start, S = 36 sequences (first action
    ``first[s]``, second ``second[s]``), N samples. ``times`` (N,): seconds after
    the decision's start of each sample. ``end`` the sample index of the end
    of the second decision; ``checked`` (N,) bool marks the samples that count
    for the clearance penalty (the two decisions, not the braking). Sequences
    whose braking ends early repeat their last pose. ``next_state[a]`` the
    drive state (wheel-command key) after action ``a``.
    """

    poses: np.ndarray
    times: np.ndarray
    first: np.ndarray
    second: np.ndarray
    end: int
    checked: np.ndarray
    next_state: tuple[bytes, ...]


class ArcModel:
    """The arcs of the six actions at one speed and timing, cached per drive state.

    The drive state is the last wheel-speed command (rad/s, shape (3,)) of the
    task's :class:`~nirl_mj.sim.drive.DriveController`, which makes the commands of
    the next decision deterministic. States are keyed by their bytes after
    rounding to 1e-6 rad/s, so that float noise does not multiply them.

    Args:
        speed: forward speed, m/s.
        period: decision period, s.
        cmd_dt: command period, s.
        max_accel: wheel rim acceleration limit, m/s^2.
        spacing: at most this many metres of travel between samples.
    """

    def __init__(self, speed: float, period: float, cmd_dt: float, max_accel: float, spacing: float = 0.12):
        self.speed, self.period, self.cmd_dt, self.max_accel = speed, period, cmd_dt, max_accel
        self.n_cmd = max(1, round(period / cmd_dt))
        # The backward action can be faster than the nominal speed only transiently; the
        # nominal speed sets the sample spacing.
        stride = max(1, math.floor(spacing / max(speed * cmd_dt, 1e-9)))
        idx = np.arange(stride - 1, self.n_cmd, stride)
        if idx.size == 0 or idx[-1] != self.n_cmd - 1:
            idx = np.append(idx, self.n_cmd - 1)
        self._sample_idx = idx
        self._profiles = [
            drive.wheel_speeds(drive.action_profile(a, speed, period, cmd_dt, max_accel)) for a in range(6)
        ]
        self._segments: dict[tuple[bytes, int], tuple[np.ndarray, np.ndarray, float]] = {}
        self._states: dict[bytes, np.ndarray] = {}
        self._tables: dict[bytes, SequenceTable] = {}
        self.zero_state = self._key(np.zeros(3))

    def _key(self, wheels: np.ndarray) -> bytes:
        w = np.round(np.asarray(wheels, dtype=np.float64), 6) + 0.0  # + 0.0: no negative zeros
        key = w.tobytes()
        self._states.setdefault(key, w)
        return key

    def segment(self, state: bytes, action: int) -> tuple[np.ndarray, bytes, float]:
        """One decision of ``action`` from drive state ``state``.

        Returns ``(samples, next_state, end_vx)``: samples (K, 3) poses
        ``(x, y, yaw)`` relative to the decision's start (robot frame, m/rad)
        at the sample times :attr:`sample_times`, the drive state afterwards
        and the commanded forward velocity at the end (m/s).
        """
        cached = self._segments.get((state, action))
        if cached is None:
            commands = drive.rate_limit(
                self._states[state], self._profiles[action], self.max_accel / drive.WHEEL_RADIUS, self.cmd_dt
            )
            twist = drive.body_twist(commands)  # (n, 3) per command period, zero-order hold
            dt = self.cmd_dt
            yaw_end = np.cumsum(twist[:, 2]) * dt
            # Midpoint heading of each command period: exact for a constant twist to O(dt^2).
            yaw_mid = yaw_end - 0.5 * twist[:, 2] * dt
            c, s = np.cos(yaw_mid), np.sin(yaw_mid)
            x = np.cumsum((twist[:, 0] * c - twist[:, 1] * s) * dt)
            y = np.cumsum((twist[:, 0] * s + twist[:, 1] * c) * dt)
            k = self._sample_idx
            samples = np.stack([x[k], y[k], yaw_end[k]], axis=1)
            cached = (samples, self._key(commands[-1]), float(twist[-1, 0]))
            self._segments[(state, action)] = cached
        return cached

    @property
    def sample_times(self) -> np.ndarray:
        """(K,) seconds after a decision's start of the samples of :meth:`segment`."""
        return (self._sample_idx + 1) * self.cmd_dt

    def table(self, state: bytes) -> SequenceTable:
        """The :class:`SequenceTable` of drive state ``state`` (built once, then cached)."""
        tab = self._tables.get(state)
        if tab is None:
            tab = self._build_table(state)
            self._tables[state] = tab
        return tab

    def _build_table(self, state: bytes) -> SequenceTable:
        k = self._sample_idx.size
        rows, firsts, seconds = [], [], []
        next_state = []
        for a1 in range(6):
            seg1, s1, _ = self.segment(state, a1)
            next_state.append(s1)
            for a2 in range(6):
                seg2, s2, vx = self.segment(s1, a2)
                parts = [seg1, _compose(seg1[-1], seg2)]
                # Brake: the opposite action until the commanded forward velocity has
                # changed sign (at most 4 decisions, enough up to 5 m/s).
                pose, st = parts[-1][-1], s2
                direction = math.copysign(1.0, vx) if abs(vx) > 1e-9 else 0.0
                for _ in range(4):
                    if direction == 0.0:
                        break
                    seg, st, vx = self.segment(st, _BACKWARD if direction > 0 else _FORWARD)
                    seg = _compose(pose, seg)
                    parts.append(seg)
                    pose = seg[-1]
                    if vx * direction <= 0.0:
                        break
                rows.append(np.concatenate(parts))
                firsts.append(a1)
                seconds.append(a2)
        n = max(r.shape[0] for r in rows)
        poses = np.stack([np.concatenate([r, np.repeat(r[-1:], n - r.shape[0], axis=0)]) for r in rows])
        t = self.sample_times
        times = np.concatenate([t + self.period * m for m in range(math.ceil(n / k))])[:n]
        checked = np.arange(n) < 2 * k
        return SequenceTable(
            poses, times, np.array(firsts), np.array(seconds), 2 * k - 1, checked, tuple(next_state)
        )


def _compose(base: np.ndarray, rel: np.ndarray) -> np.ndarray:
    """Poses ``rel`` (K, 3) given relative to pose ``base`` (3,), expressed in base's frame."""
    c, s = math.cos(base[2]), math.sin(base[2])
    out = np.empty_like(rel)
    out[:, 0] = base[0] + c * rel[:, 0] - s * rel[:, 1]
    out[:, 1] = base[1] + s * rel[:, 0] + c * rel[:, 1]
    out[:, 2] = base[2] + rel[:, 2]
    return out


_ARC_MODELS: dict[tuple[float, float, float, float], ArcModel] = {}


def arc_model(speed: float, period: float, cmd_dt: float, max_accel: float) -> ArcModel:
    """The shared :class:`ArcModel` for this speed (m/s) and timing (s, s, m/s^2)."""
    key = (float(speed), float(period), float(cmd_dt), float(max_accel))
    model = _ARC_MODELS.get(key)
    if model is None:
        model = _ARC_MODELS[key] = ArcModel(*key)
    return model


# -- global cost-to-go ----------------------------------------------------------------------


@dataclass(frozen=True)
class CostField:
    """Cost-to-go (metres, clearance-weighted) to the target, sampled at cell centres.

    ``values`` (ny, nx) is finite everywhere: occupied and unreachable cells
    hold their nearest reachable cell's value plus ``slope`` times the distance
    to it. ``resolution`` is the cell side (m); the grid's corner is at (0, 0).
    """

    values: np.ndarray
    resolution: float
    reachable: np.ndarray
    """(ny, nx) bool: cells connected to the target (the others hold fill values)."""

    def __post_init__(self) -> None:
        # Flat copy and bounds for the hot path (frozen dataclass: object.__setattr__).
        ny, nx = self.values.shape
        object.__setattr__(self, "_flat", np.ascontiguousarray(self.values).ravel())
        object.__setattr__(self, "_hi", (nx - 1.000001, ny - 1.000001))

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Cost-to-go (m) at world points ``x``, ``y`` (metres, same shapes).

        ``min over the 4 surrounding cell centres c of values[c] + |p - c|``:
        one Dijkstra step from the point. Unlike bilinear interpolation this
        has no spurious minima where the plan passes diagonally between two
        blocked cells (bilinear averages the blocked corners into a ridge
        across the passage, and a greedy follower stalls in front of it).
        """
        flat = self._flat
        nx = self.values.shape[1]
        res = self.resolution
        # np.minimum/np.maximum: np.clip's Python wrapper costs more than the work here.
        u = np.minimum(np.maximum(x * (1.0 / res) - 0.5, 0.0), self._hi[0])
        w = np.minimum(np.maximum(y * (1.0 / res) - 0.5, 0.0), self._hi[1])
        j = u.astype(np.intp)
        i = w.astype(np.intp)
        # Offsets (cell sides) of the point from its lower-left centre and the other three.
        fu = u - j
        fw = w - i
        gu = 1.0 - fu
        gw = 1.0 - fw
        k = i * nx + j
        best = flat[k] + res * np.sqrt(fu * fu + fw * fw)
        best = np.minimum(best, flat[k + 1] + res * np.sqrt(gu * gu + fw * fw))
        k += nx
        best = np.minimum(best, flat[k] + res * np.sqrt(fu * fu + gw * gw))
        return np.minimum(best, flat[k + 1] + res * np.sqrt(gu * gu + gw * gw))

    def covers(self, x: float, y: float) -> bool:
        """True if one of the 4 cell centres around world point ``(x, y)`` (m) is
        reachable, i.e. the field's value there is a path length, not a fill."""
        ny, nx = self.values.shape
        u = min(max(x / self.resolution - 0.5, 0.0), nx - 1.000001)
        w = min(max(y / self.resolution - 0.5, 0.0), ny - 1.000001)
        j, i = int(u), int(w)
        return bool(self.reachable[i : i + 2, j : j + 2].any())


_LEVELS: tuple[tuple[float, float], ...] = ((1.0, 0.5), (0.5, 0.0), (0.25, 0.0))
"""Cost-field grids tried in turn, (cell side, extra inflation) in metres. The
1 m grid costs ~1/4 of the 0.5 m one; its cell centres are blocked half a
cell further out so that a path through free centres keeps about the base
inflation everywhere (not just at the centres), at the price of closing gaps
that the finer grids still see. The last level is the generator's own test
(``spec.arena.grid_resolution`` by default), which is guaranteed to connect."""


def cost_field(
    layout: Layout,
    inflate: float,
    levels: tuple[tuple[float, float], ...] = _LEVELS,
    clearance_scale: float = 1.5,
    clearance_weight: float = 2.0,
    slope: float = 4.0,
) -> CostField:
    """Dijkstra cost-to-go from ``layout.target`` over the static obstacles.

    Cells within ``inflate`` metres (robot radius + margin) plus the level's
    extra inflation of an obstacle are blocked. A free cell whose gap
    (clearance minus the robot radius, metres) is below ``clearance_scale``
    costs up to ``1 + clearance_weight`` per metre, quadratically in the
    shortfall, so plans keep away from obstacles when there is room. The
    first of ``levels`` (cell side, extra inflation; metres) on which the
    start connects to the target is used.
    """
    for res, extra in levels:
        grid = occupancy_grid(layout, res, inflate + extra)
        field = _dijkstra_field(grid, layout, inflate + extra, clearance_scale, clearance_weight, slope)
        if field is not None:
            return field
    # Even the finest grid disconnects start and target (explicit obstacles placed
    # tighter than the generator's margin): plan with the bare robot radius.
    res = levels[-1][0]
    grid = occupancy_grid(layout, res, BODY_RADIUS)
    field = _dijkstra_field(grid, layout, BODY_RADIUS, clearance_scale, clearance_weight, slope, force=True)
    assert field is not None
    return field


def _dijkstra_field(
    grid: OccupancyGrid,
    layout: Layout,
    inflate: float,
    clearance_scale: float,
    clearance_weight: float,
    slope: float,
    force: bool = False,
) -> CostField | None:
    occ = grid.occupied
    res = grid.resolution
    ny, nx = occ.shape
    free = ~occ
    # Gap to the nearest obstacle (m): distance to the nearest blocked cell centre,
    # plus the inflation, minus the robot radius and half a cell (the blocked cell's edge).
    gap = ndimage.distance_transform_edt(free) * res + (inflate - BODY_RADIUS) - 0.5 * res
    shortfall = np.clip(1.0 - gap / clearance_scale, 0.0, 1.0)
    weight = (1.0 + clearance_weight * shortfall * shortfall).ravel()
    flat_free = free.ravel()
    idx = np.arange(ny * nx).reshape(ny, nx)
    rows, cols, vals = [], [], []
    for di, dj in _HALF_NEIGHBOURS:
        a = idx[0 : ny - di, max(0, -dj) : nx - max(0, dj)].ravel()
        b = a + di * nx + dj
        ok = flat_free[a] & flat_free[b]
        a, b = a[ok], b[ok]
        w = 0.5 * math.hypot(di, dj) * res * (weight[a] + weight[b])
        rows += [a, b]
        cols += [b, a]
        vals += [w, w]
    graph = sparse.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(ny * nx, ny * nx)
    )
    target = _nearest_free(grid, layout.target)
    if target is None:
        return None
    dist = csgraph.dijkstra(graph, directed=True, indices=target[0] * nx + target[1]).reshape(ny, nx)
    reachable = np.isfinite(dist)
    # The start's own cell must be reachable: its nearest free cell may lie on the
    # far side of a wall, and the fill below would then pull the robot into it.
    if not reachable[grid.cell_of(*layout.start)] and not force:
        return None
    # Fill blocked/unreachable cells from their nearest reachable cell, sloping
    # upwards into obstacles so the field pushes the robot out of them.
    far, (fi, fj) = ndimage.distance_transform_edt(~reachable, return_indices=True)
    values = np.where(reachable, dist, dist[fi, fj] + slope * far * res)
    return CostField(values, res, reachable)


def _nearest_free(grid: OccupancyGrid, point: tuple[float, float]) -> tuple[int, int] | None:
    """The free cell (i, j) nearest to ``point`` (metres), or None if all are blocked."""
    i, j = grid.cell_of(*point)
    if not grid.occupied[i, j]:
        return i, j
    free = np.argwhere(~grid.occupied)
    if free.size == 0:
        return None
    k = int(np.argmin((free[:, 0] - i) ** 2 + (free[:, 1] - j) ** 2))
    return int(free[k, 0]), int(free[k, 1])


# -- obstacles as signed-distance shapes --------------------------------------------------------


def _obstacle_arrays(layout: Layout) -> np.ndarray:
    """Static obstacles as rounded boxes, (N, 7): x, y, cos yaw, sin yaw, half_x,
    half_y, rounding (metres); a cylinder is a point box rounded by its radius."""
    rows = []
    for ob in layout.obstacles:
        if ob.shape == "cylinder":
            rows.append((ob.x, ob.y, 1.0, 0.0, 0.0, 0.0, ob.size[0]))
        else:
            rows.append((ob.x, ob.y, math.cos(ob.yaw), math.sin(ob.yaw), ob.size[0], ob.size[1], 0.0))
    return np.array(rows, dtype=np.float64).reshape(-1, 7)


# -- the expert -----------------------------------------------------------------------------------


class PlannerExpert:
    """Map-aware expert: cost-to-go planning plus a kinematic two-decision look-ahead.

    Args:
        margin: metres the robot's outline must keep from everything along a
            sequence (including its braking) for the sequence to count as safe;
            covers the model's tracking error on the ``tyre`` drive.
        moving_margin: the same for the moving obstacles (their prediction is
            coarser: constant velocity).
        comfort: gap (m) below which a sequence pays ``clearance_weight`` per
            squared metre of shortfall.
        clearance_weight: weight of that penalty (cost-field metres per m^2).
        levels: cost-field grids to try, (cell side, extra inflation) in
            metres; the arena's own ``grid_resolution`` with no extra
            inflation (where the generator guarantees a path) is always
            tried last.
    """

    kind = "planner"

    def __init__(
        self,
        margin: float = 0.12,
        moving_margin: float = 0.3,
        comfort: float = 0.8,
        clearance_weight: float = 4.0,
        levels: tuple[tuple[float, float], ...] = _LEVELS[:2],
    ) -> None:
        self.margin = margin
        self.moving_margin = moving_margin
        self.comfort = comfort
        self.clearance_weight = clearance_weight
        self.levels = tuple(levels)
        self._field: CostField | None = None
        self._arena = None
        self._model: ArcModel | None = None
        self._state = b""
        self._size = (0.0, 0.0)
        self._obstacles = np.zeros((0, 7))
        self._bound = np.zeros(0)
        self._reach = 0.0
        self._carrot = 1.0
        self._moving = False
        self._origin = (0.0, 0.0)
        self._layout: Layout | None = None
        self._inflate = 0.0
        self._levels: tuple[tuple[float, float], ...] = ()
        self._level = 0
        self._best = math.inf
        self._since = 0
        self._patience = 1
        self.replans = 0
        """Re-plans on a finer grid in the current episode (progress stalled)."""

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        """Plans the episode's cost field and resets the drive-state mirror."""
        task = env.task
        spec = task.spec
        layout: Layout = task.layout
        control = spec.control
        self._layout = layout
        self._inflate = BODY_RADIUS + spec.arena.path_margin
        self._levels = (*self.levels, (spec.arena.grid_resolution, 0.0))
        self._field = cost_field(layout, self._inflate, self._levels)
        self._level = self._field_level()
        self._best = math.inf
        self._since = 0
        # Decisions without a new best cost-to-go before re-planning: the time to
        # travel ~20 m, long enough for any detour around a moving obstacle.
        self._patience = max(10, round(20.0 / (control.speed * control.decision_period)))
        self.replans = 0
        self._model = arc_model(
            control.speed, control.decision_period, control.command_period, control.max_accel
        )
        self._state = self._model.zero_state
        self._size = (float(layout.size[0]), float(layout.size[1]))
        self._obstacles = _obstacle_arrays(layout)
        # Bounding-circle radius of each obstacle, for the cheap "is it near" filter.
        self._bound = np.hypot(self._obstacles[:, 4], self._obstacles[:, 5]) + self._obstacles[:, 6]
        table = self._model.table(self._state)
        self._reach = float(np.hypot(table.poses[..., 0], table.poses[..., 1]).max()) + self.comfort + 0.5
        self._carrot = control.speed * control.decision_period
        self._moving = len(layout.moving) > 0
        self._arena = task.root_entity

    def act(self, timestep: dm_env.TimeStep) -> int:
        """Scores the 36 two-decision sequences from the current pose; returns the best first action."""
        model = self._model
        if model is None or self._field is None:
            raise RuntimeError("PlannerExpert.act called before reset")
        x0, y0, yaw0 = (float(v) for v in timestep.observation["pose"])
        self._origin = (x0, y0)
        self._watch_progress(x0, y0)
        tab = model.table(self._state)
        c, s = math.cos(yaw0), math.sin(yaw0)
        lx, ly = tab.poses[..., 0], tab.poses[..., 1]
        px = x0 + c * lx - s * ly  # (S, N) world x of every sample
        py = y0 + s * lx + c * ly

        gap = self._static_gap(px, py, x0, y0)
        if self._moving:
            gap = np.minimum(gap, self._moving_gap(px, py, tab.times) - (self.moving_margin - self.margin))
        min_gap = gap.min(axis=1)  # (S,) smallest gap along sequence and braking
        safe = min_gap >= self.margin

        e = tab.end
        ex, ey = px[:, e], py[:, e]
        heading = yaw0 + tab.poses[:, e, 2]
        # Field at the end point and its slope along the final heading, by central
        # differences over +-h (one call for all points). The slope times one
        # decision's travel stands for the field one decision ahead: evaluating it
        # there directly would look through thin walls.
        h = 0.5 * self._field.resolution
        hx, hy = h * np.cos(heading), h * np.sin(heading)
        n_seq = ex.shape[0]
        values = self._field(np.concatenate([ex, ex + hx, ex - hx]), np.concatenate([ey, ey + hy, ey - hy]))
        slope = (values[n_seq : 2 * n_seq] - values[2 * n_seq :]) / (2.0 * h)
        cost = 2.0 * values[:n_seq] + self._carrot * slope
        shortfall = np.maximum(self.comfort - gap[:, tab.checked].min(axis=1), 0.0)
        cost = cost + self.clearance_weight * shortfall * shortfall
        if safe.any():
            best = int(np.argmin(np.where(safe, cost, np.inf)))
        else:
            # Nothing is safe: the largest clearance (usually backing off), cost as tie-break.
            best = int(np.argmax(min_gap - 1e-6 * cost))
        action = int(tab.first[best])
        self._state = tab.next_state[action]
        return action

    def _field_level(self) -> int:
        """Index in ``self._levels`` of the current field's grid."""
        res = self._field.resolution
        return next((k for k, (r, _) in enumerate(self._levels) if r == res), len(self._levels) - 1)

    def _watch_progress(self, x: float, y: float) -> None:
        """Re-plans on the next finer grid when the cost-to-go at the robot has not
        improved for ``_patience`` decisions: the coarse grid may show a gap that
        the robot cannot take, and the finer grids see it closed."""
        if not self._field.covers(x, y) and self._level + 1 < len(self._levels):
            # The robot is where this grid sees no path (a gap or pocket it closes).
            self._replan()
            return
        value = float(self._field(np.array([x]), np.array([y]))[0])
        if value < self._best - 0.25:
            self._best, self._since = value, 0
            return
        self._since += 1
        if self._since > self._patience and self._level + 1 < len(self._levels):
            self._replan()

    def _replan(self) -> None:
        """Cost field on the next finer level (that connects the start)."""
        self._field = cost_field(self._layout, self._inflate, self._levels[self._level + 1 :])
        self._level = self._field_level()
        self._best, self._since = math.inf, 0
        self.replans += 1

    def _static_gap(self, px: np.ndarray, py: np.ndarray, x0: float, y0: float) -> np.ndarray:
        """Gap (m) between the robot's outline and the nearest wall or static obstacle, shape of px."""
        w, h = self._size
        gap = np.minimum(np.minimum(px, w - px), np.minimum(py, h - py))
        ob = self._obstacles
        if ob.shape[0]:
            near = np.hypot(ob[:, 0] - x0, ob[:, 1] - y0) - self._bound < self._reach
            if near.any():
                ob = ob[near]
                dx = px[..., None] - ob[:, 0]
                dy = py[..., None] - ob[:, 1]
                qx = np.abs(ob[:, 2] * dx + ob[:, 3] * dy) - ob[:, 4]
                qy = np.abs(ob[:, 2] * dy - ob[:, 3] * dx) - ob[:, 5]
                outside = np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0))
                sdf = outside + np.minimum(np.maximum(qx, qy), 0.0) - ob[:, 6]
                gap = np.minimum(gap, sdf.min(axis=-1))
        return gap - BODY_RADIUS

    def _moving_gap(self, px: np.ndarray, py: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Gap (m) to the nearest moving obstacle at each sample's time, shape of px.

        Moving obstacles are predicted at constant velocity, reflected off the
        border walls as the arena moves them."""
        arena = self._arena
        pos = arena.moving_positions  # (M, 2)
        if pos.shape[0] == 0:
            return np.full(px.shape, np.inf)
        vel = arena.moving_velocities
        rad = arena.moving_radii
        # Only the obstacles that can come within reach over the horizon (usually 0-2).
        x0, y0 = self._origin
        speed = np.hypot(vel[:, 0], vel[:, 1])
        near = np.hypot(pos[:, 0] - x0, pos[:, 1] - y0) - rad - speed * times[-1] < self._reach
        if not near.any():
            return np.full(px.shape, np.inf)
        pos, vel, rad = pos[near], vel[near], rad[near]
        lo = rad[:, None]  # (M, 1)
        hi = np.asarray(self._size)[None, :] - lo  # (M, 2)
        p = pos[None, :, :] + times[:, None, None] * vel[None, :, :]  # (N, M, 2)
        # One reflection suffices over a few seconds (a crossing takes much longer).
        p = np.where(p < lo, 2.0 * lo - p, p)
        p = np.where(p > hi, 2.0 * hi - p, p)
        dx = px[..., None] - p[None, :, :, 0]  # (S, N, M)
        dy = py[..., None] - p[None, :, :, 1]
        return (np.hypot(dx, dy) - rad).min(axis=-1) - BODY_RADIUS
