"""Tests for nirl_mj.sim.arena: compiling once, applying layouts, rays, contacts, masks."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
from dm_control import composer, mjcf

from nirl_mj.sim.arena import PARK_Z, NavigationArena
from nirl_mj.sim.layout import Layout, MovingObstacle, Obstacle, advance, generate_layout
from nirl_mj.sim.spec import ArenaSpec, ObstacleSpec

SPEC = ArenaSpec(
    static_obstacles=4,
    interior_walls=2,
    moving_obstacles=3,
    obstacles=(
        ObstacleSpec("wall", (50.0, 20.0), (5.0, 0.25), 0.0),
        ObstacleSpec("box", (20.0, 50.0), (1.0, 1.0)),
    ),
)
WORLD_ONLY = np.array([1, 0, 0, 0, 0, 0], dtype=np.uint8)


def _physics(spec: ArenaSpec = SPEC) -> tuple[NavigationArena, mjcf.Physics]:
    arena = NavigationArena(spec)
    return arena, mjcf.Physics.from_mjcf_model(arena.mjcf_model)


def _layout(obstacles=(), moving=(), size=(100.0, 100.0)) -> Layout:
    return Layout(size, (10.0, 10.0), 0.0, (90.0, 90.0), tuple(obstacles), tuple(moving))


def _ray(physics, pnt, vec, group=None) -> tuple[float, int]:
    geomid = np.zeros(1, dtype=np.int32)
    dist = mujoco.mj_ray(
        physics.model.ptr,
        physics.data.ptr,
        np.asarray(pnt, float),
        np.asarray(vec, float),
        group,
        1,
        -1,
        geomid,
    )
    return dist, int(geomid[0])


def _multiray(physics, pnt, vec) -> tuple[float, int]:
    geomid = np.zeros(1, dtype=np.int32)
    dist = np.zeros(1)
    m, d = physics.model.ptr, physics.data.ptr
    mujoco.mj_multiRay(
        m, d, np.asarray(pnt, float), np.asarray(vec, float), WORLD_ONLY, 1, -1, geomid, dist, None, 1, 50.0
    )
    return float(dist[0]), int(geomid[0])


def _name(physics, geom_id: int) -> str:
    return mujoco.mj_id2name(physics.model.ptr, mujoco.mjtObj.mjOBJ_GEOM, geom_id)


def test_compiles_without_composer_and_has_the_pieces():
    arena, physics = _physics()
    m = physics.model.ptr
    ground = physics.bind(arena.ground_geom)
    assert ground.element_id == mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "ground")
    assert ground.contype == 0 and ground.conaffinity == 0 and ground.group == 0
    assert m.geom_type[ground.element_id] == mujoco.mjtGeom.mjGEOM_PLANE
    assert arena.slot_counts == {"box": 5, "cylinder": 4, "wall": 3, "moving": 3}
    assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "overview") >= 0
    assert m.nmocap == 3
    assert m.vis.global_.offwidth == 1280 and m.vis.global_.offheight == 960
    assert m.vis.map.znear == pytest.approx(0.001)
    for name in ("wall_south", "wall_north", "wall_west", "wall_east"):
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
        assert m.geom_contype[g] == 1 and m.geom_conaffinity[g] == 2 and m.geom_group[g] == 0
        assert m.geom_size[g, 2] == pytest.approx(SPEC.wall_height / 2)


def test_compiles_in_a_composer_environment():
    arena = NavigationArena(SPEC)
    env = composer.Environment(composer.NullTask(arena))
    env.reset()
    arena.apply_layout(env.physics, generate_layout(SPEC, np.random.RandomState(0)))
    assert arena.layout is not None


def test_border_walls_inner_faces_at_zero_and_size():
    _, physics = _physics(
        ArenaSpec(size=(60.0, 40.0), start=(5.0, 5.0), target=(55.0, 35.0), static_obstacles=0)
    )
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    z = 0.5
    assert _ray(physics, (30.0, 20.0, z), (1, 0, 0))[0] == pytest.approx(30.0)
    assert _ray(physics, (30.0, 20.0, z), (-1, 0, 0))[0] == pytest.approx(30.0)
    assert _ray(physics, (30.0, 20.0, z), (0, 1, 0))[0] == pytest.approx(20.0)
    assert _ray(physics, (30.0, 20.0, z), (0, -1, 0))[0] == pytest.approx(20.0)


def test_rays_hit_resized_obstacles_for_two_layouts_in_a_row():
    arena, physics = _physics()
    z = 0.3
    origin = (50.0, 50.0, z)
    # Layout 1: box centred 10 m east of the origin, half-length 2 along x, yawed by 30 deg;
    # cylinder radius 1.5 centred 8 m north.
    yaw = math.radians(30)
    box1 = Obstacle("box", 60.0, 50.0, (2.0, 3.0), yaw)
    cyl1 = Obstacle("cylinder", 50.0, 58.0, (1.5,))
    arena.apply_layout(physics, _layout([box1, cyl1]))
    # Along +x the ray enters through the face x_local = -2 (box frame): t = 10 - 2 / cos(30).
    expect_box1 = 10.0 - 2.0 / math.cos(yaw)
    dist, gid = _ray(physics, origin, (1, 0, 0))
    assert dist == pytest.approx(expect_box1, abs=1e-6) and _name(physics, gid).startswith("box_")
    dist, gid = _ray(physics, origin, (0, 1, 0))
    assert dist == pytest.approx(8.0 - 1.5, abs=1e-6) and _name(physics, gid).startswith("cylinder_")
    assert _multiray(physics, origin, (1, 0, 0))[0] == pytest.approx(expect_box1, abs=1e-6)

    # Layout 2 on the same physics: different sizes and places, a moving cylinder, a wall.
    box2 = Obstacle("box", 53.5, 50.0, (0.5, 0.5), 0.0)
    cyl2 = Obstacle("cylinder", 50.0, 54.0, (3.0,))
    wall2 = Obstacle("box", 50.0, 44.0, (4.0, 0.25), 0.0, True)
    mover = MovingObstacle(45.0, 50.0, 1.25, 0.5, 0.0)
    arena.apply_layout(physics, _layout([box2, cyl2, wall2], [mover]))
    for vec, expect, prefix in (
        ((1, 0, 0), 3.0, "box_"),
        ((0, 1, 0), 1.0, "cylinder_"),
        ((0, -1, 0), 6.0 - 0.25, "wall_"),
        ((-1, 0, 0), 5.0 - 1.25, "moving_"),
    ):
        dist, gid = _ray(physics, origin, vec)
        assert dist == pytest.approx(expect, abs=1e-6), (vec, _name(physics, gid))
        assert _name(physics, gid).startswith(prefix)
        assert _multiray(physics, origin, vec)[0] == pytest.approx(expect, abs=1e-6)
    # Where the first layout's box and cylinder were, nothing is left: these rays
    # crossed them and now reach the east border wall.
    assert _ray(physics, (50.0, 47.0, z), (1, 0, 0))[0] == pytest.approx(50.0)
    assert _ray(physics, (45.0, 58.0, z), (1, 0, 0))[0] == pytest.approx(55.0)


def test_parked_slots_are_invisible_to_rays_and_renders():
    arena, physics = _physics()
    arena.apply_layout(physics, _layout())
    m = physics.model.ptr
    bodies = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"box_{k:03d}") for k in range(5)]
    assert np.all(physics.data.ptr.xpos[bodies, 2] == pytest.approx(PARK_Z))
    geoms = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"box_{k:03d}") for k in range(5)]
    assert np.all(m.geom_rgba[geoms, 3] == 0)
    assert np.all(m.geom_contype[geoms] == 0) and np.all(m.body_contype[bodies] == 0)
    # A ray along the parking row hits nothing.
    assert _ray(physics, (-5.0, -10.0, PARK_Z), (1, 0, 0))[0] == -1


def test_compiled_bounds_match_what_apply_layout_writes():
    """apply_layout must write rbound/aabb/bvh exactly as the compiler derives them."""
    height = SPEC.obstacle_height
    xml = f"""<mujoco><worldbody>
      <body name="b" pos="3 4 {height / 2}" quat="{math.cos(0.35)} 0 0 {math.sin(0.35)}">
        <inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>
        <geom name="b" type="box" size="1.3 2.1 {height / 2}"/></body>
      <body name="c" pos="8 4 {height / 2}">
        <inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>
        <geom name="c" type="cylinder" size="1.7 {height / 2}"/></body>
    </worldbody></mujoco>"""
    ref = mujoco.MjModel.from_xml_string(xml)
    arena, physics = _physics()
    arena.apply_layout(
        physics, _layout([Obstacle("box", 3.0, 4.0, (1.3, 2.1), 0.7), Obstacle("cylinder", 8.0, 4.0, (1.7,))])
    )
    m = physics.model.ptr
    for ref_name, name in (("b", "box_000"), ("c", "cylinder_000")):
        rg = mujoco.mj_name2id(ref, mujoco.mjtObj.mjOBJ_GEOM, ref_name)
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
        np.testing.assert_allclose(m.geom_size[g], ref.geom_size[rg], atol=1e-12)
        np.testing.assert_allclose(m.geom_rbound[g], ref.geom_rbound[rg], atol=1e-12)
        np.testing.assert_allclose(m.geom_aabb[g], ref.geom_aabb[rg], atol=1e-12)
        b, rb = m.geom_bodyid[g], ref.geom_bodyid[rg]
        np.testing.assert_allclose(
            m.bvh_aabb[m.body_bvhadr[b]], ref.bvh_aabb[ref.body_bvhadr[rb]], atol=1e-12
        )
        np.testing.assert_allclose(m.body_pos[b], ref.body_pos[rb], atol=1e-12)
        np.testing.assert_allclose(m.body_quat[b], ref.body_quat[rb], atol=1e-12)


def _probe() -> mjcf.RootElement:
    """A free body with two spheres (robot-like contact bits): two geoms force
    MuJoCo's BVH midphase, which culls with the obstacle's bvh_aabb."""
    probe = mjcf.RootElement(model="probe")
    body = probe.worldbody.add("body", name="probe")
    body.add("geom", name="s1", type="sphere", size=[0.2], contype=2, conaffinity=1, group=3)
    body.add(
        "geom", name="s2", type="sphere", size=[0.1], pos=[0, 0, 0.15], contype=2, conaffinity=1, group=3
    )
    return probe


def _contacts(physics, probe_geom_ids) -> list[tuple[str, float]]:
    d = physics.data.ptr
    out = []
    for k in range(d.ncon):
        g1, g2 = d.contact.geom[k]
        other = g2 if g1 in probe_geom_ids else g1
        out.append((_name(physics, int(other)), float(d.contact.dist[k])))
    return out


def test_contacts_with_resized_obstacles_for_two_layouts():
    spec = ArenaSpec(static_obstacles=3, moving_obstacles=1, interior_walls=1)
    arena = NavigationArena(spec)
    probe = _probe()
    frame = arena.add_free_entity(composer.ModelWrapperEntity(probe))
    physics = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
    probe_ids = set(physics.bind(probe.find_all("geom")).element_id.tolist())
    free = physics.bind(frame.find_all("joint")[0])

    def place(x, y):
        free.qpos[:3] = (x, y, 0.3)
        free.qpos[3:] = (1, 0, 0, 0)

    # Layout 1: a yawed box whose near face is 0.15 m inside the sphere of radius 0.2.
    yaw = 0.4
    box = Obstacle("box", 30.0, 30.0, (1.0, 2.0), yaw)
    arena.apply_layout(physics, _layout([box]), forward=False)
    # Sphere centre on the box's local -x axis, 0.05 m outside the face -> dist -0.15.
    c, s = math.cos(yaw), math.sin(yaw)
    place(30.0 - 1.05 * c, 30.0 - 1.05 * s)
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    found = _contacts(physics, probe_ids)
    assert any(n.startswith("box_") and d == pytest.approx(-0.15, abs=1e-6) for n, d in found), found

    # Layout 2 on the same physics: the box slot shrinks (now far from the probe), a
    # cylinder and a moving obstacle grow under it; the old contact must disappear.
    px, py = 30.0 - 1.05 * c, 30.0 - 1.05 * s
    cyl = Obstacle("cylinder", px, py + 3.1, (3.0,))  # rim 0.1 m inside the sphere
    small = Obstacle("box", 70.0, 70.0, (0.3, 0.3), 0.0)
    mover = MovingObstacle(20.0, 30.0, 1.4, 0.0, 0.3)
    arena.apply_layout(physics, _layout([small, cyl], [mover]), forward=False)
    place(px, py)
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    found = _contacts(physics, probe_ids)
    assert not any(n.startswith("box_") for n, _ in found), found
    assert any(n.startswith("cylinder_") and d == pytest.approx(-0.1, abs=1e-6) for n, d in found), found

    place(21.5, 30.0)  # 0.1 m inside the moving obstacle's rim
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    found = _contacts(physics, probe_ids)
    assert any(n.startswith("moving_") and d == pytest.approx(-0.1, abs=1e-6) for n, d in found), found


def test_wall_mask_marks_exactly_the_walls():
    arena, physics = _physics()
    arena.apply_layout(physics, generate_layout(SPEC, np.random.RandomState(1)))
    mask = arena.wall_mask(physics)
    m = physics.model.ptr
    assert mask.shape == (m.ngeom,) and mask.dtype == bool
    walls = {_name(physics, g) for g in np.nonzero(mask)[0]}
    expected = {"wall_south", "wall_north", "wall_west", "wall_east", "wall_000", "wall_001", "wall_002"}
    assert walls == expected
    assert arena.wall_mask(physics) is mask  # cached
    # Every generated wall (explicit + interior) is in a wall slot.
    layout = arena.layout
    walls_in_layout = [o for o in layout.obstacles if o.is_wall]
    assert len(walls_in_layout) == 3
    for ob in walls_in_layout:
        dist, gid = _ray(physics, (ob.x, ob.y, 5.0), (0, 0, -1))
        assert mask[gid], _name(physics, gid)


def test_obstacle_geom_ids_are_everything_collidable():
    arena, physics = _physics()
    ids = arena.obstacle_geom_ids(physics)
    names = {_name(physics, g) for g in ids}
    assert len(names) == ids.size == 4 + 5 + 4 + 3 + 3
    assert "ground" not in names and "target_marker" not in names and "start_marker" not in names
    m = physics.model.ptr
    collidable = {_name(physics, g) for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]}
    assert names == collidable


def test_markers_move_and_are_visual_only():
    arena, physics = _physics()
    layout = Layout((100.0, 100.0), (12.0, 34.0), 0.0, (56.0, 78.0))
    arena.apply_layout(physics, layout)
    m, d = physics.model.ptr, physics.data.ptr
    for name, xy in (("target_marker", (56.0, 78.0)), ("start_marker", (12.0, 34.0))):
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
        np.testing.assert_allclose(d.geom_xpos[g, :2], xy)
        assert m.geom_contype[g] == 0 and m.geom_conaffinity[g] == 0 and m.geom_group[g] == 2
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "target_marker")
    assert m.geom_size[g, 0] == pytest.approx(SPEC.target_radius)


def test_move_obstacles_follows_layout_advance_and_bounces():
    spec = ArenaSpec(
        static_obstacles=0, moving_obstacles=3, size=(20.0, 20.0), start=(2.0, 2.0), target=(18.0, 18.0)
    )
    arena, physics = _physics(spec)
    moving = (
        MovingObstacle(17.0, 10.0, 1.0, 2.0, 0.3),  # bounces off the east wall within 1 s
        MovingObstacle(10.0, 2.0, 0.8, -0.4, -1.5),
        MovingObstacle(8.0, 8.0, 1.2, 0.0, 0.0),
    )
    arena.apply_layout(physics, Layout((20.0, 20.0), (2.0, 2.0), 0.0, (18.0, 18.0), (), moving))
    pos = np.array([(o.x, o.y) for o in moving])
    vel = np.array([(o.vx, o.vy) for o in moving])
    radii = np.array([o.radius for o in moving])
    mocap = physics.data.ptr.mocap_pos
    flips = 0
    for _ in range(1500):
        arena.move_obstacles(physics, 0.01)
        before = np.sign(vel)
        pos, vel = advance(pos, vel, radii, 0.01, (20.0, 20.0))
        flips += int(np.sum(np.sign(vel) != before))
        np.testing.assert_allclose(mocap[:, :2], pos, atol=1e-9)
        assert np.all(mocap[:, :2] >= radii[:, None] - 1e-9) and np.all(
            mocap[:, :2] <= 20.0 - radii[:, None] + 1e-9
        )
    np.testing.assert_allclose(arena.moving_velocities, vel)
    assert flips >= 4  # both moving ones bounced, more than once
    np.testing.assert_allclose(mocap[:, 2], spec.obstacle_height / 2)
    # physics.reset() puts them back at the episode's initial positions.
    physics.reset()
    np.testing.assert_allclose(physics.data.ptr.mocap_pos[:, :2], [(o.x, o.y) for o in moving])


def test_fewer_moving_obstacles_than_slots_are_parked():
    arena, physics = _physics()
    arena.apply_layout(physics, _layout(moving=[MovingObstacle(30.0, 30.0, 1.0, 0.5, 0.0)]))
    mocap = physics.data.ptr.mocap_pos
    assert mocap[0, 2] == pytest.approx(SPEC.obstacle_height / 2)
    assert np.all(mocap[1:, 2] == PARK_Z)
    arena.move_obstacles(physics, 0.1)
    assert mocap[0, 0] == pytest.approx(30.05)
    assert np.all(mocap[1:, 2] == PARK_Z)


def test_layout_from_another_spec_is_rejected():
    arena, physics = _physics(ArenaSpec(static_obstacles=1))
    too_many = _layout([Obstacle("box", 20.0 + 5 * k, 50.0, (1.0, 1.0)) for k in range(2)])
    with pytest.raises(ValueError, match="box slots"):
        arena.apply_layout(physics, too_many)
    with pytest.raises(ValueError, match="size"):
        arena.apply_layout(physics, _layout(size=(50.0, 50.0)))


def test_a_new_physics_gets_its_own_ids_and_views():
    spec = ArenaSpec(static_obstacles=2, moving_obstacles=2)
    arena, first = _physics(spec)
    layout = generate_layout(spec, np.random.RandomState(4))
    arena.apply_layout(first, layout)
    second = mjcf.Physics.from_mjcf_model(arena.mjcf_model)
    arena.apply_layout(second, layout)
    before = first.data.ptr.mocap_pos.copy()
    arena.move_obstacles(second, 0.5)
    np.testing.assert_array_equal(first.data.ptr.mocap_pos, before)
    np.testing.assert_allclose(second.data.ptr.mocap_pos[:, :2], arena.moving_positions)
    assert not np.allclose(second.data.ptr.mocap_pos[:, :2], before[:, :2])
