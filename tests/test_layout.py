"""Tests for nirl_mj.sim.layout: generation, solvability, occupancy grid, kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nirl_mj.sim.layout import (
    ArenaGenerationError,
    Layout,
    MovingObstacle,
    Obstacle,
    advance,
    advance_in_place,
    generate_layout,
    occupancy_grid,
    path_exists,
    time_to_wall,
)
from nirl_mj.sim.spec import ArenaSpec, ObstacleSpec

ROBOT_RADIUS = 0.225
BUSY = ArenaSpec(static_obstacles=40, interior_walls=5, moving_obstacles=10)


def _corners(ob: Obstacle) -> np.ndarray:
    """Box corners (4, 2), counter-clockwise."""
    hx, hy = ob.size
    c, s = math.cos(ob.yaw), math.sin(ob.yaw)
    local = np.array([(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)])
    return local @ np.array([[c, s], [-s, c]]) + (ob.x, ob.y)


def _outline_distance(ob: Obstacle, p: tuple[float, float]) -> float:
    """Distance from point p to the obstacle (0 inside), via corner geometry,
    independently of the module's box-frame formula."""
    p = np.asarray(p, dtype=float)
    if ob.shape == "cylinder":
        return max(0.0, float(np.hypot(*(p - (ob.x, ob.y)))) - ob.size[0])
    corners = _corners(ob)
    edges = np.roll(corners, -1, axis=0) - corners
    rel = p - corners
    cross = edges[:, 0] * rel[:, 1] - edges[:, 1] * rel[:, 0]
    if np.all(cross >= 0):
        return 0.0
    t = np.clip(np.sum(rel * edges, axis=1) / np.sum(edges * edges, axis=1), 0, 1)
    return float(np.min(np.hypot(*(rel - t[:, None] * edges).T)))


def test_same_seed_same_layout_other_seed_other_layout():
    a = generate_layout(BUSY, np.random.RandomState(7))
    b = generate_layout(BUSY, np.random.RandomState(7))
    c = generate_layout(BUSY, np.random.RandomState(8))
    assert a == b
    assert a != c
    assert a.obstacles != c.obstacles and a.moving != c.moving


def test_counts_and_kinds():
    spec = ArenaSpec(
        static_obstacles=30,
        interior_walls=4,
        moving_obstacles=6,
        obstacles=(
            ObstacleSpec("cylinder", (30.0, 60.0), (2.0,)),
            ObstacleSpec("wall", (60.0, 30.0), (5.0, 0.2)),
        ),
    )
    layout = generate_layout(spec, np.random.RandomState(0))
    assert len(layout.obstacles) == 2 + 30 + 4
    assert len(layout.moving) == 6
    # Explicit first, as given.
    assert layout.obstacles[0] == Obstacle("cylinder", 30.0, 60.0, (2.0,), 0.0, False)
    assert layout.obstacles[1] == Obstacle("box", 60.0, 30.0, (5.0, 0.2), 0.0, True)
    walls = layout.obstacles[32:]
    assert all(w.is_wall and w.shape == "box" for w in walls)
    assert all(w.size[1] == pytest.approx(spec.wall_thickness / 2) for w in walls)
    assert all(5.0 <= 2 * w.size[0] <= 20.0 for w in walls)
    random_obs = layout.obstacles[2:32]
    assert not any(o.is_wall for o in random_obs)
    assert {o.shape for o in random_obs} == {"box", "cylinder"}
    for o in random_obs:
        assert all(1.0 <= s <= 4.0 for s in o.size)
    for m in layout.moving:
        assert 0.5 <= m.radius <= 1.5
        assert 0.2 <= math.hypot(m.vx, m.vy) <= 1.0


def test_cylinder_fraction_extremes():
    boxes = generate_layout(ArenaSpec(cylinder_fraction=0.0), np.random.RandomState(1))
    cylinders = generate_layout(ArenaSpec(cylinder_fraction=1.0), np.random.RandomState(1))
    assert {o.shape for o in boxes.obstacles} == {"box"}
    assert {o.shape for o in cylinders.obstacles} == {"cylinder"}


@pytest.mark.parametrize("seed", range(10))
def test_clearance_and_inside(seed):
    spec = BUSY
    layout = generate_layout(spec, np.random.RandomState(seed), robot_radius=ROBOT_RADIUS)
    keep = spec.clear_radius + ROBOT_RADIUS
    width, height = spec.size
    for ob in layout.obstacles:
        for point in (layout.start, layout.target):
            assert _outline_distance(ob, point) >= keep - 1e-9
        pts = np.array([(ob.x, ob.y)]) if ob.shape == "cylinder" else _corners(ob)
        r = ob.size[0] if ob.shape == "cylinder" else 0.0
        assert np.all(pts - r >= -1e-9) and np.all(pts[:, 0] + r <= width + 1e-9)
        assert np.all(pts[:, 1] + r <= height + 1e-9)
    for m in layout.moving:
        assert m.radius <= m.x <= width - m.radius and m.radius <= m.y <= height - m.radius
        for point in (layout.start, layout.target):
            assert math.hypot(m.x - point[0], m.y - point[1]) - m.radius >= keep - 1e-9


def test_generated_layout_is_solvable():
    spec = ArenaSpec(static_obstacles=120, obstacle_size=(1.0, 5.0), interior_walls=10)
    layout = generate_layout(spec, np.random.RandomState(3), robot_radius=ROBOT_RADIUS)
    grid = occupancy_grid(layout, spec.grid_resolution, ROBOT_RADIUS + spec.path_margin)
    assert path_exists(grid, layout.start, layout.target)


def test_start_yaw_modes():
    spec = ArenaSpec(start=(10.0, 10.0), target=(10.0, 90.0))
    assert generate_layout(spec, np.random.RandomState(0)).start_yaw == pytest.approx(math.pi / 2)
    fixed = ArenaSpec(start_yaw=0.3)
    assert generate_layout(fixed, np.random.RandomState(0)).start_yaw == 0.3
    rnd = ArenaSpec(start_yaw="random")
    yaws = {generate_layout(rnd, np.random.RandomState(s)).start_yaw for s in range(5)}
    assert len(yaws) == 5 and all(-math.pi <= y <= math.pi for y in yaws)


def test_explicit_wall_across_the_arena_raises():
    wall = ObstacleSpec("wall", position=(50.0, 50.0), size=(50.0, 0.25), yaw=0.0)
    spec = ArenaSpec(static_obstacles=5, obstacles=(wall,))
    with pytest.raises(ArenaGenerationError, match="explicit obstacles .* alone block") as info:
        generate_layout(spec, np.random.RandomState(0))
    assert "arena.obstacles" in str(info.value)
    assert isinstance(info.value, ValueError)


def test_explicit_obstacle_on_the_start_raises():
    spec = ArenaSpec(obstacles=(ObstacleSpec("box", position=(10.0, 10.0), size=(1.0, 1.0)),))
    with pytest.raises(ArenaGenerationError, match="cover the start"):
        generate_layout(spec, np.random.RandomState(0))


def test_too_many_obstacles_raise_with_counts_tries_and_advice():
    spec = ArenaSpec(static_obstacles=2000, max_tries=2)
    with pytest.raises(ArenaGenerationError) as info:
        generate_layout(spec, np.random.RandomState(0))
    msg = str(info.value)
    assert "2000 static obstacles" in msg
    assert "2 tries" in msg
    assert "reduce arena.static_obstacles or arena.obstacle_size" in msg


def test_obstacles_bigger_than_the_arena_raise():
    spec = ArenaSpec(
        size=(10.0, 10.0), start=(1.0, 1.0), target=(9.0, 9.0), obstacle_size=(6.0, 7.0), max_tries=3
    )
    with pytest.raises(ArenaGenerationError, match="could not place"):
        generate_layout(spec, np.random.RandomState(0))


def test_occupancy_grid_single_box():
    box = Obstacle("box", 5.0, 5.0, (1.0, 0.5), 0.0, False)
    layout = Layout((10.0, 10.0), (1.0, 1.0), 0.0, (9.0, 9.0), (box,))
    grid = occupancy_grid(layout, 0.5, 0.0)
    assert grid.occupied.shape == (20, 20)
    expected = np.zeros((20, 20), dtype=bool)
    # Centres x in [4, 6] -> 4.25..5.75 (columns 8..11); y in [4.5, 5.5] -> 4.75, 5.25 (rows 9, 10).
    expected[9:11, 8:12] = True
    np.testing.assert_array_equal(grid.occupied, expected)

    # Inflated by 0.3 m: rows 8..11 (y centres 4.25..5.75), columns 7..12, minus the
    # four corner cells whose centres are farther than 0.3 m from the box corners.
    grid = occupancy_grid(layout, 0.5, 0.3)
    inner = grid.occupied[1:-1, 1:-1]  # the outer ring is the inflated border wall
    assert grid.occupied[0].all() and grid.occupied[:, 0].all() and not grid.occupied[1, 1:-1].any()
    expected = np.zeros((20, 20), dtype=bool)
    expected[8:12, 7:13] = True
    for i, j in ((8, 7), (8, 12), (11, 7), (11, 12)):
        expected[i, j] = False
    np.testing.assert_array_equal(inner, expected[1:-1, 1:-1])


def test_occupancy_grid_rotated_box_and_cylinder():
    a = Layout(
        (10.0, 10.0), (1.0, 1.0), 0.0, (9.0, 9.0), (Obstacle("box", 5.0, 5.0, (2.0, 0.5), math.pi / 2),)
    )
    b = Layout((10.0, 10.0), (1.0, 1.0), 0.0, (9.0, 9.0), (Obstacle("box", 5.0, 5.0, (0.5, 2.0), 0.0),))
    np.testing.assert_array_equal(
        occupancy_grid(a, 0.25, 0.2).occupied, occupancy_grid(b, 0.25, 0.2).occupied
    )
    cyl = Layout((10.0, 10.0), (1.0, 1.0), 0.0, (9.0, 9.0), (Obstacle("cylinder", 5.0, 5.0, (1.0,)),))
    grid = occupancy_grid(cyl, 0.1, 0.5)
    i, j = np.nonzero(grid.occupied[10:-10, 10:-10])
    x, y = grid.center_of(i + 10, j + 10)
    assert np.all(np.hypot(x - 5.0, y - 5.0) <= 1.5 + 1e-9)
    assert grid.occupied[grid.cell_of(5.0, 6.45)] and not grid.occupied[grid.cell_of(5.0, 6.55)]


def test_cell_helpers_round_trip():
    layout = Layout((10.0, 6.0), (1.0, 1.0), 0.0, (9.0, 5.0))
    grid = occupancy_grid(layout, 0.25, 0.0)
    assert grid.shape == (24, 40)
    assert grid.cell_of(0.3, 5.9) == (23, 1)
    assert grid.center_of(23, 1) == (0.375, 5.875)
    assert grid.cell_of(-5.0, 100.0) == (23, 0)  # clipped
    i, j = grid.cell_of(np.array([0.1, 9.9]), np.array([0.1, 5.9]))
    np.testing.assert_array_equal(i, [0, 23])
    np.testing.assert_array_equal(j, [0, 39])


def test_path_exists_through_a_gap():
    inflate = ROBOT_RADIUS + 0.1

    def wall_with_gap(gap: float) -> Layout:
        # Two wall pieces across x = 5 leaving a gap of ``gap`` metres around y = 5.
        half = (5.0 - gap / 2) / 2
        lower = Obstacle("box", 5.0, half, (0.1, half), 0.0, True)
        upper = Obstacle("box", 5.0, 10.0 - half, (0.1, half), 0.0, True)
        return Layout((10.0, 10.0), (2.0, 5.0), 0.0, (8.0, 5.0), (lower, upper))

    assert not path_exists(
        occupancy_grid(wall_with_gap(2 * inflate - 0.1), 0.1, inflate), (2.0, 5.0), (8.0, 5.0)
    )
    assert path_exists(occupancy_grid(wall_with_gap(2 * inflate + 0.3), 0.1, inflate), (2.0, 5.0), (8.0, 5.0))


def test_moving_obstacles_bounce_off_the_walls():
    pos = np.array([[99.0, 50.0], [50.0, 0.6], [20.0, 30.0]])
    vel = np.array([[1.0, 0.0], [0.3, -1.0], [0.0, 0.0]])
    radii = np.array([0.8, 0.5, 1.0])
    p, v = advance(pos, vel, radii, 0.5, (100.0, 100.0))
    # First: rim would reach 100.3 -> reflected to 99.2 - 0.3 = 98.9 with vx flipped.
    np.testing.assert_allclose(p[0], [98.9, 50.0])
    np.testing.assert_allclose(v[0], [-1.0, 0.0])
    # Second: y 0.6 - 0.5 = 0.1 < 0.5 -> 0.9, vy flipped, vx unchanged.
    np.testing.assert_allclose(p[1], [50.15, 0.9])
    np.testing.assert_allclose(v[1], [0.3, 1.0])
    np.testing.assert_allclose(p[2], pos[2])
    # Inputs untouched.
    assert pos[0, 0] == 99.0 and vel[0, 0] == 1.0


def test_moving_obstacles_stay_inside_and_keep_speed():
    rs = np.random.RandomState(0)
    n = 20
    radii = rs.uniform(0.5, 1.5, n)
    pos = rs.uniform(2.0, 8.0, (n, 2))
    vel = rs.uniform(-3, 3, (n, 2))
    speed = np.hypot(*vel.T)
    low, high = radii[:, None], np.array([[10.0, 10.0]]) - radii[:, None]
    flips = 0
    for _ in range(3000):
        before = np.sign(vel)
        advance_in_place(pos, vel, low, high, 0.01)
        flips += int(np.sum(np.sign(vel) != before))
        assert np.all(pos >= low - 1e-12) and np.all(pos <= high + 1e-12)
    assert flips > 50
    np.testing.assert_allclose(np.hypot(*vel.T), speed)


def test_time_to_wall():
    pos = np.array([[5.0, 5.0], [2.0, 8.0]])
    vel = np.array([[1.0, 0.0], [0.0, 0.5]])
    low = np.array([[1.0], [1.0]])
    high = np.array([[9.0, 9.0]]) - low
    # Second one already touches the top bound (y = 8 = 9 - 1).
    assert time_to_wall(pos, vel, low, high) == pytest.approx(0.0)
    pos[1, 1] = 6.0
    # First: (8 - 5) / 1 = 3 s; second: (8 - 6) / 0.5 = 4 s.
    assert time_to_wall(pos, vel, low, high) == pytest.approx(3.0)
    assert time_to_wall(pos, np.zeros_like(vel), low, high) == math.inf


def test_generated_moving_obstacles_match_dataclass():
    layout = generate_layout(ArenaSpec(moving_obstacles=3), np.random.RandomState(2))
    assert all(isinstance(m, MovingObstacle) for m in layout.moving)
