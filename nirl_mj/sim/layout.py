"""What an episode's arena is: obstacles, start, target, solvability (numpy/scipy only).

Coordinates are world metres with the arena's corner at (0, 0) and the inner
faces of the border walls at x = 0, x = size[0], y = 0, y = size[1]; angles
are radians counter-clockwise from +x. Nothing here imports MuJoCo: the
:mod:`nirl_mj.sim.arena` module shows a :class:`Layout` in a compiled model and a
map-aware planner can reuse :func:`occupancy_grid`.

Generation order (every draw through the caller's ``random_state``, so a seed
reproduces the arena):

1. ``start_yaw`` (one draw if it is ``"random"``);
2. the floor plan's family (one draw if ``floor_plan`` is ``"mixed"``);
3. per whole-arena attempt: the floor plan's structures (none for ``"random"``:
   :mod:`nirl_mj.sim.floorplans`), the random static obstacles, then the interior
   wall segments (explicit obstacles are fixed and always present);
4. once a solvable static arena is found: the moving obstacles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from nirl_mj.sim.drive import BODY_RADIUS
from nirl_mj.sim.floorplans import FloorPlan, clearance, draw_floor_plan, pick_family
from nirl_mj.sim.spec import ArenaSpec, ObstacleSpec

# Position redraws per obstacle and attempt before the attempt is given up:
# with the default clear radius a draw is rejected a few % of the time, so 100
# only runs out when the spec makes placement (nearly) impossible.
_PLACEMENT_REDRAWS = 100

# 8-connectivity for the start-target test (chosen over 4: fewer false
# "blocked" verdicts on diagonal corridors). A diagonal step between two free
# cell centres may cut into the inflated region by at most half a cell diagonal
# (0.18 m at 0.25 m cells, at the seam of two obstacles) and by ~0.05 m past a
# single convex obstacle; see ``path_exists``. 4-connectivity has the same
# problem at half a cell side, so neither is exact: path_margin pays for it.
_EIGHT = np.ones((3, 3), dtype=bool)


class ArenaGenerationError(ValueError):
    """No solvable arena could be generated; the message names the counts, the
    tries and what to change in the task file."""


@dataclass(frozen=True)
class Obstacle:
    """One static obstacle.

    ``size`` is (half_x, half_y) metres for a box (walls are boxes whose half_x
    is half their length and half_y half their thickness) and (radius,) for a
    cylinder; ``(x, y)`` is the centre (metres), ``yaw`` radians.
    """

    shape: str
    x: float
    y: float
    size: tuple[float, ...]
    yaw: float = 0.0
    is_wall: bool = False

    @property
    def half_extents(self) -> tuple[float, float]:
        """Half-widths (metres) of the obstacle's world-axis-aligned bounding box."""
        if self.shape == "cylinder":
            return self.size[0], self.size[0]
        c, s = abs(math.cos(self.yaw)), abs(math.sin(self.yaw))
        hx, hy = self.size
        return hx * c + hy * s, hx * s + hy * c


@dataclass(frozen=True)
class MovingObstacle:
    """A moving cylinder at its initial position ``(x, y)`` (metres) with ``radius``
    (metres) and constant velocity ``(vx, vy)`` (m/s) between bounces."""

    x: float
    y: float
    radius: float
    vx: float
    vy: float


@dataclass(frozen=True)
class Layout:
    """One episode's arena.

    ``obstacles`` are the static ones (explicit spec obstacles first, then the
    floor plan's, the random obstacles, then the interior walls), not the 4 border
    walls, which are implied by ``size`` (inner faces at 0 and ``size``). ``moving``
    holds the moving cylinders' initial states; ``floor_plan`` the family drawn
    (``arena.floor_plan``, or for ``"mixed"`` the one chosen).
    """

    size: tuple[float, float]
    start: tuple[float, float]
    start_yaw: float
    target: tuple[float, float]
    obstacles: tuple[Obstacle, ...] = ()
    moving: tuple[MovingObstacle, ...] = ()
    floor_plan: str = "random"


@dataclass
class OccupancyGrid:
    """A boolean map of the arena, row-major in y: ``occupied[i, j]`` is the cell
    whose centre is ``((j + 0.5) * resolution, (i + 0.5) * resolution) + origin``.

    ``occupied`` has shape (ny, nx); ``resolution`` is the cell side (metres);
    ``origin`` the world position of the grid's (0, 0) corner (metres).
    """

    occupied: np.ndarray
    resolution: float
    origin: tuple[float, float] = (0.0, 0.0)

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx)."""
        return self.occupied.shape

    def cell_of(self, x: float | np.ndarray, y: float | np.ndarray) -> tuple:
        """Cell ``(i, j)`` (row, column) containing world point ``(x, y)`` (metres),
        clipped to the grid. Scalars give ints, arrays give int arrays."""
        ny, nx = self.occupied.shape
        i = np.clip(np.floor((np.asarray(y) - self.origin[1]) / self.resolution), 0, ny - 1).astype(int)
        j = np.clip(np.floor((np.asarray(x) - self.origin[0]) / self.resolution), 0, nx - 1).astype(int)
        if i.ndim == 0:
            return int(i), int(j)
        return i, j

    def center_of(self, i: int | np.ndarray, j: int | np.ndarray) -> tuple:
        """World centre ``(x, y)`` (metres) of cell ``(i, j)``; scalars or arrays."""
        x = self.origin[0] + (np.asarray(j) + 0.5) * self.resolution
        y = self.origin[1] + (np.asarray(i) + 0.5) * self.resolution
        if x.ndim == 0:
            return float(x), float(y)
        return x, y

    def is_free(self, x: float, y: float) -> bool:
        """True if the cell containing world point ``(x, y)`` is free."""
        return not self.occupied[self.cell_of(x, y)]


def occupancy_grid(layout: Layout, resolution: float, inflate: float = 0.0) -> OccupancyGrid:
    """Rasterises the border walls and the static obstacles of ``layout``.

    A cell is occupied when its centre lies within ``inflate`` metres of an
    obstacle or beyond an inner wall face minus ``inflate`` (i.e. the
    configuration space of a disc of radius ``inflate``, sampled at cell
    centres). Moving obstacles are not drawn. Vectorised: each obstacle only
    evaluates the cells of its inflated bounding box.
    """
    width, height = layout.size
    nx = max(1, math.ceil(width / resolution - 1e-9))
    ny = max(1, math.ceil(height / resolution - 1e-9))
    xs = (np.arange(nx) + 0.5) * resolution
    ys = (np.arange(ny) + 0.5) * resolution
    occ = np.zeros((ny, nx), dtype=bool)
    # Border walls: inner faces at 0 and size; cells past the far face (when
    # size is not a multiple of the resolution) fall in here too.
    occ[:, (xs < inflate) | (xs > width - inflate)] = True
    occ[(ys < inflate) | (ys > height - inflate), :] = True
    for ob in layout.obstacles:
        _rasterise(occ, xs, ys, resolution, ob, inflate)
    return OccupancyGrid(occ, resolution, (0.0, 0.0))


def _rasterise(
    occ: np.ndarray, xs: np.ndarray, ys: np.ndarray, res: float, ob: Obstacle, inflate: float
) -> None:
    ex, ey = ob.half_extents
    j0 = max(0, math.floor((ob.x - ex - inflate) / res))
    j1 = min(xs.size, math.ceil((ob.x + ex + inflate) / res) + 1)
    i0 = max(0, math.floor((ob.y - ey - inflate) / res))
    i1 = min(ys.size, math.ceil((ob.y + ey + inflate) / res) + 1)
    if j0 >= j1 or i0 >= i1:
        return
    dx = xs[None, j0:j1] - ob.x  # (1, nj)
    dy = ys[i0:i1, None] - ob.y  # (ni, 1)
    if ob.shape == "cylinder":
        r = ob.size[0] + inflate
        hit = dx * dx + dy * dy <= r * r
    else:
        c, s = math.cos(ob.yaw), math.sin(ob.yaw)
        # Box-frame coordinates of the cell centres, distance to the box outside it.
        qx = np.abs(c * dx + s * dy) - ob.size[0]
        qy = np.abs(-s * dx + c * dy) - ob.size[1]
        np.maximum(qx, 0.0, out=qx)
        np.maximum(qy, 0.0, out=qy)
        hit = qx * qx + qy * qy <= inflate * inflate
    occ[i0:i1, j0:j1] |= hit


def path_exists(grid: OccupancyGrid, start: tuple[float, float], target: tuple[float, float]) -> bool:
    """True if the cells of ``start`` and ``target`` (world metres) are free and
    8-connected through free cells.

    Sampling at cell centres is approximate: a polyline through 8-connected
    free centres keeps at least ``inflate - resolution * sqrt(2) / 2`` metres
    from the obstacles in the worst case (a step across the seam of two
    obstacles) and ``inflate - 0.052`` m from a single convex obstacle
    (inflate 0.325 m, 0.25 m cells). Choose ``inflate`` = robot radius + a
    margin of about half a cell diagonal for a guaranteed collision-free path.
    """
    si, sj = grid.cell_of(*start)
    ti, tj = grid.cell_of(*target)
    occ = grid.occupied
    if occ[si, sj] or occ[ti, tj]:
        return False
    labels, _ = ndimage.label(~occ, structure=_EIGHT)
    return bool(labels[si, sj] == labels[ti, tj])


def advance(
    positions: np.ndarray,
    velocities: np.ndarray,
    radii: np.ndarray,
    dt: float,
    size: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray]:
    """Moves cylinders in straight lines for ``dt`` seconds, bouncing off the walls.

    ``positions`` (M, 2) metres, ``velocities`` (M, 2) m/s, ``radii`` (M,) metres,
    ``size`` the arena's (width, height) metres. A cylinder reflects specularly
    (the velocity component normal to the wall flips) when its rim would cross
    an inner wall face (0 or size). Cylinders do NOT bounce off static obstacles
    or each other: they pass through them (the paper's moving obstacles only
    bounce off the border walls). Returns new ``(positions, velocities)``;
    the inputs are not modified. See :func:`advance_in_place` for the hot path.
    """
    p = np.array(positions, dtype=np.float64).reshape(-1, 2)
    v = np.array(velocities, dtype=np.float64).reshape(-1, 2)
    low = np.asarray(radii, dtype=np.float64).reshape(-1, 1)
    high = np.asarray(size, dtype=np.float64).reshape(1, 2) - low
    advance_in_place(p, v, low, high, dt)
    return p, v


def advance_in_place(
    positions: np.ndarray, velocities: np.ndarray, low: np.ndarray, high: np.ndarray, dt: float
) -> None:
    """:func:`advance` on float64 buffers, updated in place, with precomputed
    bounds for the centres: ``low`` = radii (M, 1) and ``high`` = size - radii
    (M, 2), metres. Used every command period, so the common case (no bounce)
    is four numpy calls."""
    p, v = positions, velocities
    p += v * dt
    # Bounces are rare (one per obstacle every tens of seconds).
    if (p < low).any() or (p > high).any():
        lo = np.broadcast_to(low, p.shape)
        hi = np.broadcast_to(high, p.shape)
        below = p < lo
        above = p > hi
        p[below] = 2.0 * lo[below] - p[below]
        v[below] = np.abs(v[below])
        p[above] = 2.0 * hi[above] - p[above]
        v[above] = -np.abs(v[above])
        # A step longer than the free width would reflect past the far wall.
        np.clip(p, lo, hi, out=p)


def time_to_wall(positions: np.ndarray, velocities: np.ndarray, low: np.ndarray, high: np.ndarray) -> float:
    """Seconds until the first of the cylinders reaches a wall (inf if none
    moves), with the bounds of :func:`advance_in_place`. Lets the hot path
    skip the bounce test while no bounce can happen."""
    v = velocities
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(v > 0, (high - positions) / v, np.where(v < 0, (low - positions) / v, np.inf))
    return float(np.max([t.min(), 0.0])) if t.size else math.inf


# -- generation ----------------------------------------------------------------------


def generate_layout(
    spec: ArenaSpec, random_state: np.random.RandomState, robot_radius: float = BODY_RADIUS
) -> Layout:
    """Draws one solvable arena for ``spec``.

    Explicit ``spec.obstacles`` come first and are always present as given.
    The floor plan's structures (``spec.floor_plan``), random obstacles, wall
    segments and moving obstacles lie inside the arena and keep
    ``spec.clear_radius + robot_radius`` metres (outline to point) from start
    and target. Solvable means: on an occupancy grid at
    ``spec.grid_resolution`` inflated by ``robot_radius + spec.path_margin``
    the start and target cells are free and 8-connected. Up to
    ``spec.max_tries`` whole-arena attempts; raises
    :class:`ArenaGenerationError` otherwise (immediately if the explicit
    obstacles alone block the way).
    """
    width, height = spec.size
    start = (float(spec.start[0]), float(spec.start[1]))
    target = (float(spec.target[0]), float(spec.target[1]))
    if spec.start_yaw == "target":
        start_yaw = math.atan2(target[1] - start[1], target[0] - start[0])
    elif spec.start_yaw == "random":
        start_yaw = float(random_state.uniform(-math.pi, math.pi))
    else:
        start_yaw = float(spec.start_yaw)

    explicit = tuple(_explicit_obstacle(o) for o in spec.obstacles)
    inflate = robot_radius + spec.path_margin
    base = Layout((float(width), float(height)), start, start_yaw, target, explicit, ())
    if explicit:
        _check_explicit(base, spec, inflate)

    keep = spec.clear_radius + robot_radius
    points = np.array([start, target])
    family = pick_family(spec, random_state)
    blocked = unplaceable = 0
    for _ in range(spec.max_tries):
        plan = None if family == "random" else draw_floor_plan(family, spec, random_state, keep)
        obstacles = _random_obstacles(spec, random_state, points, keep)
        walls = _random_walls(spec, random_state, points, keep)
        if obstacles is None or walls is None or (plan is None and family != "random"):
            unplaceable += 1
            continue
        static = explicit + _plan_obstacles(plan) + obstacles + walls
        layout = Layout(base.size, start, start_yaw, target, static, (), family)
        if path_exists(occupancy_grid(layout, spec.grid_resolution, inflate), start, target):
            moving = _random_moving(spec, random_state, points, keep)
            return Layout(base.size, start, start_yaw, target, layout.obstacles, moving, family)
        blocked += 1
    raise ArenaGenerationError(_failure_message(spec, family, blocked, unplaceable))


def _plan_obstacles(plan: FloorPlan | None) -> tuple[Obstacle, ...]:
    if plan is None:
        return ()
    return tuple(
        Obstacle("cylinder", x, y, (hx,), 0.0, False)
        if cyl
        else Obstacle("box", x, y, (hx, hy), yaw, wall > 0)
        for x, y, hx, hy, yaw, cyl, wall, _ in plan.pieces.tolist()
    )


def _explicit_obstacle(o: ObstacleSpec) -> Obstacle:
    size = tuple(float(s) for s in o.size)
    x, y = (float(v) for v in o.position)
    if o.shape == "cylinder":
        return Obstacle("cylinder", x, y, size[:1], 0.0, False)
    return Obstacle("box", x, y, size[:2], float(o.yaw), o.shape == "wall")


def _check_explicit(layout: Layout, spec: ArenaSpec, inflate: float) -> None:
    grid = occupancy_grid(layout, spec.grid_resolution, inflate)
    for name, point in (("start", layout.start), ("target", layout.target)):
        if not grid.is_free(*point):
            raise ArenaGenerationError(
                f"the explicit obstacles in arena.obstacles cover the {name} {list(point)} "
                f"(with the robot radius + arena.path_margin = {inflate:.3f} m around them); "
                f"move or shrink them, or move arena.{name}"
            )
    if not path_exists(grid, layout.start, layout.target):
        raise ArenaGenerationError(
            f"the explicit obstacles in arena.obstacles alone block every path from start "
            f"{list(layout.start)} to target {list(layout.target)} (a {2 * inflate:.2f} m wide robot "
            f"corridor is needed); move, shorten or remove them"
        )


def _place(
    random_state: np.random.RandomState,
    spec: ArenaSpec,
    hx: np.ndarray,
    hy: np.ndarray,
    yaw: np.ndarray,
    is_cyl: np.ndarray,
    points: np.ndarray,
    keep: float,
) -> tuple[np.ndarray, np.ndarray] | None:
    """Uniform centres keeping each shape inside the arena and ``keep`` metres
    from ``points``; redraws only the rejected ones. None if impossible."""
    width, height = spec.size
    n = hx.size
    c, s = np.abs(np.cos(yaw)), np.abs(np.sin(yaw))
    ex = np.where(is_cyl, hx, hx * c + hy * s)
    ey = np.where(is_cyl, hx, hx * s + hy * c)
    if np.any(2 * ex > width) or np.any(2 * ey > height):
        return None
    x = np.empty(n)
    y = np.empty(n)
    todo = np.arange(n)
    for _ in range(_PLACEMENT_REDRAWS):
        if todo.size == 0:
            return x, y
        u = random_state.uniform(size=(todo.size, 2))
        x[todo] = ex[todo] + u[:, 0] * (width - 2 * ex[todo])
        y[todo] = ey[todo] + u[:, 1] * (height - 2 * ey[todo])
        d = clearance(points, x[todo], y[todo], hx[todo], hy[todo], yaw[todo], is_cyl[todo])
        todo = todo[np.any(d < keep, axis=0)]
    return (x, y) if todo.size == 0 else None


def _random_obstacles(
    spec: ArenaSpec, random_state: np.random.RandomState, points: np.ndarray, keep: float
) -> tuple[Obstacle, ...] | None:
    n = spec.static_obstacles
    if n == 0:
        return ()
    lo, hi = spec.obstacle_size
    is_cyl = random_state.uniform(size=n) < spec.cylinder_fraction
    half = random_state.uniform(lo, hi, size=(n, 2))
    yaw = random_state.uniform(0.0, 2 * math.pi, size=n)
    # A cylinder's radius is its first draw; its yaw is irrelevant and stored as 0.
    hx, hy = half[:, 0], np.where(is_cyl, half[:, 0], half[:, 1])
    yaw = np.where(is_cyl, 0.0, yaw)
    placed = _place(random_state, spec, hx, hy, yaw, is_cyl, points, keep)
    if placed is None:
        return None
    x, y = placed
    return tuple(
        Obstacle("cylinder", float(x[k]), float(y[k]), (float(hx[k]),), 0.0, False)
        if is_cyl[k]
        else Obstacle("box", float(x[k]), float(y[k]), (float(hx[k]), float(hy[k])), float(yaw[k]), False)
        for k in range(n)
    )


def _random_walls(
    spec: ArenaSpec, random_state: np.random.RandomState, points: np.ndarray, keep: float
) -> tuple[Obstacle, ...] | None:
    n = spec.interior_walls
    if n == 0:
        return ()
    lo, hi = spec.interior_wall_length
    hx = random_state.uniform(lo, hi, size=n) / 2
    hy = np.full(n, spec.wall_thickness / 2)
    yaw = random_state.uniform(0.0, math.pi, size=n)  # a segment is symmetric under +pi
    is_cyl = np.zeros(n, dtype=bool)
    placed = _place(random_state, spec, hx, hy, yaw, is_cyl, points, keep)
    if placed is None:
        return None
    x, y = placed
    return tuple(
        Obstacle("box", float(x[k]), float(y[k]), (float(hx[k]), float(hy[k])), float(yaw[k]), True)
        for k in range(n)
    )


def _random_moving(
    spec: ArenaSpec, random_state: np.random.RandomState, points: np.ndarray, keep: float
) -> tuple[MovingObstacle, ...]:
    n = spec.moving_obstacles
    if n == 0:
        return ()
    radius = random_state.uniform(*spec.moving_radius, size=n)
    speed = random_state.uniform(*spec.moving_speed, size=n)
    heading = random_state.uniform(0.0, 2 * math.pi, size=n)
    zeros = np.zeros(n)
    placed = _place(random_state, spec, radius, radius, zeros, np.ones(n, dtype=bool), points, keep)
    if placed is None:
        raise ArenaGenerationError(
            f"could not place {n} moving obstacles of radius {list(spec.moving_radius)} m inside the "
            f"{list(spec.size)} m arena at least {keep:.2f} m from start and target; reduce "
            f"arena.moving_radius or arena.clear_radius"
        )
    x, y = placed
    vx, vy = speed * np.cos(heading), speed * np.sin(heading)
    return tuple(
        MovingObstacle(float(x[k]), float(y[k]), float(radius[k]), float(vx[k]), float(vy[k]))
        for k in range(n)
    )


def _failure_message(spec: ArenaSpec, family: str, blocked: int, unplaceable: int) -> str:
    what = f"{spec.static_obstacles} static obstacles"
    if family != "random":
        what += f" on a {family!r} floor plan (arena.floor_plan = {spec.floor_plan!r})"
    if spec.interior_walls:
        what += f" and {spec.interior_walls} interior walls"
    if spec.obstacles:
        what += f" (plus {len(spec.obstacles)} explicit ones)"
    reasons = []
    if blocked:
        reasons.append(f"{blocked} blocked the path from start to target")
    if unplaceable:
        reasons.append(
            f"{unplaceable} could not place every obstacle or structure inside the arena and "
            f"{spec.clear_radius} m (arena.clear_radius) + robot radius away from start and target"
        )
    fixes = ["reduce arena.static_obstacles or arena.obstacle_size"]
    if family != "random":
        fixes.append("arena.floor_plan_count or arena.clear_radius, enlarge arena.size")
    if spec.interior_walls:
        fixes.append("arena.interior_walls or arena.interior_wall_length")
    fixes.append("or raise arena.max_tries")
    return (
        f"could not generate a solvable arena with {what} in {spec.max_tries} tries "
        f"({'; '.join(reasons)}); {', '.join(fixes)}"
    )
