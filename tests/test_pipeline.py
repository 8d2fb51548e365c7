"""The main job end to end on a tiny configuration: every artifact, and resume."""

import json
import re

import pytest
import rerun.chunk

from nirl_mj.cli import commands, main


def test_main_job_writes_report_results_and_recording(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["run", "--out", str(out), "--demos", "2", "--episodes", "2", "--tests", "2", "--quiet",
            "--set", "robot.drive=planar", "--set", "control.step_budget=10"]  # fmt: skip
    assert main([*args, "--json"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert set(last) == {"NIRL", "always forward", "rule on phi(s)", "behaviour cloning",
                         "control: progress reward", "control: constant reward"}  # fmt: skip
    results = json.loads((out / "results.json").read_text())["results"]
    assert all(r["tests"] == 2 for r in results.values())
    for name in (
        "report.md",
        "margin.png",
        "cost.png",
        "weights.png",
        "paths.png",
        "runs/NIRL/0/reward.json",
        "tests/NIRL.npz",
    ):
        assert (out / name).stat().st_size > 0, name
    report = (out / "report.md").read_text()
    assert "| NIRL |" in report and "| always forward |" in report
    images = re.findall(
        r"^!\[[^\]]*\]\(([^)]+)\)\n\n\*Figure \d", report, flags=re.MULTILINE
    )  # each captioned
    assert len(images) == report.count("![") == 5 and all((out / image).is_file() for image in images)
    assert "| path of successful tests (m) |" in report and "selected policy (iteration " in report
    entities = {chunk.entity_path for chunk in rerun.chunk.RrdReader(out / "run.rrd").store().stream()}
    assert (
        "/training/margin" in entities and "/eval/nirl/000/path" in entities and "/demos/000/path" in entities
    )

    # An existing run is never overwritten; --resume re-uses every finished stage.
    before = (out / "demos.npz").read_bytes()
    assert main(args) == 2
    assert "pass --resume" in capsys.readouterr().err
    kept = {name: (out / name).stat().st_mtime_ns for name in ("results.json", "report.md", "run.rrd")}
    assert main([*args, "--resume"]) == 0
    assert (out / "demos.npz").read_bytes() == before
    # finished: its results, report and recording are kept, not written again
    assert {name: (out / name).stat().st_mtime_ns for name in kept} == kept
    assert "had finished" in capsys.readouterr().err
    # a report that was lost is written again by the same command
    (out / "report.md").unlink()
    assert main([*args, "--resume"]) == 0
    assert "| NIRL |" in (out / "report.md").read_text()


def test_train_then_eval_from_the_command_line(tmp_path, capsys, monkeypatch):
    task = tmp_path / "tiny.toml"
    task.write_text('[robot]\ndrive = "planar"\n[control]\nstep_budget = 8\n')
    demos = tmp_path / "demos.npz"
    assert main(["demos", "--task", str(task), "--expert", "rule", "--episodes", "2", "--out", str(demos),
                 "--workers", "1", "--quiet"]) == 0  # fmt: skip
    run = tmp_path / "run"
    assert main(["train", "--task", str(task), "--demos", str(demos), "--out", str(run), "--episodes", "2",
                 "--quiet"]) == 0  # fmt: skip
    assert main(["train", "--out", str(run), "--resume", "--quiet"]) == 0  # already finished: a no-op
    capsys.readouterr()
    assert main(["eval", "--run", str(run), "--tests", "3", "--json", "--quiet"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for key in ("success_rate", "collision_rate", "timeout_rate", "mean_path_length", "spl", "tests"):
        assert key in result
    assert result["tests"] == 3
    assert len(json.loads((run / "eval.json").read_text())) == 1
    # the same evaluation again (a --set that changes nothing too) is refused before it drives an
    # episode, unless asked; one under --set is stored beside it
    before = (run / "eval.json").read_bytes()
    with monkeypatch.context() as patch:
        patch.setattr(commands, "evaluate", lambda *a, **k: pytest.fail("evaluated before refusing"))
        for same in ([], ["--set", "control.speed=2"]):
            assert main(["eval", "--run", str(run), "--tests", "3", "--quiet", *same]) == 2
            assert "already holds the evaluation" in capsys.readouterr().err
    assert (run / "eval.json").read_bytes() == before
    assert main(["eval", "--run", str(run), "--tests", "3", "--quiet", "--overwrite"]) == 0
    assert main(["eval", "--run", str(run), "--tests", "3", "--quiet", "--set", "control.speed=1.5"]) == 0
    evaluations = json.loads((run / "eval.json").read_text())
    assert [e.get("set") for e in evaluations.values()] == [None, ["control.speed=1.5"]]
    capsys.readouterr()
    assert main(["eval", "--run", str(tmp_path), "--quiet"]) == 2
    assert "not a nirl-mj run directory" in capsys.readouterr().err


def test_resume_refuses_changed_settings(tmp_path, capsys):
    assert main(["train", "--out", str(tmp_path), "--resume", "--config", "eta=3"]) == 2
    assert "--resume continues with the run's saved settings" in capsys.readouterr().err


def test_a_warp_training_drives_as_many_worlds_as_an_iteration_has_trajectories(tmp_path, monkeypatch):
    """--backend warp on train: --worlds defaults to the learner's trajectories per iteration (the
    most its rollouts drive at once), and --worlds wins. The training itself is not run (no Warp
    needed): the backend that train would be handed is captured."""

    class Handed(Exception):
        pass

    handed = []

    def capture(out, spec, demos, config, seed, resume, progress, backend):
        handed.append((config.loop.trajectories_per_episode, backend))
        raise Handed

    monkeypatch.setattr(commands, "train", capture)
    base = ["train", "--demos", str(tmp_path / "d.npz"), "--out", str(tmp_path / "run"), "--quiet",
            "--backend", "warp", "--device", "cpu"]  # fmt: skip
    for extra in ([], ["--config", "trajectories_per_episode=4"], ["--worlds", "3"]):
        with pytest.raises(Handed):
            main([*base, *extra])
    assert [(n, b.name, b.worlds, b.device) for n, b in handed] == [
        (10, "warp", 10, "cpu"), (4, "warp", 4, "cpu"), (10, "warp", 3, "cpu")
    ]  # fmt: skip
