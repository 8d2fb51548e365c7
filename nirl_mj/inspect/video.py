"""Offscreen videos and snapshot montages of a policy's episodes (MuJoCo through EGL, no display).

Cameras (``CAMERAS``):

- ``top``: the whole arena from straight above (the arena's ``overview``
  camera). A robot is a few pixels wide there, so a red disc of 0.8 m radius
  with a heading bar marks it;
- ``follow``: 12 m above the robot, north up (the model's ``robotino/top``);
- ``chase``: 4 m behind the robot along its heading, looking down 22 degrees
  (a free camera placed every frame; the model's ``robotino/chase`` keeps its
  world orientation, so it looks along +x whatever the robot's heading).

Every view draws the path driven so far (decision by decision) into the
scene. Frames are honest about time: with ``fps`` F a frame shows the first
simulated state at or after each multiple of 1/F seconds, taken through the
task's ``command_hook`` after every command period (10 ms by default), so the
video plays at real time; a last frame shows the final state. Within a decision
the scene shows the positions MuJoCo derived at the start of the last physics
step (up to 10 ms old): recomputing them would change what the task's arrival
check reads. Setting the hook runs decisions command by command, the same
physics step for step, so a rendered episode is the unrendered one.

Overlays (drawn with Pillow): simulated time, the decision index, the action
being executed, the danger levels of the seven sensors in phi(s) as coloured
bars, the target sector V and the detection flag I; the outcome on the last
frame. From the top camera the square arena fills a square of the frame and
the overlays sit in a panel beside it (right of it in a wide frame, below it in
a tall one), so they do not cover the arena, but for a panel too small for them
(under about 76 px, e.g. 160 x 120); there, from the other cameras, and in a
square frame, they sit semi-transparent in the top-left corner (in a top view
that corner holds neither the start nor the target).

Errors: :class:`RenderError` (a RuntimeError) says how to fix a missing
OpenGL backend, an unknown camera or a frame bigger than the offscreen buffer;
outputs are written to a temporary file in the target's directory and renamed
into place, so a failure leaves nothing behind.
"""

from __future__ import annotations

import math
import os

# Must precede the first mujoco/dm_control import (nirl_mj's __init__ does the same).
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image, ImageDraw, ImageFont  # noqa: E402

from nirl_mj.data.atomic import AtomicFile, refuse_existing  # noqa: E402
from nirl_mj.data.features import ACTION_NAMES, FEATURE_SENSORS  # noqa: E402
from nirl_mj.data.trajectory import Trajectory  # noqa: E402
from nirl_mj.experts.policies import PolicyAgent  # noqa: E402
from nirl_mj.inspect.recording import DANGER_COLOURS  # noqa: E402
from nirl_mj.sim.arena import OFFSCREEN_SIZE  # noqa: E402
from nirl_mj.sim.display import display_available  # noqa: E402
from nirl_mj.sim.episode import run_episode  # noqa: E402
from nirl_mj.sim.spec import TaskSpec, load_task  # noqa: E402
from nirl_mj.sim.task import checked_action  # noqa: E402

CAMERAS = ("top", "follow", "chase")
"""Camera names accepted everywhere in this module (see the module docstring)."""
MAX_SIZE = OFFSCREEN_SIZE
"""Largest frame (width, height) in pixels: the arena model's offscreen buffer."""
EGL_FIX = (
    "install the system packages libegl1 libegl-mesa0 libgl1-mesa-dri (Debian/Ubuntu: "
    "sudo apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri), or set MUJOCO_GL=osmesa "
    "(needs libosmesa6) or MUJOCO_GL=glfw (needs a display) before starting"
)


def check_gl_platform() -> None:
    """Refuses, before any GL context is made, a renderer that cannot work: MUJOCO_GL=glfw without
    a display (dm_control would fail deep in mjr_makeContext and print a traceback at exit)."""
    if os.environ.get("MUJOCO_GL") == "glfw" and not display_available():
        raise RenderError("MUJOCO_GL=glfw renders through a display, and neither DISPLAY nor WAYLAND_DISPLAY "
                          "is set: unset MUJOCO_GL to render offscreen through EGL (the default), or run "
                          "under a display (xvfb-run)")  # fmt: skip


_OUTCOME_RGBA = {
    "target": (0.16, 0.67, 0.24, 1.0),
    "collision": (0.86, 0.2, 0.16, 1.0),
    "timeout": (0.9, 0.63, 0.12, 1.0),
    "physics_error": (0.6, 0.0, 0.6, 1.0),
}
_TRAIL_RGBA = (0.1, 0.35, 0.95, 1.0)
_MARKER_RGBA = (0.9, 0.1, 0.1, 1.0)
_PANEL_RGB = (32, 32, 36)  # the overlay panel beside a top view
_MAX_TRAIL = 1500  # path segments drawn into a scene at most (decimated beyond)
# Path width and marker per camera: thick enough to see at each camera's scale.
_TRAIL_RADIUS = {"top": 0.3, "follow": 0.06, "chase": 0.04}
_CHASE = {"distance": 4.0, "elevation": -22.0, "ahead": 1.0, "height": 0.2}  # metres, degrees
_EXISTS = "exists; pass --overwrite (overwrite=True) to replace it, or choose another"

Policy = Callable[[np.ndarray], int]


class RenderError(RuntimeError):
    """Rendering is impossible as asked; the message says how to fix it."""


@dataclass(frozen=True)
class VideoResult:
    """What :func:`record_video` wrote: ``frames`` frames covering ``duration`` seconds of
    simulated time at ``fps``, and the episode's trajectory."""

    path: Path
    frames: int
    duration: float
    fps: float
    trajectory: Trajectory


def check_backend() -> None:
    """Creates (and frees) a tiny OpenGL context; raises :class:`RenderError` with the fix
    if the backend in MUJOCO_GL cannot render offscreen."""
    backend = os.environ.get("MUJOCO_GL", "")
    try:
        from dm_control import _render

        context = _render.Renderer(max_width=8, max_height=8)
        context.free()
    except Exception as exc:  # noqa: BLE001 - any backend failure gets the same advice
        raise RenderError(f"no usable OpenGL backend for offscreen rendering (MUJOCO_GL={backend}: "
                          f"{type(exc).__name__}: {exc}); {EGL_FIX}") from None  # fmt: skip


def check_frame(camera: str, width: int, height: int) -> None:
    """Raises :class:`RenderError` for an unknown camera or a frame size out of range."""
    if camera not in CAMERAS:
        raise RenderError(f"unknown camera {camera!r}; accepted: {', '.join(CAMERAS)}")
    if not (16 <= width <= MAX_SIZE[0] and 16 <= height <= MAX_SIZE[1]) or width % 2 or height % 2:
        raise RenderError(
            f"frame {width}x{height}: width and height must be even, 16..{MAX_SIZE[0]} x 16..{MAX_SIZE[1]} "
            "pixels (the offscreen buffer of the arena model; MP4 needs even sizes)"
        )


def arena_box(camera: str, width: int, height: int) -> tuple[int, int, int, int]:
    """Where the scene lies in a ``width`` x ``height`` frame, (x0, y0, x1, y1) pixels. The top camera
    sees the square arena, so it gets a square (the arena fills it; the frame's rest, right of it
    or below it, is the overlay panel); the other cameras fill the frame."""
    if camera != "top":
        return 0, 0, width, height
    side = min(width, height)
    return 0, 0, side, side


def panel_box(camera: str, width: int, height: int) -> tuple[int, int, int, int] | None:
    """The part of the frame beside the arena that holds the overlay, or None (a square top view,
    another camera: the overlay then sits semi-transparent in the top-left corner)."""
    x0, y0, x1, y1 = arena_box(camera, width, height)
    if x1 < width:
        return x1, 0, width, height
    if y1 < height:
        return 0, y1, width, height
    return None


class View:
    """Renders the current state of ``env`` from ``camera`` (``CAMERAS``) as (height, width, 3)
    uint8 arrays, with ``trail`` (N, 2) world metres drawn as the path so far. The scene fills
    :func:`arena_box`; the rest of the frame (``panel``, :func:`panel_box`) is dark grey."""

    def __init__(self, env: Any, camera: str, width: int, height: int) -> None:
        check_frame(camera, width, height)
        check_gl_platform()
        from dm_control.mujoco import engine

        self._env, self._camera = env, camera
        self.size = (width, height)
        self.box = arena_box(camera, width, height)
        self.panel = panel_box(camera, width, height)
        width, height = self.box[2] - self.box[0], self.box[3] - self.box[1]
        physics = env.physics
        max_geom = 2 * physics.model.ngeom + physics.model.nsite + _MAX_TRAIL + 20
        try:
            if camera == "chase":
                self._cam = engine.MovableCamera(physics, height, width, max_geom=max_geom,
                                                 scene_callback=self._decorate)  # fmt: skip
            else:
                name = "overview" if camera == "top" else "robotino/top"
                self._cam = engine.Camera(physics, height, width, name, max_geom=max_geom,
                                          scene_callback=self._decorate)  # fmt: skip
        except Exception as exc:  # noqa: BLE001 - a GL failure surfaces here first
            raise RenderError(f"cannot create an offscreen {width}x{height} renderer "
                              f"({type(exc).__name__}: {exc}); {EGL_FIX}") from None  # fmt: skip
        self.trail = np.zeros((0, 2))
        self.trail_rgba = _TRAIL_RGBA

    def pose(self) -> tuple[float, float, float]:
        """The robot's (x, y, yaw) as the scene shows it, metres and radians.

        Read from the body's derived position, like the rest of the scene: between the
        substeps of a decision that is one physics step (<= 10 ms) behind ``data.time``.
        Recomputing it (``mj_kinematics``) would change what the task's next arrival
        check reads, and so could change the episode.
        """
        body = self._env.physics.bind(self._env.task.robot.base_body)
        xmat = body.xmat
        return float(body.xpos[0]), float(body.xpos[1]), math.atan2(xmat[3], xmat[0])

    def render(self) -> np.ndarray:
        """The current frame, (height, width, 3) uint8 (a copy)."""
        if self._camera == "chase":
            x, y, yaw = self.pose()
            ahead = _CHASE["ahead"]
            lookat = (x + ahead * math.cos(yaw), y + ahead * math.sin(yaw), _CHASE["height"])
            self._cam.set_pose(lookat, _CHASE["distance"], math.degrees(yaw), _CHASE["elevation"])
        scene = self._cam.render()
        if self.panel is None:
            return np.array(scene)
        frame = np.full((self.size[1], self.size[0], 3), _PANEL_RGB, np.uint8)
        x0, y0, x1, y1 = self.box
        frame[y0:y1, x0:x1] = scene
        return frame

    def scene(self) -> np.ndarray:
        """The current frame without its panel: the square arena of a top view (montages tile these)."""
        x0, y0, x1, y1 = self.box
        return self.render()[y0:y1, x0:x1]

    def _decorate(self, physics: Any, scene: mujoco.MjvScene) -> None:
        """Adds the path so far (and, seen from the top, the robot marker) to the scene."""
        scene = getattr(scene, "ptr", scene)  # dm_control passes its wrapper; geoms live in the MjvScene
        x, y, yaw = self.pose()
        points = np.vstack([self.trail, [(x, y)]]) if len(self.trail) else np.array([(x, y)])
        if len(points) > _MAX_TRAIL + 1:
            points = points[np.linspace(0, len(points) - 1, _MAX_TRAIL + 1).round().astype(int)]
        radius = _TRAIL_RADIUS[self._camera]
        for a, b in zip(points[:-1], points[1:], strict=True):
            _add_capsule(scene, a, b, radius, self.trail_rgba, z=0.02)
        if self._camera == "top":
            _add_disc(scene, (x, y), 0.8, _MARKER_RGBA, z=1.2)
            tip = (x + 2.0 * math.cos(yaw), y + 2.0 * math.sin(yaw))
            _add_capsule(scene, (x, y), tip, 0.25, _MARKER_RGBA, z=1.25)


def _new_geom(scene: mujoco.MjvScene) -> Any | None:
    if scene.ngeom >= scene.maxgeom:
        return None  # the scene is full: draw less rather than fail
    scene.ngeom += 1  # first: ``geoms`` lists only the first ``ngeom`` entries
    return scene.geoms[scene.ngeom - 1]


def _add_capsule(scene: mujoco.MjvScene, a: Sequence[float], b: Sequence[float], radius: float,
                 rgba: Sequence[float], z: float) -> None:  # fmt: skip
    """A capsule of ``radius`` metres from ``a`` to ``b`` (x, y metres) at height ``z``."""
    if math.hypot(b[0] - a[0], b[1] - a[1]) < 1e-6:
        return
    geom = _new_geom(scene)
    if geom is None:
        return
    mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                        np.asarray(rgba, dtype=np.float32))  # fmt: skip
    mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, radius, np.array([a[0], a[1], z]),
                         np.array([b[0], b[1], z]))  # fmt: skip


def _add_disc(scene: mujoco.MjvScene, centre: Sequence[float], radius: float, rgba: Sequence[float],
              z: float) -> None:  # fmt: skip
    geom = _new_geom(scene)
    if geom is None:
        return
    mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_CYLINDER, np.array([radius, radius, 0.02]),
                        np.array([centre[0], centre[1], z]), np.eye(3).ravel(),
                        np.asarray(rgba, dtype=np.float32))  # fmt: skip


# -- overlays --------------------------------------------------------------------------


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError):  # Pillow without FreeType: a fixed bitmap font
        return ImageFont.load_default()


def draw_overlay(
    frame: np.ndarray,
    lines: Sequence[str],
    phi: np.ndarray | None,
    box: tuple[int, int, int, int] | None = None,
) -> np.ndarray:
    """``frame`` (H, W, 3) uint8 with one block of ``lines`` of text and, from phi(s) (16,), the
    seven danger levels as bars (height and colour by level 0..7), V and I below them.

    The block goes into ``box`` (x0, y0, x1, y1 pixels: the panel beside a top view, which holds
    nothing else) or, without one, semi-transparent into the top-left corner: in a top view that
    corner holds neither the start (bottom left) nor the target (top right)."""
    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image, "RGBA")

    def extent(size: int) -> tuple[float, float]:
        """The block's width and height (pixels) in a font of ``size`` pixels."""
        text_w = max((draw.textlength(t, font=_font(size)) for t in lines), default=0)
        width = max(text_w, 7 * (size + 4) if phi is not None else 0) + 2 * (size // 2)
        height = len(lines) * (size + 4) + (3 * size + 3 * (size + 4) + size // 2 if phi is not None else 0)
        return width, height + size // 2

    size = max(10, frame.shape[0] // 32)
    if box is not None:  # as large as the frame suggests, as small as the panel needs (down to 6 px)

        def fits(s: int) -> bool:
            width, height = extent(s)
            return width <= box[2] - box[0] and height <= box[3] - box[1]

        size = next((s for s in range(size, 5, -1) if fits(s)), None)
        if size is None:  # a panel too small for it: the corner of the frame instead
            box, size = None, next((s for s in range(10, 5, -1) if extent(s)[0] <= frame.shape[1]), 6)
    font = _font(size)
    pad = size // 2
    line_h = size + 4
    left, top = (box[0], box[1]) if box else (0, 0)
    bar_w, bar_h = size, 3 * size
    width, height = extent(size)
    if box is None and (lines or phi is not None):
        draw.rectangle((left, top, left + width, top + height), fill=(0, 0, 0, 150))
    for i, text in enumerate(lines):
        draw.text((left + pad, top + pad // 2 + i * line_h), text, fill=(255, 255, 255), font=font)
    if phi is not None:
        y = top + len(lines) * line_h + pad
        draw.text((left + pad, y), "danger", fill=(255, 255, 255), font=font)
        base = y + line_h + bar_h
        for k, sensor in enumerate(FEATURE_SENSORS):
            level = int(phi[k])
            x0 = left + pad + k * (bar_w + 4)
            fill = tuple(int(c) for c in DANGER_COLOURS[level])
            draw.rectangle((x0, base - max(2, bar_h * level // 7), x0 + bar_w, base), fill=fill)
            draw.text((x0, base + 2), f"{sensor + 1}", fill=(255, 255, 255), font=font)
        text = f"V={int(phi[7])} I={int(phi[8])}"
        draw.text((left + pad, base + line_h + 2), text, fill=(255, 255, 255), font=font)
    return np.asarray(image)


def _label(frame: np.ndarray, text: str) -> np.ndarray:
    """``frame`` with one line of text in a dark band at the top."""
    return draw_overlay(frame, [text], None)


# -- episodes --------------------------------------------------------------------------


def record_video(
    task: str | TaskSpec | Any,
    policy: Policy,
    seed: int,
    out: str | os.PathLike,
    camera: str = "top",
    width: int = 640,
    height: int = 480,
    fps: float = 10.0,
    overlay: bool = True,
    overwrite: bool = False,
) -> VideoResult:
    """Renders one episode of ``policy`` (on phi(s)) in the arena of ``seed`` to an MP4 at ``out``.

    ``task`` is a task name, path or TaskSpec, or an environment from ``make_env`` (re-used).
    ``fps`` frames per second of simulated time (at most 1 / command period); the video plays at
    real time. Written to a temporary file next to ``out`` and renamed into place.
    """
    import imageio.v2 as imageio

    out = Path(out)
    check_frame(camera, width, height)
    env = _ready_env(task)
    check_fps(fps, env.task.spec.control.command_period)
    # ffmpeg picks the container by the file name: the temporary file ends in .mp4 too.
    with AtomicFile(out, ".mp4", overwrite, _EXISTS) as target:
        view = View(env, camera, width, height)
        writer = imageio.get_writer(
            target.tmp, format="FFMPEG", mode="I", fps=fps, codec="libx264", quality=8,
            pixelformat="yuv420p", macro_block_size=2, ffmpeg_log_level="error",
        )  # fmt: skip
        try:
            episode = _VideoEpisode(env, view, writer, fps, overlay, policy)
            trajectory = episode.run(seed)
        finally:
            writer.close()
    return VideoResult(out, episode.frames, episode.end_time, fps, trajectory)


class _VideoEpisode:
    """One episode of ``policy`` with frames captured at multiples of 1/fps seconds of simulated
    time: the agent of :func:`run_episode` (it notes each action for the overlay) and its step hook;
    within a decision, frames come through the task's ``command_hook``."""

    kind = "policy"

    def __init__(self, env: Any, view: View, writer: Any, fps: float, overlay: bool, policy: Policy) -> None:
        self.env, self.view, self.writer, self.fps, self.overlay = env, view, writer, fps, overlay
        self.policy = policy
        self.frames = 0
        self.end_time = 0.0
        self._last_time = -1.0
        self._step = 0
        self._action: int | None = None
        self._phi: np.ndarray | None = None
        self._outcome = ""
        self._trail: list[np.ndarray] = []

    def run(self, seed: int) -> Trajectory:
        """Runs and captures the episode in the arena of ``seed``; returns its trajectory."""
        try:
            trajectory = run_episode(self.env, self, seed, self._on_step)
        finally:
            self.env.task.command_hook = None
        self._outcome = trajectory.outcome
        self._action = None
        self._capture(force=True)  # the final state, with the outcome
        self.end_time = float(self.env.physics.data.time)
        return trajectory

    def reset(self, env: Any, timestep: Any) -> None:
        pass

    def act(self, timestep: Any) -> int:
        # checked before it labels a frame: a bad action is the environment's clear error, not a label's
        self._action = checked_action(self.policy(timestep.observation["features"]))
        # the frame at a decision: state s_k beside the action a_k chosen there (as Rerun logs them)
        self._capture()
        return self._action

    def _on_step(self, step: int, timestep: Any, action: int | None) -> None:
        self._trail.append(timestep.observation["pose"][:2].copy())
        self._phi = timestep.observation["features"]
        self._step = step
        self.view.trail = np.asarray(self._trail)
        if step == 0:  # frames between decisions: during a_k, from the physics steps
            self.env.task.command_hook = lambda physics: self._capture()

    def _capture(self, force: bool = False) -> None:
        now = float(self.env.physics.data.time)
        due = self.frames / self.fps - 1e-9  # nominal time of the next frame
        if now <= self._last_time or (now < due and not force):
            return
        frame = self.view.render()
        if self.overlay:
            what = ACTION_NAMES[self._action] if self._action is not None else self._outcome
            # Short lines: they fit the panel beside a top view of a 4:3 frame (a quarter of its width).
            frame = draw_overlay(
                frame, [f"t {now:.2f} s", f"step {self._step}", what], self._phi, self.view.panel
            )
        self.writer.append_data(frame)
        self.frames += 1
        self._last_time = now


def _ready_env(task: str | TaskSpec | Any) -> Any:
    """An environment for ``task`` (a name, path or TaskSpec; an environment is re-used), reset
    once: composer compiles the physics at the first reset, and cameras must bind to that one."""
    from nirl_mj.sim.task import make_env

    env = task if hasattr(task, "physics") else make_env(load_task(task))
    env.reset()
    return env


def _save_png(image: np.ndarray, out: Path, overwrite: bool) -> Path:
    with AtomicFile(out, ".png", overwrite, _EXISTS) as target:
        Image.fromarray(image).save(target.tmp, format="PNG")
    return out


def _tile(images: Sequence[np.ndarray], columns: int, gap: int = 4) -> np.ndarray:
    """Images of one size on a white grid, ``columns`` per row."""
    h, w, _ = images[0].shape
    rows = math.ceil(len(images) / columns)
    sheet = np.full((rows * h + (rows - 1) * gap, columns * w + (columns - 1) * gap, 3), 255, np.uint8)
    for k, image in enumerate(images):
        r, c = divmod(k, columns)
        sheet[r * (h + gap) : r * (h + gap) + h, c * (w + gap) : c * (w + gap) + w] = image
    return sheet


MONTAGE_SNAPSHOTS, PATHS_ARENAS = 5, 4
"""The defaults of ``render --montage``'s frames and ``render --paths``' arenas."""


def check_snapshots(snapshots: int) -> None:
    """Raises :class:`RenderError` for a strip of fewer than two frames (``snapshot_strip``'s
    ``snapshots``, ``render --snapshots``)."""
    if snapshots < 2:
        raise RenderError(f"snapshots must be >= 2 (the first and the last frame at least), got {snapshots}")


def check_fps(fps: float, period: float) -> None:
    """Raises :class:`RenderError` for a video frame rate that is not > 0 and at most one frame per
    command ``period`` (seconds)."""
    if not 0 < fps <= 1.0 / period + 1e-9:
        raise RenderError(
            f"fps {fps:g}: must be > 0 and at most {1.0 / period:g} (one frame per command period)"
        )


def snapshot_strip(
    task: str | TaskSpec | Any,
    policy: Policy,
    seed: int,
    out_png: str | os.PathLike,
    snapshots: int = MONTAGE_SNAPSHOTS,
    camera: str = "top",
    width: int = 480,
    height: int = 360,
    overwrite: bool = False,
) -> Path:
    """Writes a PNG strip of ``snapshots`` frames of one episode (the paper's Fig. 8).

    Args:
        task: task name, TOML path or TaskSpec (e.g. ``"dynamic"``: moving obstacles show
            where they were at each snapshot), or an environment from ``make_env`` (re-used).
        policy: phi(s) (16,) -> action index 0..5, e.g. ``load_policy(run_dir)[0]``.
        seed: the arena seed (e.g. a held-out test seed, ``evaluate.held_out_seeds``).
        out_png: where to write the PNG (atomically).
        snapshots: frames, evenly spaced over the episode's decisions, first and last included.
        camera: one of ``CAMERAS``; ``"top"`` shows the whole arena.
        width, height: pixels of one frame (even, at most 1280 x 960); the strip is
            ``snapshots`` frames (fewer in an episode of fewer decisions) side by side with
            4-pixel gaps. A top view's frame is the arena's square, min(width, height) on a side.
        overwrite: replace an existing ``out_png`` (False: FileExistsError).

    Each frame shows the path driven so far and is labelled with its time, decision index and,
    on the last, the outcome. The episode is run twice (it is deterministic given ``seed``):
    once to learn its length, once to render the chosen decisions. Returns the PNG's path.
    """
    check_frame(camera, width, height)
    check_snapshots(snapshots)
    out = Path(out_png)
    refuse_existing(out, overwrite, _EXISTS)
    env = _ready_env(task)
    agent = PolicyAgent(policy, "policy")
    length = len(run_episode(env, agent, seed))
    wanted = sorted(set(np.linspace(0, length, snapshots).round().astype(int).tolist()))
    view = View(env, camera, width, height)
    trail: list[np.ndarray] = []
    images: list[np.ndarray] = []

    def on_step(step: int, timestep: Any, action: int | None) -> None:
        trail.append(timestep.observation["pose"][:2].copy())
        view.trail = np.asarray(trail)
        if step in wanted:
            text = f"t = {env.physics.data.time:.1f} s (step {step})"
            if timestep.last():
                from nirl_mj.sim.task import Outcome

                text += f": {Outcome(int(timestep.observation['outcome'][0])).name.lower()}"
            images.append(_label(view.scene(), text))

    run_episode(env, agent, seed, on_step)
    return _save_png(_tile(images, len(images)), out, overwrite)


def paths_montage(
    task: str | TaskSpec | Any,
    policy: Policy,
    seeds: Sequence[int],
    out_png: str | os.PathLike,
    camera: str = "top",
    width: int = 480,
    height: int = 360,
    columns: int | None = None,
    overwrite: bool = False,
    first_index: int = 0,
) -> Path:
    """Writes a PNG of ``policy``'s whole path in each arena of ``seeds`` (the paper's Fig. 5):
    the final state from ``camera`` with the path coloured by outcome (green target, red
    collision, orange timeout), labelled with the arena's index (``first_index`` for the first of
    ``seeds``: ``render --episode K`` labels test arenas K, K+1, ...), outcome and decisions; up to
    ``columns`` (default: at most 4) frames per row. Returns the PNG's path."""
    check_frame(camera, width, height)
    if not seeds:
        raise RenderError("paths_montage needs at least one arena seed")
    out = Path(out_png)
    refuse_existing(out, overwrite, _EXISTS)
    env = _ready_env(task)
    view = View(env, camera, width, height)
    agent = PolicyAgent(policy, "policy")
    images = []
    for k, seed in enumerate(seeds):
        trajectory = run_episode(env, agent, seed)
        view.trail = trajectory.poses[:-1, :2]
        view.trail_rgba = _OUTCOME_RGBA[trajectory.outcome]
        text = f"arena {first_index + k}: {trajectory.outcome}, {len(trajectory)} steps"
        images.append(_label(view.scene(), text))
    return _save_png(_tile(images, columns or min(4, len(images))), out, overwrite)
