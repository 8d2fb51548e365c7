"""Offscreen videos and montages: frames, sizes, motion, honest timing, and errors that leave nothing."""

import math
import os
import subprocess
import sys

import imageio.v3 as iio
import numpy as np
import pytest

from nirl_mj.cli import main
from nirl_mj.experts.policies import PolicyAgent, rule_policy
from nirl_mj.inspect.video import (
    RenderError,
    arena_box,
    check_frame,
    draw_overlay,
    panel_box,
    paths_montage,
    record_video,
    snapshot_strip,
)
from nirl_mj.sim import spec as specs
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import make_env


def tiny_task(moving: int = 0) -> specs.TaskSpec:
    """A 30 m arena with 3 static obstacles, planar drive: ~30 decisions of the rule policy."""
    return specs.replace(
        specs.load_task("navigate"),
        arena={"size": [30.0, 30.0], "start": [5.0, 5.0], "target": [25.0, 25.0], "static_obstacles": 3,
               "moving_obstacles": moving},
        robot={"drive": "planar"},
    )  # fmt: skip


@pytest.mark.parametrize(("camera", "overlay"), [("top", False), ("chase", True)])
def test_video_frames_size_motion_and_timing(tmp_path, camera, overlay):
    task, fps = tiny_task(), 4.0
    out = tmp_path / "episode.mp4"
    result = record_video(task, rule_policy, 7, out, camera, width=160, height=120, fps=fps, overlay=overlay)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["episode.mp4"]  # no temporary file left
    frames = iio.imread(out)
    assert frames.shape == (result.frames, 120, 160, 3)
    # A frame at each multiple of 1/fps up to the end, plus the final state unless it fell on one.
    nominal = math.floor(result.duration * fps + 1e-9) + 1
    assert result.frames in (nominal, nominal + 1) and result.frames > 10
    assert result.duration == pytest.approx(result.trajectory.times[-1], abs=0.5)
    # The robot moved: from the top its marker and path, from behind it the whole view.
    changed = np.abs(frames[0].astype(int) - frames[-1].astype(int)).max(axis=-1) > 40
    assert changed.mean() > (0.005 if camera == "top" else 0.2)
    # Rendering (which runs every decision command by command) does not change the episode.
    plain = run_episode(make_env(task), PolicyAgent(rule_policy, "rule"), 7)
    np.testing.assert_array_equal(result.trajectory.poses, plain.poses)
    np.testing.assert_array_equal(result.trajectory.actions, plain.actions)


def test_a_frame_at_a_decision_names_the_action_chosen_there(tmp_path, monkeypatch):
    """One frame per decision (fps = 1 / period): frame k shows step k, phi(s_k) and a_k, as the Rerun
    recording pairs them; the last frame the outcome."""
    from nirl_mj.data.features import ACTION_NAMES
    from nirl_mj.inspect import video

    shown = []

    def spy(frame, lines, phi, box=None):
        shown.append((list(lines), None if phi is None else np.array(phi)))
        return frame

    monkeypatch.setattr(video, "draw_overlay", spy)
    task = tiny_task()
    result = record_video(task, rule_policy, 7, tmp_path / "e.mp4", "top", 160, 120, fps=2.0, overlay=True)
    t = result.trajectory
    assert len(shown) == len(t) + 1
    for k, (lines, phi) in enumerate(shown[:-1]):
        assert lines[1:] == [f"step {k}", ACTION_NAMES[int(t.actions[k])]], (k, lines)
        np.testing.assert_array_equal(phi, t.features[k])
    assert shown[-1][0][2] == t.outcome


def test_a_policy_s_bad_action_is_the_environment_s_error_and_leaves_no_video(tmp_path):
    with pytest.raises(ValueError, match=r"action must be one integer in 0\.\.5"):
        record_video(tiny_task(), lambda phi: 6, 7, tmp_path / "e.mp4", "top", 160, 120, fps=2.0)
    assert not list(tmp_path.iterdir())


def test_the_follow_camera_looks_straight_down_with_north_up():
    # as the top view and Rerun's arena show it: image right is east (+x), image up is north (+y)
    import mujoco

    env = make_env(tiny_task(), seed=0)
    env.reset()
    physics = env.physics
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    axes = physics.data.cam_xmat[physics.model.name2id("robotino/top", "camera")].reshape(3, 3)
    np.testing.assert_allclose(axes.T, np.eye(3), atol=1e-9)  # rows: right, up, backwards (+z)


def test_overlay_draws_text_and_danger_bars():
    frame = np.full((480, 640, 3), 128, np.uint8)
    phi = np.array([0, 1, 2, 3, 5, 6, 7, 3, 1, 0, 0, 0, 0, 0, 0, 0], np.float32)
    drawn = draw_overlay(frame, ["t 1.00 s", "step 2", "forward"], phi)
    assert drawn.shape == frame.shape
    changed = np.abs(drawn.astype(int) - frame).max(axis=-1) > 0
    assert changed[:20, :40].any()  # one block in the top-left corner
    assert not changed[-150:, :].any()  # the bottom left, where a top view has the start, stays clear
    assert not changed[:, 200:].any()
    bars = draw_overlay(frame, [], phi)
    assert not np.array_equal(bars, draw_overlay(frame, [], np.zeros(16, np.float32)))


def test_top_view_keeps_the_arena_clear_of_overlays():
    # The square arena fills a square of the frame, the overlay panel takes the rest.
    assert arena_box("top", 640, 480) == (0, 0, 480, 480) and panel_box("top", 640, 480) == (480, 0, 640, 480)
    assert panel_box("top", 480, 640) == (0, 480, 480, 640)
    assert panel_box("top", 480, 480) is None and panel_box("chase", 640, 480) is None
    assert arena_box("chase", 640, 480) == (0, 0, 640, 480)
    frame = np.zeros((480, 640, 3), np.uint8)
    phi = np.full(16, 7, np.float32)
    drawn = draw_overlay(frame, ["t 12.50 s", "step 25", "right60"], phi, panel_box("top", 640, 480))
    changed = drawn.max(axis=-1) > 0
    assert not changed[:, :480].any()  # nothing on the arena
    columns = np.flatnonzero(changed.any(axis=0))
    assert columns.min() >= 480 and columns.max() < 640  # text and all seven bars fit the panel
    assert changed[:, 480:].sum() > 500


@pytest.mark.parametrize("width, height", [(480, 640), (320, 240), (640, 480), (1280, 960)])
def test_the_overlay_fits_its_panel_whatever_the_frame(width, height):
    """Sized from the panel, not from the frame's height alone: all seven bars and V, I inside it (a
    level-7 bar is the danger colour 7; V and I the lowest text)."""
    from nirl_mj.inspect.video import DANGER_COLOURS

    box = panel_box("top", width, height)
    frame = np.zeros((height, width, 3), np.uint8)
    drawn = draw_overlay(frame, ["t 12.50 s", "step 25", "right60"], np.full(16, 7, np.float32), box)
    changed = drawn.max(axis=-1) > 0
    x0, y0, x1, y1 = box
    assert not changed.sum() - changed[y0:y1, x0:x1].sum()  # nothing outside the panel
    red = np.all(drawn == np.asarray(DANGER_COLOURS[7], np.uint8), axis=-1)
    bar_columns = np.flatnonzero(red.any(axis=0))
    # seven separate bars: six gaps between runs of bar columns
    assert (np.diff(bar_columns) > 1).sum() == 6, bar_columns
    rows = np.flatnonzero(changed.any(axis=1))
    assert rows.max() > np.flatnonzero(red.any(axis=1)).max() + 5  # the labels and V, I below the bars


def test_a_panel_too_small_for_the_overlay_gives_the_corner_instead():
    frame = np.zeros((120, 160, 3), np.uint8)  # the panel beside the arena: 40 px wide
    drawn = draw_overlay(frame, ["t 1.00 s", "step 2", "forward"], np.full(16, 7, np.float32),
                         panel_box("top", 160, 120))  # fmt: skip
    from nirl_mj.inspect.video import DANGER_COLOURS

    red = np.all(drawn == np.asarray(DANGER_COLOURS[7], np.uint8), axis=-1)
    assert (np.diff(np.flatnonzero(red.any(axis=0))) > 1).sum() == 6  # all seven bars


def test_snapshot_strip_and_paths_montage(tmp_path):
    env = make_env(tiny_task(moving=3))
    strip = snapshot_strip(env, rule_policy, 1, tmp_path / "strip.png", snapshots=3, width=160, height=120)
    image = iio.imread(strip)
    assert image.shape == (120, 3 * 120 + 2 * 4, 3)  # a top view's frame: the arena's square
    assert image.std() > 20  # not blank
    tiles = [image[:, k * 124 : k * 124 + 120].astype(int) for k in range(3)]
    assert np.abs(tiles[0] - tiles[2]).mean() > 1.0  # time passes between snapshots
    montage = paths_montage(env, rule_policy, [1, 2], tmp_path / "paths.png", width=160, height=120)
    image = iio.imread(montage)
    assert image.shape == (120, 2 * 120 + 4, 3) and image.std() > 20
    assert sorted(p.name for p in tmp_path.iterdir()) == ["paths.png", "strip.png"]


def test_bad_requests_are_refused(tmp_path, capsys):
    task = tmp_path / "tiny.toml"
    task.write_text('[arena]\nsize = [30.0, 30.0]\nstart = [5.0, 5.0]\ntarget = [25.0, 25.0]\n'
                    'static_obstacles = 3\n[robot]\ndrive = "planar"\n')  # fmt: skip
    base = ["render", "--policy", "rule", "--task", str(task)]
    existing = tmp_path / "old.mp4"
    existing.write_bytes(b"keep me")
    cases = {
        "exists; pass --overwrite": ["--out", str(existing)],
        "unknown camera 'side'": ["--out", str(tmp_path / "a.mp4"), "--camera", "side"],
        "does not exist": ["--out", str(tmp_path / "missing" / "a.mp4")],
        "must be even": ["--out", str(tmp_path / "a.mp4"), "--width", "161"],
        "nothing to write": [],
        "a.png: --out writes .mp4 (for example a.mp4)": ["--out", str(tmp_path / "a.png")],
        "s.mp4: --montage writes .png": ["--montage", str(tmp_path / "s.mp4")],
    }
    for message, extra in cases.items():
        assert main([*base, *extra]) == 2, message
        assert message in capsys.readouterr().err
    # refused up front: the one error line, no header line naming the arena before it
    early = {
        "snapshots must be >= 2 (the first and the last frame at least), got 1": [
            "--montage", str(tmp_path / "s.png"), "--snapshots", "1"],
        "fps 1000: must be > 0 and at most": ["--out", str(tmp_path / "a.mp4"), "--fps", "1000"],
    }  # fmt: skip
    for message, extra in early.items():
        assert main([*base, *extra]) == 2, message
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1 and "arena seed" not in err, err
    assert existing.read_bytes() == b"keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.mp4", "tiny.toml"]
    with pytest.raises(RenderError, match="unknown camera"):
        check_frame("side", 160, 120)
    with pytest.raises(RenderError, match="16..1280 x 16..960"):
        check_frame("top", 2000, 120)
    with pytest.raises(RenderError, match=r"snapshots must be >= 2 \(the first and the last frame"):
        snapshot_strip("navigate", rule_policy, 1, tmp_path / "one.png", snapshots=1)
    assert not (tmp_path / "one.png").exists()


def test_unwritable_directory_is_refused(tmp_path, capsys, monkeypatch):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    if os.geteuid() == 0:  # root writes anywhere: the operating system's answer is simulated
        real_access = os.access
        monkeypatch.setattr(os, "access", lambda p, mode, **k: str(p) != str(locked) and real_access(p, mode))
    assert main(["render", "--policy", "rule", "--out", str(locked / "a.mp4")]) == 2
    assert "not writable" in capsys.readouterr().err and not list(locked.iterdir())


def test_without_an_opengl_backend_the_fix_is_named(tmp_path):
    # MUJOCO_GL=disable: dm_control imports, every rendering context fails, as with a missing libEGL.
    env = {**os.environ, "MUJOCO_GL": "disable", "PYOPENGL_PLATFORM": "egl"}
    out = tmp_path / "a.mp4"
    done = subprocess.run([sys.executable, "-m", "nirl_mj.cli", "render", "--policy", "forward", "--out",
                           str(out)], env=env, capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert "libegl1 libegl-mesa0 libgl1-mesa-dri" in done.stderr and "MUJOCO_GL=osmesa" in done.stderr
    assert list(tmp_path.iterdir()) == []


def test_osmesa_without_its_library_is_named_at_import_not_deep_in_pyopengl():
    import ctypes.util

    if ctypes.util.find_library("OSMesa") is not None:
        pytest.skip("OSMesa is installed here: nothing to name")
    env = {**os.environ, "MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": "osmesa"}
    done = subprocess.run([sys.executable, "-c", "import nirl_mj"], env=env, capture_output=True, text=True)
    assert done.returncode == 1
    assert done.stderr.strip().splitlines()[-1] == (
        "ImportError: MUJOCO_GL=osmesa, but no OSMesa library is installed: install it (Debian: sudo "
        "apt-get install libosmesa6), or unset MUJOCO_GL to render offscreen through EGL (the default)"
    )


def test_glfw_without_a_display_is_refused_before_any_gl_context(monkeypatch):
    """dm_control would fail deep in mjr_makeContext (and print a traceback at exit): one line instead."""
    from nirl_mj.inspect.video import RenderError, check_gl_platform

    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setenv("MUJOCO_GL", "glfw")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RenderError, match="neither DISPLAY nor WAYLAND_DISPLAY is set: unset MUJOCO_GL"):
        check_gl_platform()
    monkeypatch.setenv("DISPLAY", ":0")
    check_gl_platform()  # a display: left to GLFW
    monkeypatch.setenv("MUJOCO_GL", "egl")
    monkeypatch.delenv("DISPLAY")
    check_gl_platform()  # offscreen: needs none
