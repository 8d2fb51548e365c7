"""Structured floor plans: corridors, pockets, clusters, blocks, rooms, slalom (numpy only).

A floor plan is drawn once per layout attempt by :func:`nirl_mj.sim.layout.generate_layout`
(``arena.floor_plan``), before the random obstacles, which are added on top. Every draw goes
through the caller's ``random_state``, so a seed reproduces the plan; ``"random"`` (the
default) draws nothing here, which keeps earlier arenas bit-identical.

Structures other than rooms sit along the straight start-target line, in a frame with ``s``
metres along the line from the start and ``t`` metres to its left. Sizes are fixed metres at
the robot's scale (0.45 m wide, 1 m per decision at 2 m/s, 5 m sensing range); the counts
scale with the start-target distance (``arena.floor_plan_count = 0``) or are given.

- ``corridors``: walls across the line, perpendicular to it and from border to border, each
  with one or two gaps of :data:`GAP_WIDTH` within :data:`GAP_SPAN` of the line to find.
- ``pockets``: U-shaped traps (inner width 8-14 m, depth 6-12 m) on or near the line whose
  opening faces the start (within 20 degrees): a greedy robot drives in and must turn back.
- ``clusters``: 6-9 boxes and cylinders (0.5-1 m) grouped with 1.5-3 m gaps between them.
- ``blocks``: big boxes, sides 8-20 m, near the line.
- ``rooms``: walls parallel to the arena's sides partitioning it into a grid of rooms; every
  wall between two crossings has a doorway of :data:`GAP_WIDTH` (a stretch too short for one,
  with 1 m kept from the crossing walls, is left open).
- ``slalom``: staggered walls across the line, 8-12 m apart (closer, down to 4 m, where the
  arena is too short for them), alternately from the border on the right and on the left to
  3-6 m past the line: passing them is a zig-zag.
- ``mixed``: one of the six drawn per episode.

Pockets, clusters and blocks keep :data:`SEPARATION` metres from each other (the walls of
corridors, rooms and slalom are laid out by their plan, rooms' walls crossing); every structure
keeps ``clear_radius`` plus the robot radius from start and target. Walls of corridors, pockets,
rooms and slalom carry the wall flag (the sensors report walls); clusters and blocks are obstacles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

# A nirl_mj.sim.spec.ArenaSpec, not imported: spec imports this module (the families and the
# slot counts its checks need), and this module reads only plain fields of it.
ArenaSpec = Any

STRUCTURES = ("corridors", "pockets", "clusters", "blocks", "rooms", "slalom")
FAMILIES = ("random", *STRUCTURES, "mixed")
"""The values of ``arena.floor_plan``."""

GAP_WIDTH = (3.0, 5.0)  # m, corridor gaps and doorways: the robot (0.45 m) passes with its sensors
GAP_SPAN = 20.0  # m, corridor gaps lie within this distance of the start-target line
SEPARATION = 3.0  # m, least gap between two structures (pockets, clusters, blocks)
POCKET_WIDTH = (8.0, 14.0)  # m, inside
POCKET_DEPTH = (6.0, 12.0)  # m, inside
POCKET_TURN = math.radians(20.0)  # the opening faces the start within this angle
CLUSTER_MEMBERS = (6, 9)  # obstacles per cluster
CLUSTER_SIZE = (0.5, 1.0)  # m, cylinder radius or box half side
CLUSTER_GAP = (1.5, 3.0)  # m, between a member and the one it is placed beside; others keep the least
BLOCK_SIDE = (8.0, 20.0)  # m
SLALOM_SPACING = (8.0, 12.0)  # m between consecutive walls
SLALOM_REACH = (3.0, 6.0)  # m past the line

# Structures per family at the paper's start-target distance (80 sqrt 2 m); for rooms, the
# walls per axis (2: a grid of 3 x 3 rooms).
DEFAULT_COUNT = {"corridors": 3, "pockets": 3, "clusters": 5, "blocks": 5, "rooms": 2, "slalom": 6}
_REFERENCE_DISTANCE = math.hypot(80.0, 80.0)
# Redraws of one structure before the attempt is given up (as layout's per-obstacle redraws).
_REDRAWS = 100
# Lateral offsets (m) from the line: pockets, clusters and blocks sit on or near it.
_POCKET_OFFSET, _CLUSTER_OFFSET, _BLOCK_OFFSET = 3.0, 6.0, 12.0
_CLUSTER_SPOTS = 8  # candidate spots per cluster member
_OUTLINE_STEP = 0.25  # m between sampled outline points for the separation check


@dataclass(frozen=True)
class Opening:
    """A way through a structure: a corridor gap or a doorway (``depth`` 0), or a pocket's
    mouth (``depth`` its inner depth).

    ``(x, y)`` is the opening's centre and ``(nx, ny)`` the unit direction of passage (for a
    pocket: out of it, so the pocket's centre is ``(x, y) - depth / 2 * (nx, ny)``); metres.
    ``group`` is the structure's index in :attr:`FloorPlan.pieces`.
    """

    x: float
    y: float
    nx: float
    ny: float
    width: float
    group: int
    depth: float = 0.0


@dataclass(frozen=True)
class FloorPlan:
    """One drawn floor plan.

    ``pieces`` (N, 8) holds one obstacle per row: centre x, y; half_x, half_y (a cylinder's
    radius twice); yaw; is_cylinder, is_wall (0 or 1); group, the index of the structure it
    belongs to (a corridor wall, a pocket, a cluster, a block, a room wall line, a slalom
    wall). Metres and radians.
    """

    family: str
    pieces: np.ndarray
    openings: tuple[Opening, ...] = ()

    def groups(self) -> list[np.ndarray]:
        """The pieces of each structure, in group order."""
        ids = self.pieces[:, 7].astype(int)
        return [self.pieces[ids == g] for g in np.unique(ids)]


def structure_count(family: str, count: int, distance: float) -> int:
    """Structures of ``family`` in a plan: ``count`` if given (> 0), else :data:`DEFAULT_COUNT`
    scaled by the start-target ``distance`` (metres), at least 1."""
    if count:
        return count
    return max(1, round(DEFAULT_COUNT[family] * distance / _REFERENCE_DISTANCE))


def slot_counts(spec: ArenaSpec) -> dict[str, int]:
    """The most obstacles per pool (``box``, ``cylinder``, ``wall``) a floor plan of ``spec``
    can add, for the arena's slots and the obstacle limit; zeros for ``"random"``."""
    families = {"random": (), "mixed": STRUCTURES}.get(spec.floor_plan, (spec.floor_plan,))
    distance = math.dist(spec.start, spec.target)
    slots = {"box": 0, "cylinder": 0, "wall": 0}
    for family in families:
        n = structure_count(family, spec.floor_plan_count, distance)
        members = CLUSTER_MEMBERS[1] * n if family == "clusters" else 0
        walls = {"corridors": 3 * n, "pockets": 3 * n, "rooms": 4 * n * (n + 1), "slalom": n}.get(family, 0)
        need = {"box": members + (n if family == "blocks" else 0), "cylinder": members, "wall": walls}
        slots = {pool: max(slots[pool], need[pool]) for pool in slots}
    return slots


def pick_family(spec: ArenaSpec, random_state: np.random.RandomState) -> str:
    """The episode's family: ``spec.floor_plan``, or for ``"mixed"`` one of :data:`STRUCTURES`
    (one draw). Draws nothing otherwise."""
    if spec.floor_plan == "mixed":
        return STRUCTURES[random_state.randint(len(STRUCTURES))]
    return spec.floor_plan


def draw_floor_plan(
    family: str, spec: ArenaSpec, random_state: np.random.RandomState, keep: float
) -> FloorPlan | None:
    """Draws the structures of ``family`` (one of :data:`STRUCTURES`) for ``spec``, every piece
    ``keep`` metres (outline to point) from start and target. None if a structure could not be
    placed in :data:`_REDRAWS` draws."""
    frame = _Frame(spec, keep)
    n = structure_count(family, spec.floor_plan_count, frame.distance)
    return _DRAW[family](frame, random_state, n)


def clearance(points: np.ndarray, x, y, hx, hy, yaw, is_cyl) -> np.ndarray:
    """Distance (metres) from each of ``points`` (P, 2) to each obstacle's outline
    (N obstacles given as arrays): shape (P, N), negative inside."""
    dx = points[:, 0:1] - x[None, :]
    dy = points[:, 1:2] - y[None, :]
    c, s = np.cos(yaw), np.sin(yaw)
    qx = np.abs(c * dx + s * dy) - hx
    qy = np.abs(-s * dx + c * dy) - hy
    box = np.hypot(np.maximum(qx, 0), np.maximum(qy, 0)) + np.minimum(np.maximum(qx, qy), 0)
    cyl = np.hypot(dx, dy) - hx
    return np.where(is_cyl[None, :], cyl, box)


def piece_clearance(points: np.ndarray, pieces: np.ndarray) -> np.ndarray:
    """:func:`clearance` of ``points`` (P, 2) to the rows of a :attr:`FloorPlan.pieces` array: (P, N)."""
    return clearance(points, *pieces[:, :5].T, pieces[:, 5] > 0)


def outline_points(pieces: np.ndarray, step: float = _OUTLINE_STEP) -> np.ndarray:
    """Points (P, 2) along the outlines of ``pieces`` (rows as :attr:`FloorPlan.pieces`), at most
    ``step`` metres apart."""
    out = []
    for x, y, hx, hy, yaw, is_cyl, *_ in pieces:
        if is_cyl:
            a = np.linspace(0.0, 2 * math.pi, max(8, math.ceil(2 * math.pi * hx / step)), endpoint=False)
            out.append(np.column_stack([x + hx * np.cos(a), y + hx * np.sin(a)]))
            continue
        corners = np.array([(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy), (-hx, -hy)])
        for p, q in zip(corners[:-1], corners[1:], strict=True):
            k = max(2, math.ceil(np.hypot(*(q - p)) / step) + 1)
            local = p + np.linspace(0.0, 1.0, k)[:, None] * (q - p)
            c, s = math.cos(yaw), math.sin(yaw)
            out.append(local @ np.array([[c, s], [-s, c]]) + (x, y))
    return np.concatenate(out) if out else np.zeros((0, 2))


# -- geometry helpers ----------------------------------------------------------------


class _Frame:
    """The start-target frame and what every family needs from the spec."""

    def __init__(self, spec: ArenaSpec, keep: float) -> None:
        self.size = (float(spec.size[0]), float(spec.size[1]))
        self.start = np.array(spec.start, dtype=float)
        self.target = np.array(spec.target, dtype=float)
        self.points = np.array([self.start, self.target])
        delta = self.target - self.start
        self.distance = float(np.hypot(*delta))
        self.u = delta / self.distance
        self.v = np.array([-self.u[1], self.u[0]])
        self.keep = keep
        self.thickness = float(spec.wall_thickness)
        self.cylinder_fraction = float(spec.cylinder_fraction)

    def at(self, s: float, t: float) -> np.ndarray:
        """World point ``s`` metres along the line from the start and ``t`` to its left."""
        return self.start + s * self.u + t * self.v

    def slot(
        self, random_state: np.random.RandomState, i: int, n: int, margin: float, spread: float = 1.0
    ) -> float:
        """A uniform ``s`` in the middle ``spread`` (0..1) of the i-th of ``n`` equal stretches of
        the line between ``margin`` metres from start and target."""
        lo, hi = margin, self.distance - margin
        return float(lo + (i + 0.5 + spread * random_state.uniform(-0.5, 0.5)) * (hi - lo) / n)

    def clip(self, p0: np.ndarray, p1: np.ndarray) -> tuple[float, float] | None:
        """The parameters ``(a, b)``, 0 <= a < b <= 1, of the part of segment p0-p1 inside the
        arena (Liang-Barsky), or None."""
        a, b = 0.0, 1.0
        d = p1 - p0
        for k in range(2):
            for q, sign in ((p0[k], -1.0), (self.size[k] - p0[k], 1.0)):
                p = sign * d[k]
                if p == 0.0:
                    if q < 0:
                        return None
                    continue
                r = q / p
                if p < 0:
                    a = max(a, r)
                else:
                    b = min(b, r)
        return (a, b) if a < b else None

    def inside(self, pieces: np.ndarray, tolerance: float = 0.0) -> bool:
        """True if every piece's bounding box lies inside the arena (within ``tolerance`` m)."""
        x, y, hx, hy, yaw, is_cyl = pieces[:, :6].T
        c, s = np.abs(np.cos(yaw)), np.abs(np.sin(yaw))
        ex = np.where(is_cyl > 0, hx, hx * c + hy * s)
        ey = np.where(is_cyl > 0, hx, hx * s + hy * c)
        w, h = self.size
        return bool(
            np.all(x - ex >= -tolerance)
            and np.all(x + ex <= w + tolerance)
            and np.all(y - ey >= -tolerance)
            and np.all(y + ey <= h + tolerance)
        )

    def clear(self, pieces: np.ndarray) -> bool:
        """True if every piece keeps ``keep`` metres from start and target."""
        return bool(np.all(piece_clearance(self.points, pieces) >= self.keep))


def _wall(p0: np.ndarray, p1: np.ndarray, thickness: float, group: int) -> list[float]:
    """A wall piece whose centre line runs from p0 to p1 (metres)."""
    d = p1 - p0
    c = (p0 + p1) / 2
    return [c[0], c[1], math.hypot(*d) / 2, thickness / 2, math.atan2(d[1], d[0]) % math.pi, 0, 1, group]


def _pieces(rows: list[list[float]]) -> np.ndarray:
    return np.array(rows, dtype=float).reshape(-1, 8)


def _apart(candidate: np.ndarray, placed: np.ndarray) -> bool:
    """True if ``candidate`` keeps :data:`SEPARATION` from every ``placed`` piece (both (N, 8));
    sampled both ways, so a piece inside another counts as touching."""
    if placed.size == 0:
        return True
    there = piece_clearance(outline_points(candidate), placed)
    back = piece_clearance(outline_points(placed), candidate)
    return bool(there.min() >= SEPARATION and back.min() >= SEPARATION)


def _place_each(
    frame: _Frame, random_state: np.random.RandomState, n: int, draw
) -> tuple[np.ndarray, list[Opening]] | None:
    """Places ``n`` structures one by one: ``draw(random_state, i)`` returns the pieces of
    structure i (group i) and its openings, or None; redrawn until inside the arena, clear of
    start and target and apart from those placed. None if one cannot be placed."""
    placed, openings = _pieces([]), []
    for i in range(n):
        for _ in range(_REDRAWS):
            drawn = draw(random_state, i)
            if drawn is None:
                continue
            candidate, extra = drawn
            if (
                frame.inside(candidate, frame.thickness)
                and frame.clear(candidate)
                and _apart(candidate, placed)
            ):
                placed = np.concatenate([placed, candidate])
                openings += extra
                break
        else:
            return None
    return placed, openings


def _cut(
    frame: _Frame, p0: np.ndarray, p1: np.ndarray, gaps: list[tuple[float, float]], group: int
) -> list[list[float]]:
    """Wall pieces along p0-p1 (metres) with ``gaps``, (start, end) distances from p0, left open."""
    length = float(np.hypot(*(p1 - p0)))
    direction = (p1 - p0) / length
    rows, at = [], 0.0
    for a, b in [*sorted(gaps), (length, length)]:
        if a - at > 1e-6:
            rows.append(_wall(p0 + at * direction, p0 + a * direction, frame.thickness, group))
        at = b
    return rows


# -- families ------------------------------------------------------------------------


def _corridors(frame: _Frame, random_state: np.random.RandomState, n: int) -> FloorPlan | None:
    margin = frame.keep + frame.thickness
    if frame.distance <= 2 * margin:
        return None
    rows, openings = [], []
    far = sum(frame.size)  # longer than any line across the arena
    for i in range(n):
        s = frame.slot(random_state, i, n, margin, spread=0.5)  # walls half a stretch apart or more
        p0, p1 = frame.at(s, -far), frame.at(s, far)
        clipped = frame.clip(p0, p1)
        if clipped is None:
            return None
        t0, t1 = (-far + k * 2 * far for k in clipped)  # the wall's ends, as t
        gaps: list[tuple[float, float]] = []  # (t_low, t_high)
        for w in random_state.uniform(*GAP_WIDTH, size=random_state.randint(1, 3)):
            lo, hi = max(t0, -GAP_SPAN) + w / 2 + 1.0, min(t1, GAP_SPAN) - w / 2 - 1.0
            if lo > hi:
                return None
            centre = random_state.uniform(lo, hi)
            # A second gap overlapping the first (or within 1 m of it) is dropped.
            if all(centre + w / 2 + 1.0 < a or centre - w / 2 - 1.0 > b for a, b in gaps):
                gaps.append((centre - w / 2, centre + w / 2))
                mid = frame.at(s, centre)
                openings.append(Opening(float(mid[0]), float(mid[1]), *frame.u.tolist(), float(w), i))
        q0 = frame.at(s, t0)
        rows += _cut(frame, q0, frame.at(s, t1), [(a - t0, b - t0) for a, b in gaps], i)
    return FloorPlan("corridors", _pieces(rows), tuple(openings))


def _pocket(
    frame: _Frame, random_state: np.random.RandomState, i: int, n: int
) -> tuple[np.ndarray, list[Opening]] | None:
    """One U-shaped pocket (group i) whose mouth faces the start, and its mouth."""
    width = random_state.uniform(*POCKET_WIDTH)
    depth = random_state.uniform(*POCKET_DEPTH)
    offset = random_state.uniform(-1, 1) * _POCKET_OFFSET
    centre = frame.at(frame.slot(random_state, i, n, frame.keep), offset)
    to_start = frame.start - centre
    turn = math.atan2(to_start[1], to_start[0]) + random_state.uniform(-1, 1) * POCKET_TURN
    a = np.array([math.cos(turn), math.sin(turn)])  # out of the mouth
    b = np.array([-a[1], a[0]])
    th = frame.thickness
    side = width / 2 + th / 2  # the side walls' centre lines
    # Start and target must not lie inside the U (the clearance check alone allows a big one).
    rel = frame.points - centre
    if np.any((np.abs(rel @ a) <= depth / 2 + th) & (np.abs(rel @ b) <= side + th)):
        return None
    back = centre - a * (depth / 2 + th / 2)
    rows = [
        _wall(back - b * (side + th / 2), back + b * (side + th / 2), th, i),
        _wall(centre - a * depth / 2 + b * side, centre + a * depth / 2 + b * side, th, i),
        _wall(centre - a * depth / 2 - b * side, centre + a * depth / 2 - b * side, th, i),
    ]
    mouth = centre + a * depth / 2
    return _pieces(rows), [
        Opening(float(mouth[0]), float(mouth[1]), float(a[0]), float(a[1]), width, i, depth)
    ]


def _pockets(frame: _Frame, random_state: np.random.RandomState, n: int) -> FloorPlan | None:
    placed = _place_each(frame, random_state, n, lambda rs, i: _pocket(frame, rs, i, n))
    return None if placed is None else FloorPlan("pockets", placed[0], tuple(placed[1]))


def _cluster(
    frame: _Frame, random_state: np.random.RandomState, i: int, n: int
) -> tuple[np.ndarray, list[Opening]] | None:
    """One tight group (group i): each member beside an earlier one, CLUSTER_GAP apart from it
    and at least CLUSTER_GAP[0] from every other (bounding circles)."""
    k = random_state.randint(CLUSTER_MEMBERS[0], CLUSTER_MEMBERS[1] + 1)
    size = random_state.uniform(*CLUSTER_SIZE, size=k)
    is_cyl = random_state.uniform(size=k) < frame.cylinder_fraction
    yaw = np.where(is_cyl, 0.0, random_state.uniform(0.0, math.pi / 2, size=k))
    reach = np.where(is_cyl, size, size * math.sqrt(2))  # bounding-circle radius
    centre = frame.at(
        frame.slot(random_state, i, n, frame.keep), random_state.uniform(-1, 1) * _CLUSTER_OFFSET
    )
    xy = np.zeros((k, 2))
    xy[0] = centre
    for m in range(1, k):
        # Of a few valid spots beside earlier members, the one nearest their centroid: a
        # compact group rather than a chain.
        spots = []
        for _ in range(_REDRAWS):
            j = random_state.randint(m)
            angle = random_state.uniform(0.0, 2 * math.pi)
            gap = random_state.uniform(*CLUSTER_GAP)
            p = xy[j] + (reach[j] + reach[m] + gap) * np.array([math.cos(angle), math.sin(angle)])
            if np.all(np.hypot(*(xy[:m] - p).T) >= reach[:m] + reach[m] + CLUSTER_GAP[0]):
                spots.append(p)
                if len(spots) == _CLUSTER_SPOTS:
                    break
        if not spots:
            return None
        mean = xy[:m].mean(axis=0)
        xy[m] = min(spots, key=lambda q: float(np.hypot(*(q - mean))))
    rows = [[*xy[m], size[m], size[m], yaw[m], float(is_cyl[m]), 0, i] for m in range(k)]
    return _pieces(rows), []


def _clusters(frame: _Frame, random_state: np.random.RandomState, n: int) -> FloorPlan | None:
    placed = _place_each(frame, random_state, n, lambda rs, i: _cluster(frame, rs, i, n))
    return None if placed is None else FloorPlan("clusters", placed[0])


def _block(
    frame: _Frame, random_state: np.random.RandomState, i: int, n: int
) -> tuple[np.ndarray, list[Opening]]:
    """One big box (group i) near the line."""
    half = random_state.uniform(*BLOCK_SIDE, size=2) / 2
    yaw = random_state.uniform(0.0, math.pi / 2)
    centre = frame.at(frame.slot(random_state, i, n, frame.keep), random_state.uniform(-1, 1) * _BLOCK_OFFSET)
    return _pieces([[*centre, *half, yaw, 0, 0, i]]), []


def _blocks(frame: _Frame, random_state: np.random.RandomState, n: int) -> FloorPlan | None:
    placed = _place_each(frame, random_state, n, lambda rs, i: _block(frame, rs, i, n))
    return None if placed is None else FloorPlan("blocks", placed[0])


def _room_lines(frame: _Frame, random_state: np.random.RandomState, n: int, axis: int) -> np.ndarray | None:
    """``n`` positions (metres, sorted) of walls across ``axis`` (0: walls at fixed x), near
    equal spacing and ``keep`` + half a wall from start and target."""
    spacing = frame.size[axis] / (n + 1)
    lines = np.empty(n)
    for k in range(n):
        for _ in range(_REDRAWS):
            lines[k] = (k + 1 + random_state.uniform(-0.25, 0.25)) * spacing
            if np.all(np.abs(frame.points[:, axis] - lines[k]) >= frame.keep + frame.thickness / 2):
                break
        else:
            return None
    return lines


def _rooms(frame: _Frame, random_state: np.random.RandomState, n: int) -> FloorPlan | None:
    lines = [_room_lines(frame, random_state, n, axis) for axis in (0, 1)]
    if lines[0] is None or lines[1] is None:
        return None
    rows, openings, group = [], [], 0
    for axis in (0, 1):
        other = 1 - axis
        crossings = [0.0, *lines[other].tolist(), frame.size[other]]
        for at in lines[axis]:
            for lo, hi in zip(crossings[:-1], crossings[1:], strict=True):
                p0, p1 = np.zeros(2), np.zeros(2)
                p0[axis] = p1[axis] = at
                p0[other], p1[other] = lo, hi
                w = random_state.uniform(*GAP_WIDTH)
                room = hi - lo - frame.thickness - 2.0  # a doorway keeps 1 m from the crossing walls
                if room < w:  # too short a stretch: left open
                    w, centre = hi - lo, (hi - lo) / 2
                else:
                    centre = frame.thickness / 2 + 1.0 + w / 2 + random_state.uniform() * (room - w)
                rows += _cut(frame, p0, p1, [(centre - w / 2, centre + w / 2)], group)
                door = p0.copy()
                door[other] += centre
                normal = np.zeros(2)
                normal[axis] = 1.0
                openings.append(Opening(float(door[0]), float(door[1]), *normal.tolist(), float(w), group))
            group += 1
    return FloorPlan("rooms", _pieces(rows), tuple(openings))


def _slalom(frame: _Frame, random_state: np.random.RandomState, n: int) -> FloorPlan | None:
    spacing = random_state.uniform(*SLALOM_SPACING)
    reach = random_state.uniform(*SLALOM_REACH)
    side = 1.0 if random_state.uniform() < 0.5 else -1.0
    margin = frame.keep + frame.thickness
    room = frame.distance - 2 * margin
    if room <= 0:
        return None
    if n > 1:
        spacing = min(spacing, room / (n - 1))
        if spacing < SLALOM_SPACING[0] / 2:  # too crowded to weave through
            return None
    first = margin + random_state.uniform() * (room - (n - 1) * spacing)
    far = sum(frame.size)  # longer than any line across the arena
    rows, openings = [], []
    for i in range(n):
        s = first + i * spacing
        # side +1: from the border on the right of the line to `reach` left of it; the way
        # past is on the left, and the next wall closes that side.
        p0, p1 = frame.at(s, -side * far), frame.at(s, side * reach)
        clipped = frame.clip(p0, p1)
        if clipped is None:
            return None
        rows.append(_wall(p0 + clipped[0] * (p1 - p0), p0 + clipped[1] * (p1 - p0), frame.thickness, i))
        # The way past: from the wall's end to the border on the open side.
        q0, q1 = frame.at(s, side * reach), frame.at(s, side * far)
        gap = frame.clip(q0, q1)
        if gap is None:
            return None
        a, b = (q0 + k * (q1 - q0) for k in gap)
        mid = (a + b) / 2
        width = float(np.hypot(*(b - a)))
        openings.append(Opening(float(mid[0]), float(mid[1]), *frame.u.tolist(), width, i))
        side = -side
    return FloorPlan("slalom", _pieces(rows), tuple(openings))


_DRAW = {
    "corridors": _corridors,
    "pockets": _pockets,
    "clusters": _clusters,
    "blocks": _blocks,
    "rooms": _rooms,
    "slalom": _slalom,
}
