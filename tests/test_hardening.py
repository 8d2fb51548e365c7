"""The probes of a careful and a hostile user (issue 13), each as a test.

Bad input gives one ``error:`` line naming what was wrong, exit code 2, no traceback, and
overwrites nothing; nonsense is refused; resumes continue only what they should.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from nirl_mj import make_env
from nirl_mj.cli import main
from nirl_mj.data.dataset import save_dataset
from nirl_mj.data.rundir import RunDir
from nirl_mj.data.trajectory import TrajectoryRecorder
from nirl_mj.sim import spec
from nirl_mj.sim.task import Outcome

TINY = ["--set", "robot.drive=planar", "--set", "control.step_budget=8"]
LEARNER = ["--config", "trajectories_per_episode=2", "--config", "validation_arenas=2",
           "--config", "replay_episodes=2"]  # fmt: skip


def refused(capsys, argv: list[str], *needles: str) -> str:
    """Runs the command; it must exit 2 with one ``error:`` line holding every needle."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and sum("error:" in line for line in err.splitlines()) == 1, err
    for needle in needles:
        assert needle in err, (needle, err)
    return err


@pytest.fixture(scope="module")
def datasets(tmp_path_factory):
    """Two different tiny datasets (rule expert, seeds 0 and 1)."""
    folder = tmp_path_factory.mktemp("demos")
    for seed in (0, 1):
        argv = ["demos", "--expert", "rule", "--episodes", "2", "--seed", str(seed), "--workers", "1",
                "--quiet", "--out", str(folder / f"d{seed}.npz"), *TINY]  # fmt: skip
        assert main(argv) == 0
    return folder / "d0.npz", folder / "d1.npz"


def trained(tmp_path: Path, demos: Path, *extra: str) -> Path:
    run = tmp_path / "run"
    argv = ["train", "--demos", str(demos), "--out", str(run), "--episodes", "2", "--quiet", *TINY, *LEARNER]
    assert main([*argv, *extra]) == 0
    return run


# -- wrong results, silently ------------------------------------------------------------------


def test_a_resume_on_other_demonstrations_is_refused(tmp_path, datasets, capsys):
    run = trained(tmp_path, datasets[0])
    record = RunDir(run).read_record()
    assert Path(record["demos"]).is_absolute() and len(record["demos_sha256"]) == 64
    refused(capsys, ["train", "--out", str(run), "--resume", "--demos", str(datasets[1])],
            "holds other demonstrations")  # fmt: skip
    # the same content under another name is the same dataset
    copy = tmp_path / "copy.npz"
    copy.write_bytes(datasets[0].read_bytes())
    assert main(["train", "--out", str(run), "--resume", "--demos", str(copy), "--quiet"]) == 0


@pytest.mark.parametrize("flag", [["--seed", "3"], ["--variant", "paper"], ["--task", "dynamic"]])
def test_resume_refuses_settings_it_would_ignore(tmp_path, flag, capsys):
    refused(capsys, ["train", "--out", str(tmp_path), "--resume", *flag], "--resume continues", flag[0])


# -- a robot that tips over ---------------------------------------------------------------------


def test_a_tipped_robot_ends_the_episode_as_a_physics_error():
    task = spec.replace(spec.load_task("navigate"), robot={"drive": "rollers"},
                        control={"speed": 5.0, "physics_timestep": 0.05, "command_period": 0.1})  # fmt: skip
    env = make_env(task, seed=0)
    timestep, steps = env.reset(), 0
    while not timestep.last():
        timestep = env.step(steps % 6)
        steps += 1
    assert Outcome(int(timestep.observation["outcome"][0])) == Outcome.PHYSICS_ERROR
    assert "tipped over" in env.task.physics_error and timestep.discount == 0.0


# -- learner settings and datasets ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("config", "needle"),
    [("gamma=5", "gamma = 5.0: expected a finite number in (0.0, 1.0)"),
     ("selection=foo", "unknown selection 'foo'"), ("episodes=abc", "episodes = 'abc'"),
     ("episodes=0", "episodes = 0"), ("episodes=-3", "episodes = -3"), ("batch_size=0", "batch_size = 0"),
     ("trajectories_per_episode=0", "trajectories_per_episode = 0"), ("method=xyz", "unknown method 'xyz'"),
     ("variant=paper", "--variant"), ("nonsense=1", "unknown learner setting 'nonsense'"),
     ("noequals", "expected KEY=VALUE")],
)  # fmt: skip
def test_bad_learner_settings_are_refused_before_anything_is_written(
    tmp_path, datasets, config, needle, capsys
):
    out = tmp_path / "run"
    refused(capsys, ["train", "--demos", str(datasets[0]), "--out", str(out), "--config", config], needle)
    assert not out.exists()


def test_episodes_given_twice_is_refused(tmp_path, datasets, capsys):
    argv = ["train", "--demos", str(datasets[0]), "--out", str(tmp_path / "r"), "--episodes", "3"]
    refused(capsys, [*argv, "--config", "episodes=5"], "give one")


def test_a_dataset_of_empty_trajectories_is_flagged_and_not_trained_on(tmp_path, capsys):
    env = make_env(spec.replace(spec.load_task("navigate"), robot={"drive": "planar"}), seed=0)
    recorder = TrajectoryRecorder(0.5)
    recorder.start(env.reset().observation)
    empty = tmp_path / "empty.npz"
    save_dataset(empty, [recorder.finish("timeout", 1, env.task.spec, 2.0, "sensor")])
    assert main(["inspect", str(empty)]) == 0
    assert "warning: 1 of 1 trajectories end before their first decision" in capsys.readouterr().out
    refused(capsys, ["train", "--demos", str(empty), "--out", str(tmp_path / "run")], "no state-action pair")
    assert not (tmp_path / "run" / "metrics.jsonl").exists() or not RunDir(tmp_path / "run").read_metrics()


# -- task files --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("override", "needle"),
    [("arena.static_obstacles=10000", "at most 1000"), ("arena.static_obstacles=1000000000", "at most 1000"),
     ("arena.size=[100000.0, 100000.0]", "at most 1000 metres per side"),
     ("control.decision_period=1e9", "decision_period = 1e+09: at most 10 seconds"),
     ("arena.obstacles=[{shape='box', position=[500.0, 5.0], size=[1.0, 1.0]}]", "must lie inside the arena"),
     ("control.max_accel=0.001", "needs max_accel >="), ("arena.target=[10.0, 10.0]", "start at its goal"),
     ("control.speed=1e-9", "at most 100000 decisions"),
     ("robot.drive=wheels", "accepted: tyre, rollers, planar")],
)  # fmt: skip
def test_task_values_that_would_hang_exhaust_memory_or_make_no_sense_are_refused(override, needle, capsys):
    refused(capsys, ["rollout", "--episodes", "1", "--quiet", "--set", override], needle)


def test_a_task_file_that_is_not_utf8_is_refused(tmp_path, capsys):
    path = tmp_path / "latin1.toml"
    path.write_bytes('description = "caf\xe9"\n'.encode("latin-1"))
    refused(capsys, ["task", str(path)], "not a UTF-8 text file")


# -- run directories ---------------------------------------------------------------------------------


def test_corrupt_run_files_give_clear_errors(tmp_path, datasets, capsys):
    run = trained(tmp_path, datasets[0])
    (run / "eval.json").write_text("{ not json")
    refused(capsys, ["eval", "--run", str(run), "--tests", "1"], "eval.json is corrupted")
    (run / "eval.json").unlink()
    policy = (run / "policy.npz").read_bytes()
    (run / "policy.npz").write_bytes(os.urandom(256))
    refused(capsys, ["eval", "--run", str(run), "--tests", "1"], "not an .npz archive")
    (run / "policy.npz").write_bytes(policy)
    record = json.loads((run / "run.json").read_text())
    (run / "run.json").write_text(json.dumps({k: v for k, v in record.items() if k != "config"}))
    refused(capsys, ["eval", "--run", str(run), "--tests", "1"], "lacks config")


def test_a_run_killed_before_its_first_checkpoint_resumes_from_scratch(tmp_path, datasets, capsys):
    run = trained(tmp_path, datasets[0])
    finished = RunDir(run).read_checkpoint()
    for name in ("checkpoint.npz", "policy.npz", "reward.json"):
        (run / name).unlink()
    record = json.loads((run / "run.json").read_text())
    (run / "run.json").write_text(json.dumps({k: v for k, v in record.items() if k in (
        "task", "config", "seed", "demos", "demos_sha256", "demo_seeds", "validation_seeds")}))  # fmt: skip
    (run / "metrics.jsonl").write_text("")
    leftover = run / ".checkpoint.npz.0badc0de.tmp"  # what kill -9 during a write leaves
    leftover.write_bytes(b"")
    assert main(["train", "--out", str(run), "--resume", "--quiet"]) == 0
    assert not leftover.exists()
    again = RunDir(run).read_checkpoint()
    assert all(np.array_equal(finished[k], again[k]) for k in ("net_W1", "net_W2", "theta"))


def test_ctrl_c_during_training_says_how_to_resume(tmp_path, datasets, capsys, monkeypatch):
    from nirl_mj.cli import commands

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(commands, "train", interrupted)
    assert main(["train", "--demos", str(datasets[0]), "--out", str(tmp_path / "r"), "--quiet"]) == 130
    err = capsys.readouterr().err
    assert "nothing was written" not in err and f"nirl-mj train --out {tmp_path / 'r'} --resume" in err
    # the main job resumes only with its own flags: its hint repeats the command as given
    monkeypatch.setattr(commands, "main_job", interrupted)
    given = ["run", "--demos", "3", "--episodes", "2", "--out", str(tmp_path / "m"), "--quiet", *TINY]
    assert main(given) == 130
    assert f"continue with nirl-mj {' '.join(given)} --resume" in capsys.readouterr().err


def test_a_directory_as_output_file_is_refused_before_any_episode(tmp_path, capsys):
    refused(capsys, ["demos", "--out", str(tmp_path), "--overwrite", "--episodes", "1"], "is a directory")


def test_eval_refuses_a_rerun_it_cannot_write_before_cloning_the_demonstrations(
    tmp_path, datasets, capsys, monkeypatch
):
    from nirl_mj.cli import commands

    def no_subject(args):
        raise AssertionError("the subject was built (behaviour cloning trained) before the refusal")

    monkeypatch.setattr(commands, "_subject", no_subject)
    kept = tmp_path / "eval.rrd"
    kept.write_bytes(b"a user's recording")
    argv = ["eval", "--policy", "bc", "--demos", str(datasets[0]), "--rerun", str(kept), "--tests", "1"]
    refused(capsys, argv, "exists", "--overwrite")
    assert kept.read_bytes() == b"a user's recording"
    fresh = ["eval", "--policy", "bc", "--demos", str(datasets[0]), "--rerun", str(tmp_path / "new.rrd"),
             "--set", 'control.actions="continuous"', "--tests", "1"]  # fmt: skip
    refused(capsys, fresh, "--rerun: task", "continuous actions")


def test_a_rerun_recording_never_takes_the_place_of_a_file_the_command_keeps(tmp_path, capsys, datasets):
    """``--rerun`` names a .rrd file other than the command's own outputs, checked before any work:
    with --overwrite the recording had replaced the dataset just written, or a run's policy."""
    data = tmp_path / "d.npz"
    data.write_bytes(b"a user's dataset")
    demos = ["demos", "--episodes", "1", "--workers", "1", "--quiet", *TINY, "--overwrite"]
    refused(capsys, [*demos, "--out", str(data), "--rerun", str(data)], "ends in .rrd")
    refused(capsys, [*demos, "--out", str(tmp_path / "d.rrd"), "--rerun", str(tmp_path / "d.rrd")],
            "also a file this command writes")  # fmt: skip
    assert data.read_bytes() == b"a user's dataset" and not (tmp_path / "d.rrd").exists()
    run = tmp_path / "run"
    run.mkdir()
    (run / "policy.npz").write_bytes(b"a trained policy")
    refused(
        capsys, ["eval", "--run", str(run), "--rerun", str(run / "policy.npz"), "--overwrite"], "ends in .rrd"
    )
    assert (run / "policy.npz").read_bytes() == b"a trained policy"
    refused(capsys, ["run", "--out", str(run), "--rerun", str(run / "run.rrd"), "--resume"],
            "also a file this command writes")  # fmt: skip


def test_an_output_or_a_resume_of_the_wrong_kind_is_refused_by_name(tmp_path, capsys, datasets, monkeypatch):
    """A file given as a run directory, a resume with nothing to resume or of another command's run, a
    task file given as an experiment, a negative --train-seed: one line each, saying what to give."""
    refused(capsys, ["train", "--demos", str(datasets[0]), "--out", str(datasets[0])], "is a file, not a run")
    refused(capsys, ["run", "--out", str(datasets[0]), "--workers", "1"], "is a file, not a directory")
    refused(
        capsys, ["run", "--out", str(tmp_path / "none"), "--resume", "--workers", "1"], "nothing to resume"
    )
    assert not (tmp_path / "none").exists()
    nirl = tmp_path / "nirl"
    nirl.mkdir()
    from nirl_mj.data.rundir import RECORD_KEYS

    record = {**dict.fromkeys(RECORD_KEYS, 0), "demos": None, "demo_seeds": [], "validation_seeds": []}
    (nirl / "run.json").write_text(json.dumps(record))  # a record without kind "rl"
    refused(capsys, ["rl", "--out", str(nirl), "--resume"], "not of `nirl-mj rl`", "nirl-mj train")
    refused(capsys, ["compare", "--task", "navigate", "--report"], "is a task file, not an experiment")
    refused(capsys, ["demos", "--expert", "sensor", "--slip", "0.5", "--out", str(tmp_path / "n.npz")],
            "--slip: only for --expert noisy")  # fmt: skip
    with pytest.raises(SystemExit):
        main(["eval", "--policy", "bc", "--demos", str(datasets[0]), "--train-seed", "-5"])
    assert "--train-seed: " in capsys.readouterr().err
    # the shipped experiment files by the path the docs give, from any working directory
    monkeypatch.chdir(tmp_path)
    from nirl_mj.experiments.definition import load_experiment

    assert load_experiment("tasks/table1.toml").name == "table1"


def test_a_flag_the_command_would_ignore_is_refused_under_its_own_usage(tmp_path, capsys, datasets):
    """An unknown option prints the command's usage (not the top level's); --workers with the serial
    executor or with a Ray cluster's address, --train-seed without --policy bc and --demos with --run are
    refused by name, not ignored; a dataset given to run's --demos says where it goes; an input error
    draws no empty progress bar."""
    with pytest.raises(SystemExit):
        main(["sweep", "--only", "NIRL"])
    err = capsys.readouterr().err
    assert "usage: nirl-mj sweep" in err and "unrecognized arguments: --only NIRL" in err
    compare = ["compare", "--task", "table1", "--out", str(tmp_path / "c"), "--quiet"]
    refused(capsys, [*compare, "--executor", "serial", "--workers", "2"], "--workers 2: the serial executor")
    refused(capsys, [*compare, "--executor", "ray", "--address", "auto", "--workers", "2"],
            "--workers 2: the Ray cluster at auto")  # fmt: skip
    assert not (tmp_path / "c").exists()
    refused(capsys, ["eval", "--policy", "rule", "--train-seed", "3", "--tests", "1"],
            "--train-seed is the training seed of --policy bc", "--policy rule")  # fmt: skip
    run = trained(tmp_path, datasets[0])
    refused(capsys, ["eval", "--run", str(run), "--demos", str(datasets[0])], "--demos goes with --policy")
    err = refused(capsys, ["train", "--demos", str(tmp_path / "none.npz"), "--out", str(tmp_path / "t")])
    assert "episode/s" not in err and "%|" not in err, err
    refused(capsys, ["eval", "--policy", "rule", "--which", "last"], "--which chooses among a run's policies")
    render = ["render", "--policy", "rule", "--out", str(tmp_path / "v.mp4")]
    refused(capsys, [*render, "--arenas", "3"], "--arenas sets --paths's figure")
    refused(capsys, [*render, "--snapshots", "3"], "--snapshots sets --montage's figure")
    with pytest.raises(SystemExit):
        main([*render, "--fps", "0"])
    assert "--fps: expected a frame rate > 0, got 0" in capsys.readouterr().err
    # run's --demos counts what it records, where train's names a dataset: a path says where it goes
    with pytest.raises(SystemExit):
        main(["run", "--demos", str(datasets[0]), "--out", str(tmp_path / "m")])
    assert "nirl-mj train --demos PATH" in capsys.readouterr().err and not (tmp_path / "m").exists()
    # an experiment file given as a task names what it is; a refused command leaves no folder behind
    refused(capsys, ["task", "tasks/table1.toml"], "is an experiment (kind = 'compare'), not a task")
    # an override is checked as every command checks it
    refused(capsys, ["task", "navigate", "--set", "arena.floor_plan=maze"], "arena.floor_plan")
    assert main(["task", "navigate", "--set", "arena.floor_plan=pockets"]) == 0
    assert '"floor_plan": "pockets"' in capsys.readouterr().out
    assert "table1" not in refused(capsys, ["task", "nonexistent"], "unknown task")
    refused(capsys, ["compare", "--task", "table1", "--only", "Foo", "--out", str(tmp_path / "np" / "c")],
            "--only Foo")  # fmt: skip
    assert not (tmp_path / "np").exists()
    plain = tmp_path / "plain.toml"  # an experiment without a [quick] table
    plain.write_text('kind = "compare"\nruns = 1\ntests = 1\nmethods = ["rule"]\n')
    refused(capsys, ["compare", "--task", str(plain), "--quick", "--report"], "has no [quick] table")


def test_a_progress_bar_drawn_at_its_first_step_is_timed_from_when_the_work_began():
    """The bar is made when the first step ends (so that an input error prints under none): its
    elapsed time and first rate count from its creation, not 1 / (a few microseconds)."""
    import io
    import time

    from nirl_mj.cli.commands import _LazyBar

    bar = _LazyBar(total=3, unit="episode", file=io.StringIO())
    time.sleep(0.2)
    bar.update()
    assert bar.format_dict["elapsed"] >= 0.2
    assert bar.format_dict["n"] / bar.format_dict["elapsed"] < 10  # one episode in >= 0.2 s
    bar.close()
