"""Tests for nirl_mj.sim.floorplans: structured floor plans are seeded, solvable and have their shape."""

from __future__ import annotations

import hashlib
import math

import mujoco
import numpy as np
import pytest
from dm_control import mjcf

from nirl_mj.sim import floorplans
from nirl_mj.sim.arena import NavigationArena
from nirl_mj.sim.floorplans import STRUCTURES, draw_floor_plan, piece_clearance, slot_counts, structure_count
from nirl_mj.sim.layout import (
    ArenaGenerationError,
    Layout,
    Obstacle,
    generate_layout,
    occupancy_grid,
    path_exists,
)
from nirl_mj.sim.spec import ArenaSpec, SpecError, from_dict, load_task

ROBOT_RADIUS = 0.225
SEEDS = range(6)
ALONE = {family: ArenaSpec(floor_plan=family, static_obstacles=0) for family in STRUCTURES}
KEEP = ArenaSpec().clear_radius + ROBOT_RADIUS


def _plan(family: str, seed: int, spec: ArenaSpec | None = None) -> floorplans.FloorPlan:
    spec = spec or ALONE[family]
    plan = draw_floor_plan(family, spec, np.random.RandomState(seed), spec.clear_radius + ROBOT_RADIUS)
    assert plan is not None, f"{family} seed {seed}: could not be placed"
    return plan


def _blocked(pieces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(P,) True where a point lies inside (or on) one of the pieces."""
    return np.any(piece_clearance(points, pieces) <= 1e-9, axis=1)


def _ray_hit(pieces: np.ndarray, origin: np.ndarray, direction: np.ndarray, length: float) -> float:
    """Distance (m) along the ray to the first piece within ``length``, inf if none (0.02 m steps)."""
    steps = np.arange(0.0, length, 0.02)
    hit = _blocked(pieces, origin + steps[:, None] * direction)
    return float(steps[np.argmax(hit)]) if hit.any() else math.inf


def _door(o: floorplans.Opening) -> Obstacle:
    """A wall piece closing opening ``o`` (0.5 m longer on each side)."""
    yaw = math.atan2(o.ny, o.nx) + math.pi / 2
    return Obstacle("box", o.x, o.y, (o.width / 2 + 0.5, 0.25), yaw, True)


def _layout_arrays(layout: Layout):
    obs = layout.obstacles
    return (
        np.array([o.x for o in obs]),
        np.array([o.y for o in obs]),
        np.array([o.size[0] for o in obs]),
        np.array([o.size[-1] for o in obs]),
        np.array([o.yaw for o in obs]),
        np.array([o.shape == "cylinder" for o in obs]),
    )


# -- every family: seeded, solvable, clear of start and target, inside, within its slots -----------


@pytest.mark.parametrize("family", [*STRUCTURES, "mixed"])
@pytest.mark.parametrize("static_obstacles", [0, 5])
def test_generation_is_seeded_solvable_and_keeps_start_and_target_clear(family, static_obstacles):
    spec = ArenaSpec(floor_plan=family, static_obstacles=static_obstacles)
    slots = slot_counts(spec)
    for seed in SEEDS:
        layout = generate_layout(spec, np.random.RandomState(seed), ROBOT_RADIUS)
        assert layout == generate_layout(spec, np.random.RandomState(seed), ROBOT_RADIUS)
        assert layout != generate_layout(spec, np.random.RandomState(seed + 100), ROBOT_RADIUS)
        assert layout.floor_plan == family if family != "mixed" else layout.floor_plan in STRUCTURES
        grid = occupancy_grid(layout, spec.grid_resolution, ROBOT_RADIUS + spec.path_margin)
        assert path_exists(grid, layout.start, layout.target)
        d = floorplans.clearance(np.array([layout.start, layout.target]), *_layout_arrays(layout))
        assert d.min() >= KEEP - 1e-9
        # Every obstacle of the plan lies inside the arena (walls may touch the border by half a thickness).
        for o in layout.obstacles:
            ex, ey = o.half_extents
            assert -spec.wall_thickness <= o.x - ex and o.x + ex <= 100.0 + spec.wall_thickness
            assert -spec.wall_thickness <= o.y - ey and o.y + ey <= 100.0 + spec.wall_thickness
        pools = {"box": 0, "cylinder": 0, "wall": 0}
        for o in layout.obstacles:
            pools["wall" if o.is_wall else o.shape] += 1
        assert pools["box"] <= slots["box"] + static_obstacles
        assert pools["cylinder"] <= slots["cylinder"] + static_obstacles
        assert pools["wall"] <= slots["wall"]


def test_mixed_draws_every_family():
    spec = ArenaSpec(floor_plan="mixed", static_obstacles=5)
    drawn = {generate_layout(spec, np.random.RandomState(seed)).floor_plan for seed in range(40)}
    assert drawn == set(STRUCTURES)


def test_families_fit_small_arenas():
    for family in STRUCTURES:
        spec = ArenaSpec(
            size=(24.0, 24.0),
            start=(4.0, 4.0),
            target=(20.0, 20.0),
            clear_radius=3.0,
            floor_plan=family,
            static_obstacles=3,
        )
        for seed in range(3):
            layout = generate_layout(spec, np.random.RandomState(seed))
            assert layout.floor_plan == family and len(layout.obstacles) > 3


def test_random_is_unchanged():
    """floor_plan = "random" draws nothing new: the layouts of the code before floor plans (17085ea)."""
    h = hashlib.sha256()
    for spec in (
        ArenaSpec(),
        ArenaSpec(static_obstacles=5, interior_walls=3, moving_obstacles=2, start_yaw="random"),
    ):
        for seed in range(5):
            lay = generate_layout(spec, np.random.RandomState(seed))
            h.update(
                repr((lay.size, lay.start, lay.start_yaw, lay.target, lay.obstacles, lay.moving)).encode()
            )
    assert h.hexdigest() == "1081df7411e2fa8c3cc0ffed11cd2c0eeb558944c13aa2052f9e124f856d7846"
    assert slot_counts(ArenaSpec()) == {"box": 0, "cylinder": 0, "wall": 0}


# -- each family's shape -------------------------------------------------------------------------


def test_corridors_cross_the_line_from_border_to_border_with_gaps_the_robot_fits():
    start, target = np.array([10.0, 10.0]), np.array([90.0, 90.0])
    u = (target - start) / np.linalg.norm(target - start)
    for seed in SEEDS:
        plan = _plan("corridors", seed)
        walls = plan.groups()
        assert len(walls) == structure_count("corridors", 0, float(np.linalg.norm(target - start))) == 3
        for g, wall in enumerate(walls):
            assert np.all(wall[:, 6] == 1)  # wall flag
            # Perpendicular to the start-target line.
            assert np.allclose(np.abs(np.cos(wall[:, 4]) * u[0] + np.sin(wall[:, 4]) * u[1]), 0, atol=1e-9)
            gaps = [o for o in plan.openings if o.group == g]
            assert 1 <= len(gaps) <= 2
            assert all(o.width >= 3.0 > 2 * ROBOT_RADIUS for o in gaps)
            # Along the wall's line inside the arena, every point is wall except in the gaps.
            d = np.array([-u[1], u[0]])
            taus = np.arange(-150.0, 150.0, 0.1)
            line = wall[0, :2] + taus[:, None] * d
            inside = np.all((line > 0.3) & (line < 99.7), axis=1)
            in_gap = np.zeros(taus.size, dtype=bool)
            for o in gaps:
                off = np.hypot(*(line - (o.x, o.y)).T)
                in_gap |= off < o.width / 2 + 0.05
                # The gap is open across its whole width.
                assert not _blocked(wall, line[off < o.width / 2 - 0.05]).any()
            assert _blocked(wall, line[inside & ~in_gap]).all()
            # The start-target segment crosses the wall's line between them.
            s = float((wall[0, :2] - start) @ u)
            assert KEEP < s < np.linalg.norm(target - start) - KEEP


def test_pockets_open_towards_the_start_and_are_closed_on_three_sides():
    start = np.array([10.0, 10.0])
    for seed in SEEDS:
        plan = _plan("pockets", seed)
        assert len(plan.groups()) == len(plan.openings) == 3
        for pocket, mouth in zip(plan.groups(), plan.openings, strict=True):
            assert len(pocket) == 3 and np.all(pocket[:, 6] == 1)
            a = np.array([mouth.nx, mouth.ny])
            centre = np.array([mouth.x, mouth.y]) - a * mouth.depth / 2
            to_start = (start - centre) / np.linalg.norm(start - centre)
            # The opening faces the start: within 90 degrees (by construction within 20).
            assert a @ to_start > math.cos(math.radians(20.0)) - 1e-9
            # On or near the start-target line.
            off = centre - start
            assert abs(off[1] - off[0]) / math.sqrt(2) <= 3.0 + 1e-9
            b = np.array([-a[1], a[0]])
            reach = max(mouth.width, mouth.depth) + 1.0
            assert _ray_hit(pocket, centre, -a, reach) == pytest.approx(mouth.depth / 2, abs=0.03)
            assert _ray_hit(pocket, centre, b, reach) == pytest.approx(mouth.width / 2, abs=0.03)
            assert _ray_hit(pocket, centre, -b, reach) == pytest.approx(mouth.width / 2, abs=0.03)
            assert _ray_hit(pocket, centre, a, reach) == math.inf  # open towards the start
            assert 8.0 <= mouth.width <= 14.0 and 6.0 <= mouth.depth <= 12.0


def test_clusters_are_tight_groups_with_narrow_passable_gaps():
    for seed in SEEDS:
        plan = _plan(
            "clusters", seed, ArenaSpec(floor_plan="clusters", static_obstacles=0, cylinder_fraction=0.5)
        )
        groups = plan.groups()
        assert len(groups) == 5
        for members in groups:
            assert 6 <= len(members) <= 9 and np.all(members[:, 6] == 0)
            reach = np.where(members[:, 5] > 0, members[:, 2], np.hypot(members[:, 2], members[:, 3]))
            dist = np.hypot(*(members[:, None, :2] - members[None, :, :2]).transpose(2, 0, 1))
            gap = dist - reach[:, None] - reach[None, :]
            np.fill_diagonal(gap, np.inf)
            assert gap.min() >= 1.5 - 1e-9  # the robot (0.45 m) fits between any two
            assert np.all(gap.min(axis=1) <= 3.0 + 1e-9)  # every member has a close neighbour
        # Clusters keep 3 m from each other.
        for i, a in enumerate(groups):
            for b in groups[i + 1 :]:
                assert piece_clearance(floorplans.outline_points(a), b).min() >= 3.0 - 1e-9


def test_blocks_are_big_boxes_apart():
    for seed in SEEDS:
        plan = _plan("blocks", seed)
        blocks = plan.groups()
        assert len(blocks) == 5
        for block in blocks:
            assert len(block) == 1 and block[0, 5] == 0 and block[0, 6] == 0
            assert np.all((2 * block[0, 2:4] >= 8.0) & (2 * block[0, 2:4] <= 20.0))
        for i, a in enumerate(blocks):
            for b in blocks[i + 1 :]:
                assert piece_clearance(floorplans.outline_points(a), b).min() >= 3.0 - 1e-9


def test_rooms_partition_the_arena_and_every_room_has_a_doorway_to_its_neighbours():
    spec = ALONE["rooms"]
    for seed in SEEDS:
        layout = generate_layout(spec, np.random.RandomState(seed), ROBOT_RADIUS)
        plan = _plan("rooms", seed)
        lines = plan.groups()
        assert len(lines) == 4  # 2 walls per axis: 3 x 3 rooms
        xs, ys = [], []
        for g, line in enumerate(lines):
            vertical = np.allclose(np.cos(line[:, 4]), 0, atol=1e-9)
            (xs if vertical else ys).append(line[0, 0] if vertical else line[0, 1])
            doors = [o for o in plan.openings if o.group == g]
            assert len(doors) == 3 and all(o.width >= 3.0 for o in doors)
            assert not _blocked(line, np.array([(o.x, o.y) for o in doors])).any()
        assert len(xs) == len(ys) == 2
        # Every room is reachable from the start, through doorways the robot fits.
        grid = occupancy_grid(layout, spec.grid_resolution, ROBOT_RADIUS + spec.path_margin)
        cx = np.diff([0.0, *sorted(xs), 100.0]) / 2 + np.array([0.0, *sorted(xs)])
        cy = np.diff([0.0, *sorted(ys), 100.0]) / 2 + np.array([0.0, *sorted(ys)])
        for x in cx:
            for y in cy:
                assert path_exists(grid, layout.start, (float(x), float(y)))
        # Closing the doorways splits the arena: the walls do partition it.
        doors = tuple(_door(o) for o in plan.openings)
        closed = Layout(layout.size, layout.start, 0.0, layout.target, layout.obstacles + doors)
        grid = occupancy_grid(closed, spec.grid_resolution, ROBOT_RADIUS + spec.path_margin)
        assert not path_exists(grid, layout.start, layout.target)


def test_slalom_walls_alternate_sides_and_force_a_zig_zag():
    start, target = np.array([10.0, 10.0]), np.array([90.0, 90.0])
    u = (target - start) / np.linalg.norm(target - start)
    v = np.array([-u[1], u[0]])
    for seed in SEEDS:
        plan = _plan("slalom", seed)
        walls = plan.groups()
        assert len(walls) == len(plan.openings) == 6
        sides = []
        for wall, way in zip(walls, plan.openings, strict=True):
            ((x, y, hx, _, yaw, *_),) = wall
            d = np.array([math.cos(yaw), math.sin(yaw)])
            assert abs(d @ u) < 1e-9  # across the line
            ends = np.array([(x, y) + hx * d, (x, y) - hx * d])
            t = (ends - start) @ v
            assert t.min() < 0 < t.max()  # crosses the line
            # One end on the border, the other 3-6 m past the line.
            on_border = np.any((np.abs(ends) < 1e-6) | (np.abs(ends - 100.0) < 1e-6), axis=1)
            assert on_border.sum() == 1
            assert 3.0 - 1e-9 <= abs(t[~on_border][0]) <= 6.0 + 1e-9
            side = np.sign((np.array([way.x, way.y]) - start) @ v)
            assert side == np.sign(t[~on_border][0])  # the way past is beyond the free end
            sides.append(side)
        assert all(a == -b for a, b in zip(sides[:-1], sides[1:], strict=True))
        spacing = np.diff(sorted(((w[0, :2] - start) @ u) for w in walls))
        assert np.all((spacing >= 8.0 - 1e-9) & (spacing <= 12.0 + 1e-9))


# -- spec keys, task file, arena slots -----------------------------------------------------------


def test_spec_keys_are_validated_and_left_out_of_records_at_their_defaults():
    assert "floor_plan" not in from_dict({}).to_dict()["arena"]
    assert "floor_plan_count" not in from_dict({}).to_dict()["arena"]
    task = from_dict({"arena": {"floor_plan": "pockets", "floor_plan_count": 2}})
    assert task.to_dict()["arena"]["floor_plan"] == "pockets"
    assert from_dict(task.to_dict()) == task
    with pytest.raises(SpecError, match="floor_plan = 'maze': accepted: random, corridors"):
        from_dict({"arena": {"floor_plan": "maze"}})
    with pytest.raises(SpecError, match="floor_plan_count = -1: must be >= 0"):
        from_dict({"arena": {"floor_plan_count": -1}})
    with pytest.raises(SpecError, match="at most 1000"):
        from_dict({"arena": {"floor_plan": "rooms", "floor_plan_count": 20}})


def test_counts_and_slots():
    assert structure_count("pockets", 0, math.hypot(80, 80)) == 3
    assert structure_count("pockets", 0, 10.0) == 1
    assert structure_count("pockets", 7, 10.0) == 7
    assert slot_counts(ALONE["rooms"]) == {"box": 0, "cylinder": 0, "wall": 24}
    mixed = slot_counts(ArenaSpec(floor_plan="mixed"))
    assert mixed == {"box": 45, "cylinder": 45, "wall": 24}


def test_structured_task_file_and_an_impossible_plan():
    task = load_task("structured")
    assert task.arena.floor_plan == "mixed" and task.arena.static_obstacles == 5 and task.description
    spec = ArenaSpec(floor_plan="blocks", floor_plan_count=60, static_obstacles=0, max_tries=2)
    with pytest.raises(ArenaGenerationError, match="'blocks' floor plan.*floor_plan_count"):
        generate_layout(spec, np.random.RandomState(0))


def test_arena_has_slots_for_every_family():
    spec = ArenaSpec(floor_plan="mixed", static_obstacles=5)
    arena = NavigationArena(spec)
    assert arena.slot_counts == {"box": 50, "cylinder": 50, "wall": 24, "moving": 0}
    physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
    for seed in range(12):  # apply_layout raises if a layout has more pieces than slots
        layout = generate_layout(spec, np.random.RandomState(seed))
        arena.apply_layout(physics, layout)
        walls = [o for o in layout.obstacles if o.is_wall]
        if walls:  # the first wall piece stands where the layout puts it
            w = walls[0]
            geom = mujoco.mj_name2id(physics.model.ptr, mujoco.mjtObj.mjOBJ_GEOM, "wall_000")
            assert np.allclose(physics.data.geom_xpos[geom, :2], (w.x, w.y))
            assert np.allclose(physics.model.geom_size[geom, :2], w.size)
