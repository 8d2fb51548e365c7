"""Screenshots of a recording's default layout in Rerun's web viewer, as a person sees it on open.

For each shot it writes the main job's recording with the layout opened on one episode
(``record_main_job``), serves it with ``rerun --serve-web``, opens the viewer in headless
Chromium, waits for it to load and draw (software rendering: 70-100 s), and saves the page
through the DevTools protocol. Nothing is clicked: what is saved is what opens. It also prints
the views that the recording itself says would be empty (``layout_check.views_without_data``).

Needs the Debian package ``chromium`` (``apt-get install -y chromium``) and the ``websockets``
module (installed with mujoco). Writes docs/images/rerun_*.png by default.

    nice -n 10 .venv/bin/python docs/scripts/rerun_screenshots.py --run runs/main [--wait 120]
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
from nirl_mj.data.rundir import RunDir
from nirl_mj.experiments.main_job import record_main_job
from nirl_mj.inspect.layout_check import views_without_data

SHOTS = {
    "rerun_layout.png": "demos/000",  # what `rerun run.rrd` opens on
    "rerun_eval.png": "eval/nirl/003",  # an evaluation episode of NIRL, its group's paths beside it
}
"""Output file -> the episode whose tabs the layout opens on."""
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


def screenshot(rrd: Path, out: Path, width: int, height: int, wait: float, ports: tuple[int, int]) -> None:
    """Serves ``rrd`` and saves the web viewer's page after ``wait`` seconds as the PNG ``out``."""
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
                 "--remote-debugging-port=0", page],
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
            time.sleep(wait)  # the viewer loads its wasm, the recording, then draws every view
            with connect(socket_url, max_size=None, open_timeout=30) as ws:
                request = {"id": 1, "method": "Page.captureScreenshot", "params": {"format": "png"}}
                ws.send(json.dumps(request))
                while True:
                    reply = json.loads(ws.recv(timeout=120))
                    if reply.get("id") == 1:
                        break
            png = base64.b64decode(reply["result"]["data"])
            with AtomicFile(out, ".png", overwrite=True) as target:
                Path(target.tmp).write_bytes(png)
                # Modest files: a palette of 256 colours loses nothing a reader needs in a UI.
                Image.open(target.tmp).convert("RGB").quantize(256).save(target.tmp, optimize=True)
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
    parser.add_argument("--wait", type=float, default=120.0, help="seconds for the viewer to load and draw")
    parser.add_argument("--size", default="1920x1080", help="browser window, WIDTHxHEIGHT pixels")
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
            rrd = record_main_job(args.run, nirl, Path(tmp) / f"{Path(name).stem}.rrd", focus=focus)
            empty = views_without_data(rrd)
            print(f"{name}: {len(empty)} empty view(s){': ' + ', '.join(empty) if empty else ''}")
            screenshot(rrd, args.out / name, width, height, args.wait, ports)
            print(f"wrote {args.out / name}")


if __name__ == "__main__":
    main()
