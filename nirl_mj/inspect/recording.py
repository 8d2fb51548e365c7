"""Rerun recordings of what the robot saw and did (rerun-sdk 0.41 API).

A trajectory stores its arena's seed and task spec, not the arena itself; the
arena is regenerated exactly as the environment drew it (:func:`layout_of`),
and moving obstacles are advanced along their straight, bouncing paths to each
decision's time. Sensor rays are drawn from the stored clearances (a ray per
sensor, clearance + robot radius long, coloured by its danger level), so no
physics runs while recording.

Entity paths of an episode under ``P`` (``demos/007``, ``eval/nirl/003``;
docs/INSPECT.md lists everything, with the blueprint):

- static: ``P/arena/{obstacles,cylinders,border,start_target}``, ``P/path``
  (line strip coloured by outcome), ``P/end`` (the last position, in the outcome's
  colour) and ``P/end/label`` (the outcome's word just north of it), ``P/label``
  (the episode's index and outcome, north of the arena),
  ``P/robot/footprint``, ``P/robot/heading`` and ``P/robot/marker`` (in the robot's frame),
  ``P/reward_path`` (the path's segments coloured by r_theta, with a learned reward);
- on the ``step`` (decision index) and ``time`` (simulated seconds)
  timelines: ``P/robot`` (pose, a 3-D transform), ``P/robot/rays`` (nine
  rays), ``P/action`` (text), ``P/features/{danger,target,flags}`` (the 16 values of phi(s)),
  ``P/reward`` (r_theta(s_t, a_t), with a learned reward), and
  ``P/arena/moving`` (moving obstacles).

Training scalars are under ``training/<name>`` on the ``iteration`` timeline only
(one row per NIRL iteration; never on ``step``), and drawn as one static figure
(``training/figure``); the recovered-reward map under ``reward_map/``; each episode
group's colour legend, an image of every colour its tab draws, under ``legend/<group>``.
:class:`Recording` writes a file atomically (:class:`nirl_mj.data.atomic.AtomicFile`).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr

from nirl_mj.data.atomic import AtomicFile
from nirl_mj.data.features import ACTION_NAMES, N_ACTIONS, SENSOR_ANGLES, danger_levels
from nirl_mj.data.trajectory import Trajectory
from nirl_mj.inspect.blueprint import (
    ITERATION,
    OUTCOME_WORDS,
    TIMELINE,
    TRAINING_FIGURE,
    Group,
    Scene,
    default_blueprint,
    legend_entity,
    tile_offsets,
)
from nirl_mj.inspect.styles import (
    FEATURE_GROUPS,
    REWARD_COLOUR,
    TRAINING_KEYS,
    LegendSection,
    Swatch,
    feature_names,
    legend_image,
    log_series_style,
    log_training_styles,
    training_figure,
)
from nirl_mj.sim.drive import BODY_RADIUS
from nirl_mj.sim.layout import Layout, advance, generate_layout
from nirl_mj.sim.spec import from_dict

if TYPE_CHECKING:
    from nirl_mj.inspect.reward_map import PhiGrid
    from nirl_mj.learn.reward import RewardModel
    from nirl_mj.sim.spec import TaskSpec

_EXISTS = "exists; pass --overwrite (overwrite=True) to replace it, or choose another --rerun file"
_OBSTACLE = (150, 150, 160)
_WALL = (90, 90, 100)
_MOVING = (255, 140, 26)
_ROBOT = (230, 230, 230)
_MARKER_RGB = (20, 20, 20)  # the robot's marker and heading: dark on the light floor and paths
_PATH = {
    "target": (40, 170, 60),
    "collision": (220, 50, 40),
    "timeout": (230, 160, 30),
    "physics_error": (150, 0, 150),
}
DANGER_COLOURS = np.array(
    [(110, 190, 110), (255, 235, 120), (255, 210, 90), (255, 180, 70),
     (250, 145, 55), (240, 105, 45), (225, 65, 40), (200, 20, 30)], dtype=np.uint8,
)  # fmt: skip
"""RGB of danger levels 0 (nothing in range: green) .. 7 (closest: dark red), shape (8, 3)."""
_START = (40, 90, 220)
_TARGET = (40, 170, 60)
_SCALE = ((40, 90, 220), (200, 200, 200), (220, 40, 40))  # r_theta along a path: lowest, middle, highest
_RAY_HEIGHT = 0.06  # m: the sensors' height on the robot
# Widths in screen points (Rerun reads a negative radius so): the robot, its rays and its path stay
# visible whether a view shows one arena or thirty, and the path never hides the robot.
_PATH_WIDTH = rr.Radius.ui_points(2.0)
_REWARD_PATH_WIDTH = rr.Radius.ui_points(1.2)
_RAY_WIDTH = rr.Radius.ui_points(1.5)
_MARKER = rr.Radius.ui_points(6.0)
_END = rr.Radius.ui_points(5.0)
_END_LABEL = 3.0  # m north of the end: where its label sits
_HEADING = 2.0  # m: the heading arrow's length, past the 0.225 m body so that it shows from afar


def png_image(rgb: np.ndarray) -> rr.EncodedImage:
    """An (H, W, 3) uint8 figure as a PNG-encoded image: lossless (a legend's colours stay exact)
    and a tenth of the raw pixels' size, so the viewer loads it quickly."""
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(rgb).save(buffer, format="PNG", optimize=False)
    return rr.EncodedImage(contents=buffer.getvalue(), media_type="image/png")


def layout_of(trajectory: Trajectory) -> Layout:
    """The arena the trajectory ran in, regenerated from its seed and task spec."""
    spec = from_dict(trajectory.task, "trajectory task")
    return generate_layout(spec.arena, np.random.RandomState(trajectory.arena_seed), robot_radius=BODY_RADIUS)


def slug(name: str) -> str:
    """``name`` as one entity-path part: lower case, runs of other characters as ``_``."""
    return re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")


def _yaw_quaternions(yaw: np.ndarray) -> np.ndarray:
    """(N,) radians about +z -> (N, 4) quaternions in Rerun's xyzw order."""
    return np.stack([np.zeros_like(yaw), np.zeros_like(yaw), np.sin(yaw / 2), np.cos(yaw / 2)], axis=1)


def log_layout(
    rec: rr.RecordingStream, path: str, layout: Layout, height: float = 1.0, target_radius: float = 1.0
) -> None:
    """Logs an arena as static 3-D geometry under ``path`` (metres; the target a disc of
    ``target_radius``); moving obstacles are logged over time by :func:`log_trajectory`."""
    boxes = [o for o in layout.obstacles if o.shape == "box"]
    cylinders = [o for o in layout.obstacles if o.shape == "cylinder"]
    if boxes:
        rec.log(
            f"{path}/obstacles",
            rr.Boxes3D(
                centers=[(o.x, o.y, height / 2) for o in boxes],
                half_sizes=[(o.size[0], o.size[1], height / 2) for o in boxes],
                quaternions=_yaw_quaternions(np.array([o.yaw for o in boxes])),
                colors=[_WALL if o.is_wall else _OBSTACLE for o in boxes],
                fill_mode="solid",
            ),
            static=True,
        )
    if cylinders:
        rec.log(
            f"{path}/cylinders",
            rr.Cylinders3D(
                centers=[(o.x, o.y, height / 2) for o in cylinders],
                radii=[o.size[0] for o in cylinders],
                lengths=[height] * len(cylinders),
                quaternions=_yaw_quaternions(np.zeros(len(cylinders))),
                colors=[_OBSTACLE] * len(cylinders),
                fill_mode="solid",
            ),
            static=True,
        )
    w, h = layout.size
    rec.log(
        f"{path}/border",
        rr.LineStrips3D([[(0, 0, 0), (w, 0, 0), (w, h, 0), (0, h, 0), (0, 0, 0)]], colors=[_WALL]),
        static=True,
    )
    rec.log(
        f"{path}/start_target",
        rr.Points3D(
            [(*layout.start, 0.0), (*layout.target, 0.0)],
            colors=[_START, _TARGET],
            radii=[0.5, target_radius],
            labels=["start", "target"],
        ),
        static=True,
    )


def moving_positions(layout: Layout, times: np.ndarray) -> np.ndarray:
    """Centres (metres) of the layout's moving obstacles at ``times`` (seconds since the episode's
    start, non-decreasing): (len(times), M, 2). The task moves them the same way (straight lines,
    bouncing off the border walls); it stops them once an episode's outcome is decided, so the
    last decision of an episode that ends early shows them up to one decision ahead."""
    m = len(layout.moving)
    p = np.array([(o.x, o.y) for o in layout.moving], dtype=np.float64).reshape(m, 2)
    v = np.array([(o.vx, o.vy) for o in layout.moving], dtype=np.float64).reshape(m, 2)
    r = np.array([o.radius for o in layout.moving], dtype=np.float64)
    out = np.empty((len(times), m, 2))
    now = 0.0
    for t, when in enumerate(times):
        if when > now:
            p, v = advance(p, v, r, float(when - now), layout.size)
            now = float(when)
        out[t] = p
    return out


def _indexes(trajectory: Trajectory, rows: int) -> list[rr.TimeColumn]:
    return [
        rr.TimeColumn(TIMELINE, sequence=np.arange(rows)),
        rr.TimeColumn("time", duration=np.asarray(trajectory.times[:rows], dtype=np.float64)),
    ]


def _ray_strips(trajectory: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Sensor rays in the robot's frame: strips (T+1, 9, 2, 3) metres, colours (T+1, 9, 3)."""
    sensing = trajectory.task["sensing"]
    ranges = np.asarray(trajectory.ranges, dtype=np.float64)
    levels = danger_levels(ranges, sensing["range"], sensing["danger7_clearance"])
    length = BODY_RADIUS + np.minimum(ranges, sensing["range"])
    strips = np.zeros((*ranges.shape, 2, 3))
    strips[..., :, 2] = _RAY_HEIGHT
    strips[..., 1, 0] = length * np.cos(SENSOR_ANGLES)
    strips[..., 1, 1] = length * np.sin(SENSOR_ANGLES)
    return strips, DANGER_COLOURS[levels]


def _colour_scale(values: np.ndarray) -> np.ndarray:
    """Values -> (N, 3) uint8 from blue (lowest) through grey to red (highest)."""
    values = np.asarray(values, dtype=np.float64)
    span = np.ptp(values) if values.size else 0.0
    u = (values - values.min()) / span if span > 0 else np.full(values.shape, 0.5)
    low, mid, high = (np.array(c, dtype=np.float64) for c in _SCALE)
    w = u[:, None]
    out = np.where(w < 0.5, low + (mid - low) * (2 * w), mid + (high - mid) * (2 * w - 1))
    return out.astype(np.uint8)


def _action_texts(trajectory: Trajectory) -> list[str]:
    """The actions as the log shows them: a name (``forward``), or a continuous action's shares of
    the forward speed and the yaw rate."""
    actions = np.asarray(trajectory.actions)
    if actions.ndim == 2:
        return [f"speed {v:+.2f}, turn {w:+.2f}" for v, w in actions]
    return np.asarray(ACTION_NAMES)[actions].tolist()


def log_trajectory(
    rec: rr.RecordingStream,
    path: str,
    trajectory: Trajectory,
    reward: RewardModel | None = None,
    layout: Layout | None = None,
) -> None:
    """Logs one episode under ``path``: the path, its end (a dot in the outcome's colour, and just
    north of it its label: ``collision`` where the robot hit something) and the robot's footprint
    and marker (static); per
    decision on the ``step`` and ``time`` timelines the robot's pose, its sensor rays, the action,
    phi(s) (``features/danger``, ``features/target``, ``features/flags``: one entity per scale),
    r_theta(s_t, a_t) when ``reward`` is given, and the moving obstacles of ``layout``. Series are
    named and coloured once (static ``SeriesLines``).

    Row counts: T + 1 (states) for the pose, rays, features and moving obstacles; T for the
    action and the reward. Columnar (``send_columns``): a few ms per episode.
    """
    n = len(trajectory) + 1
    poses = np.asarray(trajectory.poses, dtype=np.float64)
    points = np.column_stack([poses[:, :2], np.full(n, 0.1)])
    rec.log(
        f"{path}/path",
        rr.LineStrips3D([points], colors=[_PATH[trajectory.outcome]], radii=_PATH_WIDTH),
        static=True,
    )
    colour = _PATH[trajectory.outcome]
    rec.log(f"{path}/end", rr.Points3D([(*poses[-1, :2], 0.35)], colors=[colour], radii=_END), static=True)
    # The label a little north of the dot: an arrival's would cover the target's own label.
    word = rr.Points3D([(poses[-1, 0], poses[-1, 1] + _END_LABEL, 0.35)], colors=[colour], radii=[0.0],
                       labels=[OUTCOME_WORDS[trajectory.outcome]], show_labels=True)  # fmt: skip
    rec.log(f"{path}/end/label", word, static=True)
    rec.log(
        f"{path}/robot/footprint",
        rr.Cylinders3D(centers=[(0, 0, 0.15)], radii=[BODY_RADIUS], lengths=[0.3], colors=[_ROBOT]),
        static=True,
    )
    # Above the path (z 0.1) and the rays, so that a view from above shows the robot on top.
    marker = rr.Points3D([(0, 0, 0.6)], colors=[_MARKER_RGB], radii=_MARKER)
    rec.log(f"{path}/robot/marker", marker, static=True)
    rec.log(
        f"{path}/robot/heading",
        rr.Arrows3D(origins=[(0, 0, 0.6)], vectors=[(_HEADING, 0, 0)], colors=[_MARKER_RGB],
                    radii=rr.Radius.ui_points(2.0)),
        static=True,
    )  # fmt: skip
    states = _indexes(trajectory, n)
    rec.send_columns(
        f"{path}/robot",
        indexes=states,
        columns=rr.Transform3D.columns(
            translation=np.column_stack([poses[:, :2], np.zeros(n)]), quaternion=_yaw_quaternions(poses[:, 2])
        ),
    )
    strips, colours = _ray_strips(trajectory)
    k = strips.shape[1]
    rec.send_columns(
        f"{path}/robot/rays",
        indexes=states,
        columns=rr.LineStrips3D.columns(
            strips=strips.reshape(-1, 2, 3), colors=colours.reshape(-1, 3), radii=np.full(n * k, _RAY_WIDTH)
        ).partition(np.full(n, k)),
    )
    features = np.asarray(trajectory.features, dtype=np.float64)
    for group in FEATURE_GROUPS:
        entity = f"{path}/features/{group.name}"
        log_series_style(rec, entity, feature_names(group), group.colours)
        rec.send_columns(entity, indexes=states, columns=rr.Scalars.columns(scalars=features[:, group.index]))
    if len(trajectory):
        decisions = _indexes(trajectory, n - 1)
        rec.send_columns(
            f"{path}/action", indexes=decisions, columns=rr.TextLog.columns(text=_action_texts(trajectory))
        )
        if reward is not None and trajectory.action_kind == "discrete":  # r_theta(s, a) is of the six actions
            phi, actions = trajectory.pairs()
            r = np.asarray(reward.reward(phi, actions), dtype=np.float64)
            log_series_style(rec, f"{path}/reward", ["r_theta"], (REWARD_COLOUR,))
            rec.send_columns(f"{path}/reward", indexes=decisions, columns=rr.Scalars.columns(scalars=r))
            segments = np.stack([points[:-1], points[1:]], axis=1) + (0, 0, 0.05)
            rec.log(
                f"{path}/reward_path",
                rr.LineStrips3D(segments, colors=_colour_scale(r), radii=_REWARD_PATH_WIDTH),
                static=True,
            )
    if layout is not None and layout.moving:
        _log_moving(rec, f"{path}/arena/moving", layout, trajectory, states)


def _log_moving(
    rec: rr.RecordingStream, path: str, layout: Layout, trajectory: Trajectory, indexes: list
) -> None:
    n, m = len(trajectory) + 1, len(layout.moving)
    height = float(trajectory.task["arena"].get("obstacle_height", 1.0))
    xy = moving_positions(layout, np.asarray(trajectory.times))
    centres = np.concatenate([xy, np.full((n, m, 1), height / 2)], axis=2).reshape(-1, 3)
    radii = np.tile([o.radius for o in layout.moving], n)
    rec.send_columns(
        path,
        indexes=indexes,
        columns=rr.Cylinders3D.columns(
            centers=centres, radii=radii, lengths=np.full(n * m, height), colors=np.tile(_MOVING, (n * m, 1))
        ).partition(np.full(n, m)),
    )


def log_episode(
    rec: rr.RecordingStream,
    path: str,
    trajectory: Trajectory,
    reward: RewardModel | None = None,
) -> Layout:
    """:func:`log_layout` of the trajectory's regenerated arena under ``path/arena`` and
    :func:`log_trajectory` under ``path``, and the episode's index and outcome (``007 collision``,
    in the outcome's colour) centred north of the arena (``path/label``: short, so that the labels
    of a group's tiled arenas do not overlap). Returns the layout."""
    layout = layout_of(trajectory)
    height = float(trajectory.task["arena"].get("obstacle_height", 1.0))
    target_radius = float(trajectory.task["arena"].get("target_radius", 1.0))
    name = f"{path.rsplit('/', 1)[-1]} {OUTCOME_WORDS[trajectory.outcome]}"
    label = rr.Points3D([(layout.size[0] / 2, layout.size[1] + 4.0, 0.0)], radii=[0.0], labels=[name],
                        colors=[_PATH[trajectory.outcome]], show_labels=True)  # fmt: skip
    rec.log(f"{path}/label", label, static=True)
    log_layout(rec, f"{path}/arena", layout, height, target_radius)
    log_trajectory(rec, path, trajectory, reward, layout)
    return layout


def log_training(rec: rr.RecordingStream, metrics: Sequence[dict], prefix: str = "training") -> set[str]:
    """Training scalars (margin, cost, weight changes, accuracies, success; :data:`TRAINING_KEYS`),
    one row per metrics dict at its ``episode`` (the NIRL iteration) on the :data:`ITERATION`
    timeline only (columnar, so without the automatic ``log_time`` either): an episode's ``step``
    is another axis. Returns the keys logged."""
    logged = set()
    for key in TRAINING_KEYS:
        rows = [(int(row["episode"]), float(row[key])) for row in metrics
                if row.get(key) is not None and np.isfinite(row[key])]  # fmt: skip
        if rows:
            iterations, values = zip(*rows, strict=True)
            rec.send_columns(f"{prefix}/{key}", indexes=[rr.TimeColumn(ITERATION, sequence=iterations)],
                             columns=rr.Scalars.columns(scalars=np.array(values)))  # fmt: skip
            logged.add(key)
    return logged


def log_reward_map(
    rec: rr.RecordingStream, grid: PhiGrid, reward: RewardModel, arena: str = "", path: str = "reward_map"
) -> np.ndarray:
    """Logs r_theta over ``grid`` (static): ``path/<action>`` one image per action with the
    target ahead, ``path/grid`` every target bearing x action with a colour bar, ``path/values``
    the raw (bearings, actions, y, x) tensor and ``path/info`` what the images show. Returns the
    values (K, 6, ny, nx)."""
    from nirl_mj.inspect.reward_map import colourise, grid_figure, reward_map

    values = reward_map(grid, reward)
    finite = values[np.isfinite(values)]
    low, high = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    for a in range(N_ACTIONS):
        rec.log(f"{path}/{ACTION_NAMES[a]}", rr.Image(colourise(values[0, a], low, high)), static=True)
    rec.log(
        f"{path}/grid", png_image(grid_figure(grid, values, f"r_theta(s, a) {arena}".strip())), static=True
    )
    rec.log(
        f"{path}/values",
        rr.Tensor(np.nan_to_num(values, nan=low), dim_names=["bearing", "action", "y", "x"]),
        static=True,
    )
    cell = float(grid.xs[1] - grid.xs[0]) if grid.xs.size > 1 else 0.0
    bearings = ", ".join(f"{np.degrees(b):+.0f}" for b in grid.bearings)
    rec.log(
        f"{path}/info",
        rr.TextDocument(
            f"# Recovered reward r_theta(s, a)\n\nArena: {arena or 'sample arena'}. Grid: {grid.xs.size} x "
            f"{grid.ys.size} cells of {cell:g} m (north up); dark cells (white in the grid) are where the "
            f"robot cannot be. Per-action images: the target straight ahead (viridis, {low:.3g} .. "
            f"{high:.3g}). Grid rows: target at {bearings} degrees from the robot's front; columns: "
            f"{', '.join(ACTION_NAMES)}.",
            media_type="text/markdown",
        ),
        static=True,
    )
    return values


def episode_legend(
    outcomes: Mapping[str, int],
    sensing_range: float = 5.0,
    danger7_clearance: float = 1.0,
    moving: bool = False,
    reward_of: str | None = None,
) -> list[list[LegendSection]]:
    """Every colour an episode group's tab draws, in legend columns (:func:`styles.legend_image`):
    the paths by outcome with their counts (``outcomes``: outcome -> episodes) and, with a learned
    reward (``reward_of``: whose), the r_theta scale along them; the arena and the robot; the rays'
    danger levels with the clearances they stand for; and the plots' series colours."""
    counts = tuple(Swatch("line", (_PATH[o],), f"{OUTCOME_WORDS[o]}: {outcomes.get(o, 0)}") for o in _PATH)
    paths = [LegendSection("path, by outcome", counts)]
    if reward_of is not None:
        paths.append(
            LegendSection(f"path, by r_theta ({reward_of})", (Swatch("scale", _SCALE, "low .. high"),))
        )
    arena = [Swatch("dot", (_START,), "start"), Swatch("dot", (_TARGET,), "target"),
             Swatch("box", (_OBSTACLE,), "obstacle"), Swatch("box", (_WALL,), "wall, border")]  # fmt: skip
    if moving:
        arena.append(Swatch("box", (_MOVING,), "moving obstacle"))
    robot = (Swatch("box", (_ROBOT,), "body"), Swatch("dot", (_MARKER_RGB,), "centre, heading"))
    width = (sensing_range - danger7_clearance) / 6.0
    bands = [f"{k}: {danger7_clearance + (6 - k) * width:.1f}-{danger7_clearance + (7 - k) * width:.1f} m"
             for k in range(1, 7)]  # fmt: skip
    levels = [f"0: nothing in {sensing_range:g} m", *bands, f"7: under {danger7_clearance:g} m"]
    rays = LegendSection("rays, by danger D", tuple(
        Swatch("line", (tuple(int(v) for v in c),), text)
        for c, text in zip(DANGER_COLOURS, levels, strict=True)))  # fmt: skip
    names: dict[tuple[int, int, int], list[str]] = {}
    for group in FEATURE_GROUPS:
        for name, colour in zip(feature_names(group), group.colours, strict=True):
            names.setdefault(colour, []).append(name)
    lines = [Swatch("line", (c,), ", ".join(n)) for c, n in names.items()]
    if reward_of is not None:
        lines.append(Swatch("line", (REWARD_COLOUR,), "r_theta"))
    plots = LegendSection("plot lines", tuple(lines))
    return [paths, [LegendSection("arena", tuple(arena)), LegendSection("robot", robot)], [rays], [plots]]


class _GroupFacts:
    """What an episode group's legend needs to know: outcomes, moving obstacles, r_theta, sensing."""

    def __init__(self, trajectory: Trajectory) -> None:
        sensing = trajectory.task["sensing"]
        self.sensing = (float(sensing["range"]), float(sensing["danger7_clearance"]))
        self.outcomes: dict[str, int] = {}
        self.moving = False
        self.reward = False


def _default_group(path: str) -> Group:
    """How a group the caller did not describe is named: ``demos`` as demonstrations, ``eval/x``
    as test episodes of ``x``."""
    if path == "demos":
        return Group(path, "demonstrations", "demonstrations")
    if path.startswith("eval/"):
        return Group(path, path.removeprefix("eval/"), "test episodes")
    return Group(path, path)


class Recording(AtomicFile):
    """A ``.rrd`` file written atomically: data goes to a temporary file next to ``path`` and
    :meth:`close` moves it to ``path`` (after the legends, the training figure and the default
    blueprint); :meth:`abort`, or an exception inside a ``with`` block, deletes it. ``rec`` is the
    open :class:`rerun.RecordingStream`. ``method`` names whose training and learned reward the
    recording holds (tabs and plot titles say it). ``overwrite`` False: a ``path`` that exists, now or
    when the recording closes, is refused (``FileExistsError``)."""

    def __init__(
        self, path: str | os.PathLike, focus: str | None = None, method: str = "NIRL", overwrite: bool = False
    ) -> None:
        super().__init__(path, overwrite=overwrite, refusal=_EXISTS)
        self.focus = focus  # the episode whose tabs the layout opens on (None: the first)
        self.method = method
        try:
            self.rec = rr.RecordingStream("nirl-mj")
            self.rec.save(self.tmp)
        except BaseException:
            super().discard()
            raise
        self.scenes: list[Scene] = []  # logged episodes, in order, as the layout places them
        self.groups: dict[str, Group] = {}  # how the groups' tabs name them (:meth:`group`)
        self.logged_iterations: set[int] = set()  # ``episode`` values of logged metrics rows
        self.training_keys: set[str] = set()  # training scalars logged (and styled) so far
        self.metrics: list[dict] = []  # the logged metrics rows' training scalars, for the figure
        self.selected_iteration: int | None = None  # the reported policy's iteration, marked on the figure
        self.has_reward_map = False
        self._facts: dict[str, _GroupFacts] = {}

    @property
    def episodes(self) -> list[str]:
        """Entity paths of the logged episodes, in order."""
        return [scene.path for scene in self.scenes]

    def group(self, path: str, title: str, noun: str = "episodes", total: int | None = None) -> None:
        """Names the episode group ``path`` (``demos``, ``eval/nirl``): its tab ``title``, what its
        episodes are (``noun``) and how many there are in all (``total``; the recording holds the
        first ones), so that the tab says ``first 10 of 100 test episodes``."""
        self.groups[path] = Group(path, title, noun, total)

    def episode(self, path: str, trajectory: Trajectory, reward: RewardModel | None = None) -> None:
        """Logs one episode (:func:`log_episode`) under ``path``."""
        layout = log_episode(self.rec, path, trajectory, reward)
        drawn = reward is not None and len(trajectory) > 0
        self.scenes.append(Scene(path, layout.size, drawn, trajectory.outcome))
        facts = self._facts.setdefault(path.rsplit("/", 1)[0], _GroupFacts(trajectory))
        facts.outcomes[trajectory.outcome] = facts.outcomes.get(trajectory.outcome, 0) + 1
        facts.moving |= bool(layout.moving)
        facts.reward |= drawn

    def training(self, metrics: Sequence[dict]) -> None:
        """Logs metrics rows (:func:`log_training`), and each series' style the first time it
        appears; cheap enough to call every iteration (the figure is drawn once, at :meth:`close`)."""
        new = log_training(self.rec, metrics) - self.training_keys
        if new:
            log_training_styles(self.rec, new)
            self.training_keys |= new
        self.logged_iterations.update(int(row["episode"]) for row in metrics)
        self.metrics += [{k: row.get(k) for k in ("episode", *TRAINING_KEYS)} for row in metrics]

    def reward_map(
        self, task: str | TaskSpec, arena_seed: int, reward: RewardModel, resolution: float = 2.0
    ) -> None:
        """Senses phi(s) on a grid in the arena of ``arena_seed`` and logs r_theta there."""
        from nirl_mj.inspect.reward_map import sense_grid

        grid = sense_grid(task, arena_seed, resolution)
        log_reward_map(self.rec, grid, reward, f"arena seed {arena_seed}")
        self.has_reward_map = True

    def _log_legends(self) -> None:
        """Each group's colour legend (``legend/<group>``), and the training figure."""
        for group, facts in self._facts.items():
            columns = episode_legend(facts.outcomes, *facts.sensing, facts.moving,
                                     self.method if facts.reward else None)  # fmt: skip
            self.rec.log(legend_entity(group), png_image(legend_image(columns)), static=True)
        if self.metrics:
            rows = sorted(self.metrics, key=lambda r: int(r["episode"]))
            image = training_figure(rows, f"{self.method} training: {len(rows)} iterations",
                                    self.selected_iteration)  # fmt: skip
            self.rec.log(TRAINING_FIGURE, png_image(image), static=True)

    def commit(self) -> Path:
        """Places each episode in its group's view (a static transform of its entity: a view of the
        episode itself stays in the arena's frame), logs the legends and the training figure, sends
        the blueprint, flushes and moves the file into place; returns its path."""
        try:
            for path, (x, y) in tile_offsets(self.scenes).items():
                self.rec.log(path, rr.Transform3D(translation=(x, y, 0.0)), static=True)
            self._log_legends()
            groups = {g: self.groups.get(g) or _default_group(g) for g in self._facts}
            blueprint = default_blueprint(self.scenes, bool(self.metrics), self.has_reward_map, self.focus,
                                          groups, self.method)  # fmt: skip
            self.rec.send_blueprint(blueprint, make_active=True)
            self.rec.flush()
        except BaseException:
            self.discard()
            raise
        self.rec.disconnect()
        return super().commit()

    def discard(self) -> None:
        """Stops writing and deletes the partial file."""
        self.rec.disconnect()
        super().discard()

    close = commit
    abort = discard


def finish_training(recording: Recording, run_dir: str | os.PathLike, demos: str | os.PathLike) -> Path:
    """Completes and closes the recording of a finished training run in ``run_dir``: the metrics
    rows not logged yet (iterations before a resume), the demonstrations of the dataset ``demos``
    with r_theta of the run's selected reward (``reward.json``), and the reward map in the first
    demonstration's arena. Returns the recording's path."""
    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.data.rundir import REWARD_FILE, RUN_FILE, RunDir
    from nirl_mj.learn.reward import RewardModel

    run = RunDir(run_dir)
    try:
        record = run.read_record()
        rows = run.read_metrics()
        recording.selected_iteration = record.get("selected_iteration")
        recording.training([r for r in rows if int(r["episode"]) not in recording.logged_iterations])
        reward = RewardModel.from_dict(run.read_reward(), str(run.file(REWARD_FILE)))
        trajectories = load_dataset(demos)
        recording.group("demos", "demonstrations", "demonstrations", len(trajectories))
        for i, trajectory in enumerate(trajectories):
            recording.episode(f"demos/{i:03d}", trajectory, reward)
        recording.reward_map(
            from_dict(record["task"], f"{run.file(RUN_FILE)}: task"), trajectories[0].arena_seed, reward
        )
    except BaseException:
        recording.abort()
        raise
    return recording.close()


def copy_recording(source: str | os.PathLike, target: str | os.PathLike, overwrite: bool = False) -> Path:
    """Copies the recording ``source`` to ``target`` atomically (a temporary file, then a rename)."""
    import shutil

    with AtomicFile(target, overwrite=overwrite, refusal=_EXISTS) as out:
        shutil.copyfile(source, out.tmp)
    return out.path


def record_demonstrations(
    path: str | os.PathLike,
    trajectories: Sequence[Trajectory],
    reward: RewardModel | None = None,
    overwrite: bool = False,
) -> Path:
    """Writes a ``.rrd`` with every demonstration (``demos/<i>``), atomically."""
    return record_run(path, trajectories, (), {}, reward=reward, overwrite=overwrite)


def record_evaluation(
    path: str | os.PathLike,
    name: str,
    trajectories: Sequence[Trajectory],
    reward: RewardModel | None = None,
    map_arena: tuple[str | TaskSpec, int] | None = None,
    overwrite: bool = False,
) -> Path:
    """Writes a ``.rrd`` with every evaluation episode (``eval/<slug(name)>/<i>``), r_theta along
    each when ``reward`` (``name``'s learned reward) is given, and the reward map of ``map_arena``
    (task, arena seed)."""
    return record_run(
        path,
        (),
        (),
        {name: trajectories},
        len(trajectories),
        reward,
        map_arena,
        reward_of=name,
        overwrite=overwrite,
    )


def record_run(
    path: str | os.PathLike,
    demos: Sequence[Trajectory],
    metrics: Sequence[dict],
    evaluations: dict[str, Sequence[Trajectory]],
    max_paths: int = 10,
    reward: RewardModel | None = None,
    map_arena: tuple[str | TaskSpec, int] | None = None,
    focus: str | None = None,
    reward_of: str | None = None,
    selected: int | None = None,
    overwrite: bool = False,
) -> Path:
    """Writes a run's recording, atomically: the demonstrations (``demos/<i>``), the training
    scalars, the first ``max_paths`` test episodes of each policy (``eval/<policy slug>/<i>``; the
    tab says how many of how many) and, when ``reward`` is given, r_theta along the demonstrations
    and the test episodes of the policy whose reward it is (``reward_of``; default: the first of
    ``evaluations``; the other policies' tabs show only their own data) and the reward map in
    ``map_arena`` (task, arena seed) if given; the layout opens on the episode ``focus`` (an
    entity path; None: the first); the training figure marks the ``selected`` iteration.
    ``overwrite`` False: an existing ``path`` is refused, now or when the file is moved into place."""
    owner = reward_of if reward_of is not None else next(iter(evaluations), "NIRL")
    with Recording(path, focus, owner, overwrite) as recording:
        recording.selected_iteration = selected
        recording.group("demos", "demonstrations", "demonstrations", len(demos))
        for i, trajectory in enumerate(demos):
            recording.episode(f"demos/{i:03d}", trajectory, reward)
        if metrics:
            recording.training(metrics)
        for name, trajectories in evaluations.items():
            group = f"eval/{slug(name)}"
            recording.group(group, name, "test episodes", len(trajectories))
            for i, trajectory in enumerate(trajectories[:max_paths]):
                recording.episode(f"{group}/{i:03d}", trajectory, reward if name == owner else None)
        if reward is not None and map_arena is not None:
            recording.reward_map(map_arena[0], map_arena[1], reward)
    return Path(path)
