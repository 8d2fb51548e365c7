"""Offscreen rendering speed, and what a Rerun recording adds to training.

1. Rendering: per camera (top, follow, chase) at 640x480 on tasks/navigate.toml
   (100 m arena, 20 obstacles; EGL through Mesa on the CPU), one frame per
   decision of the rule policy: the time of a frame's render (``View.render``:
   scene update + GL draw + read-back), of its overlay (Pillow) and of its MP4
   encoding (imageio-ffmpeg, libx264), and the resulting frames per second.
2. Training with ``--rerun``: the same short NIRL training (default variant,
   ``--episodes`` iterations, 10 sensor-expert demonstrations, planar training
   drive) without and with a recording, interleaved; the time spent inside the
   recording calls (per-iteration scalars, then demonstrations with r_theta and
   the reward map at the end) is timed directly, since wall-time differences of
   a few % drown in this machine's +-30 % drift. Without ``--rerun`` no
   recording object exists; a subprocess runs a one-iteration ``nirl-mj train`` without
   ``--rerun`` and reports whether ``rerun`` was imported (it is: the command line imports
   ``inspect.recording`` at start-up).

Writes docs/PERFORMANCE.md.

    python bench/bench_render.py [--frames 40] [--episodes 6]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from nirl_mj.inspect.video import View, draw_overlay
from nirl_mj.sim.spec import load_task
from nirl_mj.sim.task import make_env

try:
    from report import markdown_table, write_section
except ImportError:  # run as a module
    from bench.report import markdown_table, write_section


def measure_camera(camera: str, frames: int, width: int = 640, height: int = 480) -> dict:
    """Mean ms per frame for render, overlay and encoding, over ``frames`` decisions."""
    import imageio.v2 as imageio

    from nirl_mj.experts.policies import rule_policy

    env = make_env(load_task("navigate"), seed=0)
    timestep = env.reset()
    view = View(env, camera, width, height)
    view.render()  # the first frame allocates GL buffers
    times = {"render": 0.0, "overlay": 0.0, "encode": 0.0}
    with tempfile.TemporaryDirectory() as tmp:
        writer = imageio.get_writer(Path(tmp) / "x.mp4", format="FFMPEG", fps=10, codec="libx264", quality=8,
                                    pixelformat="yuv420p", macro_block_size=2)  # fmt: skip
        trail = []
        for _ in range(frames):
            if timestep.last():
                timestep = env.reset()
                trail = []
            phi = timestep.observation["features"]
            trail.append(timestep.observation["pose"][:2].copy())
            view.trail = np.asarray(trail)
            t0 = time.perf_counter()
            frame = view.render()
            t1 = time.perf_counter()
            frame = draw_overlay(frame, ["t 12.50 s  step 25", "forward"], phi)
            t2 = time.perf_counter()
            writer.append_data(frame)
            t3 = time.perf_counter()
            times["render"] += t1 - t0
            times["overlay"] += t2 - t1
            times["encode"] += t3 - t2
            timestep = env.step(rule_policy(phi))
        writer.close()
    ms = {k: 1e3 * v / frames for k, v in times.items()}
    return {"camera": camera, **ms, "fps": 1e3 / sum(ms.values()), "render_fps": 1e3 / ms["render"]}


class _TimedRecording:
    """Wraps a Recording and adds up the time spent in it."""

    def __init__(self, recording) -> None:
        self.recording, self.seconds, self.calls = recording, 0.0, 0

    def training(self, rows) -> None:
        t0 = time.perf_counter()
        self.recording.training(rows)
        self.seconds += time.perf_counter() - t0
        self.calls += 1


def train_once(demos: Path, out: Path, episodes: int, record: bool) -> dict:
    """One training run; with ``record`` the CLI's recording path (per-iteration scalars, then
    ``finish_training``). Returns wall seconds of training and of the recording's parts."""
    from nirl_mj.experiments.training import train
    from nirl_mj.learn.config import LearnerConfig

    spec = load_task("navigate")
    config = LearnerConfig.preset("default", episodes=episodes)
    timed = None
    if record:
        from nirl_mj.inspect.recording import Recording

        timed = _TimedRecording(Recording(out.with_suffix(".rrd"), overwrite=True))
    t0 = time.perf_counter()
    train(out, spec, demos, config, 0, False, (lambda m: timed.training([vars(m)])) if timed else None)
    t1 = time.perf_counter()
    result = {"train": t1 - t0, "per_iteration_log": 0.0, "finish": 0.0}
    if timed:
        from nirl_mj.inspect.recording import finish_training

        finish_training(timed.recording, out, demos)
        result["per_iteration_log"] = timed.seconds / max(timed.calls, 1)
        result["logged"] = timed.seconds
        result["finish"] = time.perf_counter() - t1
    return result


def rerun_imported_without_flag(tmp: Path, demos: Path) -> bool:
    """Runs ``nirl-mj train`` without ``--rerun`` (1 iteration) in a fresh process; True if that
    process imported rerun."""
    code = (
        "import sys; from nirl_mj.cli import main; "
        f"assert main(['train', '--demos', {str(demos)!r}, '--out', {str(tmp / 'off')!r}, "
        "'--episodes', '1', '--quiet', '--config', 'validation_arenas=1']) == 0; "
        "print('rerun' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return out.stdout.strip().splitlines()[-1] == "True"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=40, help="frames per camera")
    parser.add_argument("--episodes", type=int, default=6, help="NIRL iterations per training run")
    parser.add_argument("--repeat", type=int, default=2, help="training runs per setting (interleaved)")
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args()

    cams = []
    for camera in ("top", "follow", "chase"):
        r = measure_camera(camera, args.frames)
        cams.append(r)
        print(f"{camera:7s} render {r['render']:5.1f} ms  overlay {r['overlay']:4.1f} ms  encode "
              f"{r['encode']:4.1f} ms  -> {r['fps']:4.1f} frames/s "
              f"(render alone {r['render_fps']:4.1f})")  # fmt: skip

    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.experiments.demos import ExpertConfig, collect

    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        demos = tmp / "demos.npz"
        save_dataset(demos, collect(load_task("navigate"), ExpertConfig("sensor", seed=0), 10, 0, 1))
        runs = {False: [], True: []}
        for k in range(args.repeat):
            for record in (False, True):
                r = train_once(demos, tmp / f"run_{int(record)}_{k}", args.episodes, record)
                runs[record].append(r)
                extra = (
                    f", logging {1e3 * r['per_iteration_log']:.2f} ms/iteration, finish {r['finish']:.2f} s"
                )
                print(f"train {'on ' if record else 'off'}: {r['train']:.1f} s{extra if record else ''}")
        imported = rerun_imported_without_flag(tmp, demos)
    off = statistics.median(r["train"] for r in runs[False])
    on = statistics.median(r["train"] for r in runs[True])
    per_iter = statistics.median(r["per_iteration_log"] for r in runs[True])
    finish = statistics.median(r["finish"] for r in runs[True])
    iteration = off / args.episodes
    share = (args.episodes * per_iter + finish) / off
    default_iters = 60
    share_default = (default_iters * per_iter + finish) / (default_iters * iteration)
    print(f"overhead: {share:.1%} of a {args.episodes}-iteration run, {share_default:.1%} extrapolated to "
          f"{default_iters} iterations; rerun imported without --rerun: {imported}")  # fmt: skip

    cam_table = markdown_table(
        ["camera (640x480)", "render (ms)", "overlay (ms)", "MP4 encode (ms)", "frames/s (all)",
         "frames/s (render only)"],
        [[r["camera"], f"{r['render']:.1f}", f"{r['overlay']:.1f}", f"{r['encode']:.1f}", f"{r['fps']:.1f}",
          f"{r['render_fps']:.1f}"] for r in cams],
    )  # fmt: skip
    train_table = markdown_table(
        ["", "value"],
        [["training wall time, off / on (median)", f"{off:.1f} s / {on:.1f} s"],
         ["one iteration (off)", f"{iteration:.2f} s"],
         ["per-iteration logging (scalars)", f"{1e3 * per_iter:.2f} ms"],
         ["end of run (demonstrations with r_theta, reward map, blueprint, close)", f"{finish:.2f} s"],
         [f"recording share, this {args.episodes}-iteration run", f"{share:.1%}"],
         [f"recording share, extrapolated to {default_iters} iterations (default variant)",
          f"{share_default:.1%}"],
         ["without --rerun: rerun imported by `nirl-mj train`", "yes" if imported else "no"]],
    )  # fmt: skip
    body = (
        f"Rendering: tasks/navigate.toml (tyre), {args.frames} frames per camera, one per decision of the "
        "rule policy, Mesa EGL on the CPU, one process. A video at F frames/s of simulated time costs "
        "about F / (frames/s) seconds per simulated second on top of the simulation.\n\n"
        f"{cam_table}\n\nTraining with `--rerun` (target: at most 10 % more time; nothing without it): "
        f"default variant, {args.episodes} iterations, 10 sensor-expert demonstrations, {args.repeat} "
        "interleaved runs per setting. The recording's own cost is timed inside it; the wall times "
        f"off/on differ by noise as much as by it.\n\n{train_table}"
    )
    if not args.no_write:
        write_section("Rendering and recording (bench/bench_render.py)", body)


if __name__ == "__main__":
    main()
