"""bench/bench_warp_training.py on the CPU backend: one tiny training, its JSON line, its resume."""

import json
import subprocess
import sys
from pathlib import Path

from nirl_mj.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _bench(*args: str) -> subprocess.CompletedProcess:
    command = [sys.executable, str(ROOT / "bench" / "bench_warp_training.py"), "--backend", "cpu", *args]
    return subprocess.run(command, capture_output=True, text=True, cwd=ROOT)


def test_one_iteration_then_its_resume(tmp_path):
    demos = tmp_path / "demos.npz"
    assert main(["demos", "--episodes", "2", "--workers", "1", "--quiet", "--out", str(demos)]) == 0
    run = tmp_path / "run"
    first = _bench("--demos", str(demos), "--out", str(run), "--episodes", "1", "--tests", "2")
    assert first.returncode == 0, first.stderr
    result = json.loads(first.stdout.splitlines()[-1])
    assert (result["backend"], result["resumed_at"], result["iterations"]) == ({"name": "cpu"}, 0, 1)
    assert result["tests"] == 2 and 0 <= result["test_success"] <= 1
    assert "iteration 1:" in first.stdout
    again = _bench("--demos", str(demos), "--out", str(run), "--episodes", "1", "--tests", "0", "--resume")
    assert again.returncode == 0, again.stderr
    resumed = json.loads(again.stdout.splitlines()[-1])
    assert (resumed["resumed_at"], resumed["iterations"]) == (1, 0) and "tests" not in resumed
    # a finished run is not trained over without --resume: one error line, no traceback
    refused = _bench("--demos", str(demos), "--out", str(run), "--episodes", "1", "--tests", "0")
    assert refused.returncode != 0 and refused.stderr.startswith("error:")
    assert "Traceback" not in refused.stderr
