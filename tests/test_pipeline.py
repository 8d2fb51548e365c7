"""The main job end to end on a tiny configuration: every artifact, and resume."""

import json

import rerun.chunk

from nirl_mj.cli import main


def test_main_job_writes_report_results_and_recording(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["run", "--out", str(out), "--demos", "2", "--episodes", "2", "--tests", "2", "--quiet",
            "--set", "robot.drive=planar", "--set", "control.step_budget=10"]  # fmt: skip
    assert main([*args, "--json"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert set(last) == {"NIRL", "always forward", "rule on phi(s)", "behaviour cloning",
                         "control: SARSA on progress", "control: constant reward"}  # fmt: skip
    results = json.loads((out / "results.json").read_text())["results"]
    assert all(r["tests"] == 2 for r in results.values())
    for name in ("report.md", "margin.png", "cost.png", "weights.png", "paths.png", "nirl/reward.json"):
        assert (out / name).stat().st_size > 0, name
    report = (out / "report.md").read_text()
    assert "| NIRL |" in report and "| always forward |" in report
    entities = {chunk.entity_path for chunk in rerun.chunk.RrdReader(out / "run.rrd").store().stream()}
    assert (
        "/training/margin" in entities and "/eval/nirl/000/path" in entities and "/demos/000/path" in entities
    )

    # An existing run is never overwritten; --resume re-uses every finished stage.
    before = (out / "demos.npz").read_bytes()
    assert main(args) == 2
    assert "pass --resume" in capsys.readouterr().err
    assert main([*args, "--resume"]) == 0
    assert (out / "demos.npz").read_bytes() == before
