"""Recovered-reward maps: r_theta(s, a) for every action over a grid of robot poses in one arena.

phi(s) at a pose is sensed the way the task senses it (same rays, same
``mj_multiRay`` call, same danger bands): the arena of ``arena_seed`` is built
in a physics model, moving obstacles stay at their initial positions (t = 0),
and the sensors are cast from each grid cell's centre. The robot itself never
needs to move there: the rays see only the world (geom group 0).

Headings are set by the target's bearing from the robot (counter-clockwise
from its front), so one row of the map means the same everywhere: 0 faces the
target, 90 has it on the left, 160 behind (the centre of S5's cone; 180 would
sit on the S5/S6 border, where V flips with rounding), -90 on the right. Cells
whose centre is within the robot's radius of an obstacle (where the robot
cannot be) are NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from nirl_mj.data import features
from nirl_mj.learn.reward import RewardModel
from nirl_mj.sim.drive import BODY_RADIUS
from nirl_mj.sim.layout import Layout, occupancy_grid
from nirl_mj.sim.spec import TaskSpec, load_task

DEFAULT_BEARINGS_DEG = (0.0, 90.0, 160.0, -90.0)
"""The target's bearing from the robot's front (degrees, counter-clockwise) of each map row."""


@dataclass(frozen=True)
class PhiGrid:
    """phi(s) sensed on a grid of poses in one arena.

    ``xs`` (nx,) and ``ys`` (ny,) cell centres in metres; ``bearings`` (K,) the
    target's bearing from the robot's front, radians; ``phi`` (K, ny, nx, 16)
    float32, NaN where ``free`` (ny, nx) is False; ``layout`` the arena.
    """

    xs: np.ndarray
    ys: np.ndarray
    bearings: np.ndarray
    phi: np.ndarray
    free: np.ndarray
    layout: Layout


def sense_grid(
    task: str | TaskSpec,
    arena_seed: int,
    resolution: float = 2.0,
    bearings_deg: tuple[float, ...] = DEFAULT_BEARINGS_DEG,
) -> PhiGrid:
    """phi(s) at every free cell centre (``resolution`` metres apart) of the arena drawn
    from ``arena_seed``, for each heading that puts the target at one of ``bearings_deg``
    (degrees counter-clockwise from the robot's front).
    Costs about 50 us per pose (2 m cells in a 100 m arena, 4 offsets: ~0.5 s)."""
    from nirl_mj.sim.sensing import RangeSensors
    from nirl_mj.sim.task import make_env

    spec = load_task(task)
    env = make_env(spec)
    env.random_state.seed(arena_seed)
    env.reset()
    physics, nav = env.physics, env.task
    layout = nav.layout
    sensors = RangeSensors(
        physics.model.ptr,
        nav.root_entity.wall_mask(physics),
        spec.robot.rays_per_sensor,
        spec.sensing.range,
        BODY_RADIUS,
    )
    origin_z = float(physics.bind(nav.robot.sensor_origin).xpos[2])
    width, height = layout.size
    xs = np.arange(resolution / 2, width, resolution)
    ys = np.arange(resolution / 2, height, resolution)
    free = _free_cells(layout, xs, ys)
    bearings = np.deg2rad(np.asarray(bearings_deg, dtype=np.float64))
    phi = np.full((bearings.size, ys.size, xs.size, features.N_FEATURES), np.nan, dtype=np.float32)
    target = np.asarray(layout.target, dtype=np.float64)
    data = physics.data.ptr
    origin = np.zeros(3)
    origin[2] = origin_z
    for i, j in zip(*np.nonzero(free), strict=True):
        origin[0], origin[1] = xs[j], ys[i]
        towards = math.atan2(target[1] - ys[i], target[0] - xs[j])
        for k, bearing in enumerate(bearings):
            scan = sensors.scan(data, origin, towards - bearing, target)
            danger = features.danger_levels(scan.ranges, spec.sensing.range, spec.sensing.danger7_clearance)
            region = features.target_region(scan.bearing)
            phi[k, i, j] = features.state_features(danger, scan.wall, region, scan.target_visible)
    env.close()
    return PhiGrid(xs, ys, bearings, phi, free, layout)


def _free_cells(layout: Layout, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """(ny, nx) True where a robot centred on the cell centre touches nothing (moving
    obstacles at t = 0 included)."""
    # A fine occupancy grid of the robot's configuration space, sampled at the centres.
    grid = occupancy_grid(layout, 0.1, inflate=BODY_RADIUS)
    gx, gy = np.meshgrid(xs, ys)
    rows, cols = grid.cell_of(gx, gy)
    free = ~grid.occupied[rows, cols]
    for ob in layout.moving:
        free &= np.hypot(gx - ob.x, gy - ob.y) > ob.radius + BODY_RADIUS
    return free


def reward_map(grid: PhiGrid, model: RewardModel) -> np.ndarray:
    """r_theta(s, a) on the grid: (K bearings, 6 actions, ny, nx) float64, NaN where not free."""
    k, ny, nx, _ = grid.phi.shape
    out = np.full((k * ny * nx, features.N_ACTIONS), np.nan)
    flat = grid.phi.reshape(-1, features.N_FEATURES)
    ok = np.repeat(grid.free.reshape(1, -1), k, axis=0).ravel()
    if ok.any():
        out[ok] = model.rewards_all_actions(flat[ok])
    return out.reshape(k, ny, nx, features.N_ACTIONS).transpose(0, 3, 1, 2)


def colourise(values: np.ndarray, low: float, high: float, scale: int = 4) -> np.ndarray:
    """(ny, nx) values (row 0 at the smallest y) -> (ny * scale, nx * scale, 3) uint8 image with
    north up (row 0 at the largest y), viridis from ``low`` to ``high``, NaN dark grey."""
    from matplotlib import colormaps

    span = max(high - low, 1e-12)
    norm = np.clip((values - low) / span, 0.0, 1.0)
    rgb = (colormaps["viridis"](np.nan_to_num(norm))[..., :3] * 255).astype(np.uint8)
    rgb[~np.isfinite(values)] = (60, 60, 60)
    rgb = rgb[::-1]  # images run top-down, the arena's y runs up
    return np.repeat(np.repeat(rgb, scale, axis=0), scale, axis=1)


def grid_figure(grid: PhiGrid, rewards: np.ndarray, title: str = "r_theta(s, a)") -> np.ndarray:
    """One image (H, W, 3) uint8 of all maps: a row per target bearing, a column per action,
    one shared colour scale with its bar; drawn with matplotlib."""
    from nirl_mj.inspect.canvas import subplots, to_rgb

    k = rewards.shape[0]
    finite = rewards[np.isfinite(rewards)]
    low, high = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    w, h = grid.layout.size
    fig, axes = subplots(k, features.N_ACTIONS, figsize=(1.6 * features.N_ACTIONS + 1.2, 1.6 * k + 0.5),
                         dpi=80, squeeze=False)  # fmt: skip
    image = None
    for r in range(k):
        for a in range(features.N_ACTIONS):
            ax = axes[r, a]
            masked = np.ma.masked_invalid(rewards[r, a])
            image = ax.imshow(masked, origin="lower", extent=(0, w, 0, h), vmin=low, vmax=high,
                              cmap="viridis", interpolation="nearest")  # fmt: skip
            ax.plot(*grid.layout.target, "r*", ms=6)
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(features.ACTION_NAMES[a], fontsize=9)
            if a == 0:
                ax.set_ylabel(f"target at {math.degrees(grid.bearings[r]):+.0f} deg", fontsize=8)
    fig.suptitle(title, fontsize=10)
    # Fixed margins: matplotlib's constrained layout costs ~0.2 s for these 24 panels.
    fig.subplots_adjust(left=0.05, right=0.9, bottom=0.02, top=0.9, wspace=0.05, hspace=0.05)
    if image is not None:
        fig.colorbar(image, cax=fig.add_axes((0.92, 0.1, 0.015, 0.75)))
    return to_rgb(fig)
