"""Screenshots of a recording's default layout in Rerun's web viewer, as a person sees it on open.

For each shot it writes the main job's recording with the layout opened on one episode or tab
(``record_main_job``), serves it with ``rerun --serve-web``, opens the viewer in headless
Chromium with a page of exactly ``--size`` pixels (1600 x 860 by default, set through DevTools),
waits for it to load and draw (software rendering on a loaded 2-core machine: up to 200 s), and
saves the page through the DevTools protocol. Nothing is clicked: what is saved is what opens. It
also prints the views that the recording itself says would be empty
(``layout_check.views_without_data``) and the views on screen with their estimated sizes
(``layout_check.open_views``).

Shots (:data:`SHOTS`): the first view (``rerun run.rrd`` opens on the demonstrations, episode
000), NIRL's tab on test episode 3, the first test episode that ended in a collision of a method
other than NIRL (preferring one whose tab also has arrivals), and NIRL's training tab.

Needs the Debian package ``chromium`` (``apt-get install -y chromium``) and the ``websockets``
module (installed with mujoco). Writes docs/images/rerun_*.png by default.

    nice -n 10 .venv/bin/python docs/scripts/rerun_screenshots.py --run runs/main [--wait 200]
        [--only rerun_eval.png ...]
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

from PIL import Image

from nirl_mj.data.atomic import AtomicFile
from nirl_mj.data.dataset import load_dataset
from nirl_mj.data.rundir import RunDir
from nirl_mj.experiments.main_job import ROWS, record_main_job
from nirl_mj.inspect.layout_check import open_views, read_layout, views_without_data
from nirl_mj.inspect.recording import slug

COLLISION = "collision"
SHOTS = {
    "rerun_layout.png": None,  # what `rerun run.rrd` opens on: the demonstrations, episode 000
    "rerun_eval.png": "eval/nirl/003",  # a test episode of NIRL, its group's paths beside it
    "rerun_episode.png": COLLISION,  # a collision, in a method's tab of its own
    "rerun_training.png": "training",  # NIRL's training curves
}
"""Output file -> the episode or tab the layout opens on (:data:`COLLISION`: the first collision
that :func:`collision_episode` finds)."""
RECORDED = 10  # the test episodes per method that the main job's recording holds


def collision_episode(run: Path) -> str:
    """The entity path of the first recorded test episode that ended in a collision, of a method
    other than NIRL whose recorded episodes also arrive somewhere (else of any method)."""
    found = []
    for name, row in ROWS.items():
        file = run / "tests" / f"{name}.npz"
        if name == "NIRL" or not file.is_file():
            continue
        outcomes = [t.outcome for t in load_dataset(file)[:RECORDED]]
        if COLLISION in outcomes:
            found.append((("target" not in outcomes), f"eval/{slug(row)}/{outcomes.index(COLLISION):03d}"))
    if not found:
        raise SystemExit("error: no recorded test episode ended in a collision")
    return min(found)[1]


CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--hide-scrollbars")  # fmt: skip


def _wait_for(url: str, seconds: float) -> bytes:
    """The body at ``url`` once it answers (polled every 0.5 s for up to ``seconds``)."""
    end = time.monotonic() + seconds
    while True:
        try:
            with urllib.request.urlopen(url, timeout=5) as response:
                return response.read()
        except OSError:
            if time.monotonic() > end:
                raise
            time.sleep(0.5)


def _call(ws, ident: int, method: str, params: dict | None = None) -> dict:
    """Sends one DevTools command and returns its result (events in between are skipped)."""
    ws.send(json.dumps({"id": ident, "method": method, "params": params or {}}))
    while True:
        reply = json.loads(ws.recv(timeout=120))
        if reply.get("id") == ident:
            if "error" in reply:
                raise RuntimeError(f"{method}: {reply['error']}")
            return reply.get("result", {})


def screenshot(rrd: Path, out: Path, width: int, height: int, wait: float, ports: tuple[int, int]) -> None:
    """Serves ``rrd`` and saves the web viewer's page after ``wait`` seconds as the PNG ``out``,
    ``width`` x ``height`` pixels (the page's viewport, set through DevTools: a headless window's
    size is not its viewport's)."""
    from websockets.sync.client import connect

    web, grpc = ports
    with tempfile.TemporaryDirectory() as profile:
        server = subprocess.Popen(
            [str(Path(sys.executable).with_name("rerun")), "--serve-web", "--web-viewer-port", str(web),
             "--port", str(grpc), str(rrd)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
        )  # fmt: skip
        browser = None
        try:
            _wait_for(f"http://127.0.0.1:{web}/", 60)
            page = f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy"
            browser = subprocess.Popen(
                ["chromium", *CHROMIUM_FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
                 "--remote-debugging-port=0", "about:blank"],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
            )  # fmt: skip
            port_file = Path(profile) / "DevToolsActivePort"
            end = time.monotonic() + 60
            while not port_file.is_file() or not port_file.read_text().strip():
                if time.monotonic() > end:
                    raise RuntimeError("chromium did not open its DevTools port")
                time.sleep(0.5)
            devtools = int(port_file.read_text().split()[0])
            targets = json.loads(_wait_for(f"http://127.0.0.1:{devtools}/json/list", 30))
            socket_url = next(t["webSocketDebuggerUrl"] for t in targets if t["type"] == "page")
            with connect(socket_url, max_size=None, open_timeout=30) as ws:
                metrics = {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False}
                _call(ws, 1, "Emulation.setDeviceMetricsOverride", metrics)
                _call(ws, 2, "Page.navigate", {"url": page})
                time.sleep(wait)  # the viewer loads its wasm, the recording, then draws every view
                png = base64.b64decode(_call(ws, 3, "Page.captureScreenshot", {"format": "png"})["data"])
            with AtomicFile(out, ".png", overwrite=True) as target:
                Path(target.tmp).write_bytes(png)
                # Modest files: a palette of 256 colours (octree, no dithering) keeps a UI's flat
                # colours, the legend's light yellows among them.
                image = Image.open(target.tmp).convert("RGB")
                image.quantize(256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE).save(
                    target.tmp, optimize=True
                )
        finally:
            # Each was started in a session of its own: end it with its children (the `rerun`
            # script runs the viewer binary as a child, chromium its renderers).
            for process in (browser, server):
                if process is not None:
                    os.killpg(process.pid, signal.SIGTERM)
                    process.wait(timeout=30)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, default=Path("runs/main"), help="a finished `nirl-mj run` --out")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "images")
    parser.add_argument("--wait", type=float, default=200.0, help="seconds for the viewer to load and draw")
    parser.add_argument("--size", default="1600x860", help="the page, WIDTHxHEIGHT pixels")
    parser.add_argument("--only", nargs="*", default=None, help="these shots only (file names)")
    parser.add_argument("--ports", default="9190,9976", help="web viewer and gRPC ports")
    args = parser.parse_args()
    if shutil.which("chromium") is None:
        sys.exit("error: chromium not found; install it (Debian: apt-get install -y chromium)")
    width, height = (int(v) for v in args.size.split("x"))
    ports = tuple(int(p) for p in args.ports.split(","))
    seed = json.loads((args.run / "experiment.json").read_text())["seed"]
    nirl = RunDir(args.run / "runs" / "NIRL" / str(seed))  # the main job's one NIRL run
    with tempfile.TemporaryDirectory() as tmp:
        for name, focus in SHOTS.items():
            if args.only is not None and name not in args.only:
                continue
            if focus == COLLISION:
                focus = collision_episode(args.run)
            rrd = record_main_job(args.run, nirl, Path(tmp) / f"{Path(name).stem}.rrd", focus=focus)
            empty = views_without_data(rrd)
            print(f"{name} (opens on {focus or 'the first episode'}): {len(empty)} empty view(s)"
                  f"{': ' + ', '.join(empty) if empty else ''}")  # fmt: skip
            for view in open_views(read_layout(rrd), width, height):
                print(f"  {view.view.kind:12s} {view.width:5.0f} x {view.height:4.0f} px  {view.view.name}")
            screenshot(rrd, args.out / name, width, height, args.wait, ports)
            print(f"wrote {args.out / name}")


if __name__ == "__main__":
    main()
