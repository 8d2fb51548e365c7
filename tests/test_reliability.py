"""Files that cannot be corrupted (issue 34): a resume checks the checkpoint before it writes
anything, one writer per directory, no stuck directories. Each defect of the issue is reproduced
from the user's side."""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from helpers import damaged_bytes, rule_experiment
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nirl_mj.cli import main
from nirl_mj.data.atomic import write_npz
from nirl_mj.data.rundir import CHECKPOINT_FILE, METRICS_FILE, POLICY_FILE, RUN_FILE

ROOT = Path(__file__).resolve().parents[1]
TINY = ["--set", "robot.drive=planar", "--set", "control.step_budget=8"]
LEARNER = ["--config", "trajectories_per_episode=2", "--config", "validation_arenas=2",
           "--config", "replay_episodes=2"]  # fmt: skip


@pytest.fixture(scope="module")
def demos(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("demos") / "d.npz"
    assert main(["demos", "--expert", "rule", "--episodes", "2", "--seed", "0", "--workers", "1", "--quiet",
                 "--out", str(path), *TINY]) == 0  # fmt: skip
    return path


def train_args(demos: Path, run: Path, *extra: str) -> list[str]:
    return ["train", "--demos", str(demos), "--out", str(run), "--episodes", "3", "--quiet", *TINY, *LEARNER,
            *extra]  # fmt: skip


def resume_args(demos: Path, run: Path) -> list[str]:
    return ["train", "--demos", str(demos), "--out", str(run), "--resume", "--quiet"]


@pytest.fixture(scope="module")
def finished(demos, tmp_path_factory) -> Path:
    run = tmp_path_factory.mktemp("finished") / "run"
    assert main(train_args(demos, run)) == 0
    return run


def digests(run: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(run.iterdir()) if p.is_file()}


def tree_digests(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (subfolders included) by its path, with its sha256."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}  # fmt: skip


def copy_of(run: Path, tmp_path: Path) -> Path:
    import shutil

    target = tmp_path / "copy"
    shutil.copytree(run, target)
    return target


def damaged(run: Path, **changes) -> None:
    with np.load(run / CHECKPOINT_FILE) as data:
        state = {k: data[k] for k in data.files}
    for key, value in changes.items():
        state[key] = value(state[key]) if callable(value) else value
    write_npz(run / CHECKPOINT_FILE, state)


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ({"net_W1": lambda w: np.where(np.arange(w.size).reshape(w.shape) == 0, np.nan, w)},
         "net_W1: not all finite numbers"),
        ({"iteration": np.array(10**6)}, "iteration = 1000000: outside 0..3"),
        ({"iteration": np.array(-3)}, "iteration = -3: outside 0..3"),
        ({"theta": lambda t: t[:-1]}, "theta: shape"),
        ({"scores": np.array([0.5, 0.5])}, "scores: shape (2,), expected (3,)"),
        ({"iteration": np.array(2.5)}, "iteration: array(2.5) is not a whole number"),
        ({"stopped": np.array("no")}, "stopped: array('no', dtype='<U2') is not true or false"),
        ({"replay_action": lambda a: np.where(np.arange(a.size) == 0, 99, a)},
         "replay_action: not all actions 0..5"),
        ({"replay_next_action": lambda a: a - 9}, "replay_next_action: not all actions -1..5"),
    ],
)  # fmt: skip
def test_a_resume_from_a_damaged_checkpoint_is_refused_and_changes_nothing(
    finished, demos, tmp_path, capsys, change, needle
):
    run = copy_of(finished, tmp_path)
    damaged(run, **change)
    before = digests(run)
    assert main(resume_args(demos, run)) == 2
    err = capsys.readouterr().err
    assert f"{CHECKPOINT_FILE} cannot be resumed: {needle}" in err and "Traceback" not in err
    assert digests(run) == before  # policy.npz, run.json and metrics.jsonl untouched


def test_a_checkpoint_ahead_of_its_metrics_is_refused_before_the_metrics_are_cut(
    finished, demos, tmp_path, capsys
):
    run = copy_of(finished, tmp_path)
    lines = (run / METRICS_FILE).read_text().splitlines(keepends=True)
    (run / METRICS_FILE).write_text("".join(lines[:1]))
    before = digests(run)
    assert main(resume_args(demos, run)) == 2
    assert "holds 1 rows but the checkpoint is at iteration 3" in capsys.readouterr().err
    assert digests(run) == before


def test_a_directory_holding_only_a_killed_writes_temporary_file_trains_afresh(demos, tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / f".{RUN_FILE}.1a2b3c4d.tmp").write_text('{"half": ')  # the first write of run.json, killed
    assert main(train_args(demos, run)) == 0
    assert (run / POLICY_FILE).is_file() and not list(run.glob(".*tmp*"))


def test_a_training_that_fails_before_its_first_iteration_leaves_its_output_usable(demos, tmp_path, capsys):
    run = tmp_path / "run"
    crowded = ["--set", "arena.static_obstacles=900", "--set", "arena.obstacle_size=[6.0, 8.0]"]
    assert main(train_args(demos, run, *crowded)) == 2  # valid values; no arena can be built of them
    assert "could not generate a solvable arena" in capsys.readouterr().err
    assert not (run / RUN_FILE).exists()  # nothing left that would block the same --out
    assert main(train_args(demos, run)) == 0


def hold(path: Path, tmp_path: Path) -> tuple[subprocess.Popen, int]:
    """Another process holding the write lock of ``path``; returns it and its pid."""
    ready = tmp_path / "ready"
    script = ("import sys, time; from pathlib import Path\n"
              "from nirl_mj.data.lock import DirectoryLock\n"
              f"lock = DirectoryLock({str(path)!r}).acquire(); Path({str(ready)!r}).write_text('1')\n"
              "time.sleep(600)\n")  # fmt: skip
    process = subprocess.Popen([sys.executable, "-c", script], cwd=ROOT)
    deadline = time.monotonic() + 60
    while not ready.exists():
        assert time.monotonic() < deadline and process.poll() is None, "the holder did not start"
        time.sleep(0.02)
    return process, process.pid


def test_two_writers_of_one_run_or_experiment_the_second_is_refused_every_time(demos, tmp_path, capsys):
    run, out = tmp_path / "run", tmp_path / "exp"
    spec = tmp_path / "e.toml"
    spec.write_text(
        'kind = "compare"\nruns = 1\ntests = 1\nmethods = ["rule"]\n[set.robot]\ndrive = "planar"\n'
    )
    for target, argv in ((run, train_args(demos, run)),
                         (out, ["compare", "--task", str(spec), "--out", str(out), "--quiet"])):  # fmt: skip
        process, pid = hold(target, tmp_path)
        try:
            for _ in range(3):
                assert main(argv) == 2
                err = capsys.readouterr().err.strip().splitlines()
                assert len(err) == 1 and f"is being written by process {pid}" in err[0]
        finally:
            process.send_signal(signal.SIGKILL)  # dies holding the lock: the OS releases it
            process.wait()
        (tmp_path / "ready").unlink()
        assert main(argv) == 0  # taken over from the dead holder
    report = ["compare", "--task", str(spec), "--out", str(out), "--quiet", "--report"]
    assert main(report) == 0  # no one else writes: the report writes its tables
    capsys.readouterr()
    # while the experiment runs, a --report is no second writer: it prints its tables, writes nothing
    process, pid = hold(out, tmp_path)
    try:
        before = tree_digests(out)
        assert main(report) == 0
        printed = capsys.readouterr().out
        assert "| rule |" in printed and f"is being written by process {pid}" in printed
        assert "printed, not written" in printed and tree_digests(out) == before
        grown = tmp_path / "grown.toml"  # a method added: the running experiment records it, not a report
        grown.write_text(spec.read_text().replace('["rule"]', '["rule", "forward"]'))
        assert main(["compare", "--task", str(grown), "--out", str(out), "--quiet", "--report"]) == 0
        assert "printed, not written" in capsys.readouterr().out and tree_digests(out) == before
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait()


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_damage_to_a_checkpoint_is_refused_or_resumed_never_a_traceback(
    finished, demos, tmp_path_factory, capsys, data
):
    """Random truncation, byte flips, NaN/inf, wrong dtypes and shapes of the checkpoint: a resume
    either refuses with one line (the run unchanged) or resumes a state it can continue."""
    run = copy_of(finished, tmp_path_factory.mktemp("hyp"))
    path = run / CHECKPOINT_FILE
    kind = data.draw(st.sampled_from(["truncate", "flip", "nan", "dtype", "shape"]))
    if kind in ("truncate", "flip"):
        raw = bytearray(path.read_bytes())
        at = data.draw(st.integers(0, len(raw) - 1))
        if kind == "truncate":
            raw = raw[:at]
        else:
            raw[at] ^= data.draw(st.integers(1, 255))
        path.write_bytes(bytes(raw))
    else:
        with np.load(path) as npz:
            state = {k: npz[k] for k in npz.files}
        key = data.draw(
            st.sampled_from(sorted(k for k in state if state[k].dtype.kind == "f" and state[k].size))
        )
        value = state[key]
        if kind == "nan":
            value = value.copy()
            value.reshape(-1)[data.draw(st.integers(0, value.size - 1))] = data.draw(
                st.sampled_from([np.nan, np.inf, -np.inf]))  # fmt: skip
        elif kind == "dtype":
            value = value.astype(np.str_)
        else:
            value = value.reshape(-1)[:-1] if value.size > 1 else np.zeros((2, 2))
        state[key] = value
        write_npz(path, state)
    before = digests(run)
    capsys.readouterr()  # one capture serves every example
    code = main(resume_args(demos, run))
    assert code in (0, 2)
    if code == 2:
        err = capsys.readouterr().err
        assert "Traceback" not in err and sum("error:" in line for line in err.splitlines()) == 1, err
        assert digests(run) == before


@pytest.mark.parametrize("content", ["[1, 2]", '"x"', "null", '{"a": 3}', "\xff\xfe"])
def test_a_damaged_eval_json_is_one_error_line_before_any_test(finished, tmp_path, capsys, content):
    run = copy_of(finished, tmp_path)
    (run / "eval.json").write_bytes(content.encode("latin-1"))
    before = digests(run)
    assert main(["eval", "--run", str(run), "--tests", "2", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "eval.json is corrupted" in err[0]
    assert digests(run) == before


@pytest.mark.parametrize(
    "stored",
    [{}, {"success_rate": "abc"}, {"success_rate": 2.5}, [1, 2], {"success_rate": float("nan")}],
    ids=["empty", "text", "above-1", "list", "nan"],
)
def test_a_damaged_cell_is_computed_again_and_a_report_never_a_traceback(tmp_path, capsys, stored):
    import json

    out, argv = rule_experiment(tmp_path)
    assert main(argv) == 0
    cell = out / "cells" / "rule-run001.json"
    good = json.loads(cell.read_text())["result"]
    record = json.loads(cell.read_text())
    cell.write_text(json.dumps({**record, "result": stored}))
    assert main([*argv, "--report"]) == 0  # reported as not finished
    assert "1 cells are not finished yet" in (out / "table.md").read_text()
    assert main(argv) == 0  # computed again
    assert json.loads(cell.read_text())["result"] == good
    assert "Traceback" not in capsys.readouterr().err


@pytest.mark.parametrize("content", ["[]", '"x"', "\xff"])
def test_a_damaged_experiment_json_is_one_error_line(tmp_path, capsys, content):
    spec = tmp_path / "e.toml"
    spec.write_text('kind = "compare"\nruns = 1\ntests = 1\nmethods = ["rule"]\n')
    out = tmp_path / "out"
    out.mkdir()
    (out / "experiment.json").write_bytes(content.encode("latin-1"))
    assert main(["compare", "--task", str(spec), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "experiment.json is corrupted" in err[0]


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["demos", "--episodes", "1", "--seed", str(10**23), "--out", "x.npz"], "--seed: expected a seed"),
        (["demos", "--episodes", "1", "--seed", "-1", "--out", "x.npz"], "--seed: expected a seed"),
        (
            ["compare", "--task", "table1", "--workers", "2147483647"],
            "--workers: expected a number of processes",
        ),
        (
            ["train", "--demos", "minari:foo", "--out", "mm"],
            "Minari dataset id 'foo': expected [NAMESPACE/]NAME",
        ),
    ],
)
def test_values_out_of_range_are_one_error_line(tmp_path, monkeypatch, capsys, argv, needle):
    monkeypatch.chdir(tmp_path)
    if argv[0] == "train":
        pytest.importorskip("minari")
    try:
        code = main([*argv, "--quiet"])
    except SystemExit as exc:  # argparse refuses an option's value itself
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and needle in err and "Traceback" not in err and not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["leaderboard", "nothing_here"], "nothing_here"),  # its lock would make runs/ for runs/leaderboard
        (["render", "--policy", "rule", "--out", "a.png", "--montage", "a.png"], "name the same file"),
    ],
)
def test_a_refused_command_creates_nothing(tmp_path, monkeypatch, capsys, argv, needle):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err and "being written" not in err and not list(tmp_path.iterdir())


def test_a_run_directory_that_does_not_exist_has_no_leftovers_and_is_not_made(tmp_path):
    from nirl_mj.data.rundir import RunDir

    assert RunDir(tmp_path / "a" / "run").remove_leftovers() == [] and not (tmp_path / "a").exists()


def test_the_scratch_folder_of_a_killed_collection_is_removed_by_the_next(tmp_path, monkeypatch):
    import tempfile

    from nirl_mj.experiments.demos import SCRATCH, ExpertConfig, collect
    from nirl_mj.sim import spec as specs

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    )
    orphan = tmp_path / f"{SCRATCH}{int(dead.stdout)}-abcd"
    orphan.mkdir()
    (orphan / "episode-000000.npz").write_bytes(b"half")
    alive = tmp_path / f"{SCRATCH}{os.getpid()}-efgh"  # a live collection's: kept
    alive.mkdir()
    task = specs.replace(specs.load_task("navigate"), robot={"drive": "planar"}, control={"step_budget": 4})
    collect(task, ExpertConfig("rule"), 1, 0)
    assert not orphan.exists() and alive.exists()


def test_the_temporary_file_of_a_killed_writer_is_removed_by_the_next_writer_of_that_file(tmp_path):
    """A dataset's writer killed mid-write leaves ``.NAME.<hex>.tmp.npz`` beside it; the next writer of
    that file (who holds its lock) removes it, and no other file's."""
    killed = tmp_path / ".d.npz.1a2b3c4d.tmp.npz"
    killed.write_bytes(b"half a dataset")
    other = tmp_path / ".e.npz.1a2b3c4d.tmp.npz"  # another file's (its writer may be alive)
    other.write_bytes(b"half another dataset")
    assert main(["demos", "--expert", "rule", "--episodes", "1", "--workers", "1", "--quiet",
                 "--out", str(tmp_path / "d.npz"), *TINY]) == 0  # fmt: skip
    assert not killed.exists() and other.exists() and (tmp_path / "d.npz").is_file()


def test_a_resume_of_a_training_that_had_not_started_says_to_run_it_without_resume(demos, tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / f".{RUN_FILE}.1a2b3c4d.tmp").write_text('{"half": ')  # killed in its first write
    assert main(resume_args(demos, run)) == 2
    err = capsys.readouterr().err
    assert "nothing to resume" in err and "the same command without --resume" in err
    assert main(train_args(demos, run)) == 0


def test_a_second_writer_of_a_dataset_a_main_job_a_leaderboard_or_a_video_is_refused(tmp_path, capsys):
    demos, main_out = tmp_path / "d.npz", tmp_path / "main"
    board, clip = tmp_path / "board", tmp_path / "c.mp4"
    (tmp_path / "e").mkdir()
    results, run_it = rule_experiment(tmp_path / "e")  # a leaderboard's source, read before the lock
    assert main(run_it) == 0
    capsys.readouterr()
    commands = {demos: ["demos", "--episodes", "1", "--out", str(demos), "--quiet", *TINY],
                main_out: ["run", "--demos", "1", "--episodes", "1", "--tests", "1", "--out", str(main_out),
                           "--quiet", *TINY],
                board: ["leaderboard", str(results), "--out", str(board)],
                clip: ["render", "--policy", "rule", "--out", str(clip)]}  # fmt: skip
    for target, argv in commands.items():
        process, pid = hold(target, tmp_path)
        try:
            assert main(argv) == 2
            assert f"is being written by process {pid}" in capsys.readouterr().err
            assert not target.exists()
        finally:
            process.send_signal(signal.SIGKILL)
            process.wait()
        (tmp_path / "ready").unlink()


def test_a_dataset_with_a_duplicate_entry_or_a_lying_header_is_one_error_line(demos, tmp_path, capsys):
    import io
    import zipfile

    with zipfile.ZipFile(demos) as z:
        data = {n: z.read(n) for n in z.namelist()}
    dup, huge = tmp_path / "dup.npz", tmp_path / "huge.npz"
    with warnings.catch_warnings(), zipfile.ZipFile(dup, "w") as z:
        warnings.simplefilter("ignore")  # zipfile warns of the duplicate name it is asked to write
        for name, raw in data.items():
            z.writestr(name, raw)
        z.writestr("actions.npy", data["features.npy"])  # a second, different "actions"
    with zipfile.ZipFile(huge, "w") as z:
        for name, raw in data.items():
            if name == "features.npy":
                array = np.lib.format.read_array(io.BytesIO(raw))
                header = io.BytesIO()
                claim = {"descr": array.dtype.str, "fortran_order": False, "shape": (10**12, 16)}
                np.lib.format.write_array_header_1_0(header, claim)
                raw = header.getvalue() + array.tobytes()
            z.writestr(name, raw)
    for path, needle in (
        (dup, "holds entry 'actions.npy' twice"),
        (huge, "claims shape (1000000000000, 16)"),
    ):
        assert main(["inspect", str(path)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0]


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        (lambda task: task["control"].update(speed=-1.0), "control.speed"),
        (lambda task: task["arena"].update(colour="red"), "unknown key(s) colour"),
        (lambda task: task.update(robot={"drive": "hovercraft"}), "robot.drive"),
    ],
)
def test_a_dataset_whose_task_record_breaks_the_task_file_s_rules_is_one_error_line(
    demos, tmp_path, capsys, change, needle
):
    """A dataset's task record is checked as a task file is (issue 34, defect 8): a negative speed,
    an unknown key or a drive that does not exist is refused naming the file, never read as valid."""
    import json

    with np.load(demos) as stored:
        arrays = {k: stored[k] for k in stored.files}
    tasks = [json.loads(text) for text in arrays["tasks"].tolist()]
    change(tasks[0])
    arrays["tasks"] = np.array([json.dumps(task) for task in tasks])
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    assert main(["inspect", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "task record" in err[0] and needle in err[0], err


def test_a_bare_dataset_reader_checks_task_records_without_the_gymnasium_extra(demos, tmp_path):
    """The task file's rules reach ``load_dataset`` from ``import nirl_mj`` itself: without Gymnasium
    (whose registration also imports the task specs) a record with a negative speed is refused."""
    import json

    with np.load(demos) as stored:
        arrays = {k: stored[k] for k in stored.files}
    tasks = [json.loads(text) for text in arrays["tasks"].tolist()]
    tasks[0]["control"]["speed"] = -1.0
    arrays["tasks"] = np.array([json.dumps(task) for task in tasks])
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    code = ("import sys; sys.modules['gymnasium'] = None\n"
            "from nirl_mj.data.dataset import DatasetError, load_dataset\n"
            f"try:\n    load_dataset({str(bad)!r})\n"
            "except DatasetError as exc:\n    print('refused:', exc)")  # fmt: skip
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.startswith("refused:") and "control.speed" in done.stdout, done.stdout + done.stderr


@pytest.mark.parametrize("line", ["[1]", "not json", '"x"'])
def test_a_damaged_metrics_line_is_one_error_naming_the_file_and_line(finished, tmp_path, line):
    from nirl_mj.data.rundir import RunDir, RunError

    run = copy_of(finished, tmp_path)
    with open(run / METRICS_FILE, "a") as f:
        f.write(line + "\n")
    with pytest.raises(RunError, match=r"metrics.jsonl: line 4 "):
        RunDir(run).read_metrics()


WRONG_TYPES = [("seed", "abc", "seed = 'abc', not a whole number"), ("seed", 1.5, "seed = 1.5"),
               ("demos", 5, "demos = 5"), ("train_seeds", "oops", "train_seeds is not a list"),
               ("demo_seeds", None, "demo_seeds is not a list")]  # fmt: skip


@pytest.mark.parametrize(("key", "value", "needle"), WRONG_TYPES)
def test_a_run_record_of_the_wrong_types_is_refused(finished, tmp_path, capsys, key, value, needle):
    import json

    run = copy_of(finished, tmp_path)
    record = json.loads((run / RUN_FILE).read_text())
    (run / RUN_FILE).write_text(json.dumps({**record, key: value}))
    before = digests(run)
    assert main(["eval", "--run", str(run), "--tests", "1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{RUN_FILE} is corrupted: {needle}" in err and "Traceback" not in err
    assert digests(run) == before


def test_a_torn_metrics_row_is_not_counted_as_an_iteration(finished, tmp_path):
    from nirl_mj.data.rundir import RunDir, RunError

    run = copy_of(finished, tmp_path)
    text = (run / METRICS_FILE).read_text()
    assert RunDir(run).iterations_done() == 3
    (run / METRICS_FILE).write_text(text[:-40])  # the last row cut (disk damage, a hand edit)
    assert RunDir(run).iterations_done() == 2 == len(RunDir(run).read_metrics())
    (run / METRICS_FILE).write_bytes(text.encode() + b"\xff\n")  # not UTF-8: named, and left as it is
    with pytest.raises(RunError, match=r"metrics.jsonl is corrupted \(not UTF-8 text"):
        RunDir(run).keep_metrics(3)
    assert (run / METRICS_FILE).read_bytes().endswith(b"\xff\n")


def test_policy_weights_that_are_not_finite_are_refused_naming_the_file(finished, tmp_path, capsys):
    """A damaged policy (NaN weights) is one error line, never an evaluation of a broken network;
    the same for a kept policy of the checkpoint (--which N)."""
    run = copy_of(finished, tmp_path)
    for name, key in ((POLICY_FILE, "selected/W1"), (CHECKPOINT_FILE, "kept_W2")):
        with np.load(run / name) as stored:
            arrays = {k: stored[k] for k in stored.files}
        arrays[key] = np.full_like(arrays[key], np.nan)
        np.savez(run / name, **arrays)
    before = digests(run)
    assert main(["eval", "--run", str(run), "--tests", "1", "--quiet"]) == 2
    assert "policy.npz's selected policy is corrupted: W1 is not finite" in capsys.readouterr().err
    assert main(["eval", "--run", str(run), "--which", "1", "--tests", "1", "--quiet"]) == 2
    assert "checkpoint.npz's policy of iteration 1 is corrupted: W2 is not finite" in capsys.readouterr().err
    assert digests(run) == before


def test_a_dataset_whose_task_record_lacks_what_readers_take_from_it_is_refused(demos, tmp_path, capsys):
    import json

    with np.load(demos) as stored:
        arrays = {k: stored[k] for k in stored.files}
    tasks = [json.loads(text) for text in arrays["tasks"].tolist()]
    del tasks[0]["sensing"]  # the task file's rules would fill in its defaults
    arrays["tasks"] = np.array([json.dumps(task) for task in tasks])
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    assert main(["inspect", str(bad)]) == 2
    assert "tasks[0] lacks sensing.range, sensing.danger7_clearance" in capsys.readouterr().err


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_damage_to_any_stored_file_is_refused_in_one_line_never_a_traceback(
    finished, demos, tmp_path_factory, capsys, data
):
    """Every file of a finished run and the dataset, truncated, byte-flipped or replaced by another
    JSON shape: `eval` (the run) or `inspect` (the dataset) exits 0, or 2 with one error line and the
    directory unchanged."""
    import shutil

    tmp = tmp_path_factory.mktemp("any")
    run = copy_of(finished, tmp)
    dataset = tmp / "d.npz"
    shutil.copy(demos, dataset)
    (run / "eval.json").write_text('{"a": {"success_rate": 0.5}}')
    name = data.draw(st.sampled_from([RUN_FILE, METRICS_FILE, CHECKPOINT_FILE, POLICY_FILE, "reward.json",
                                      "eval.json", "dataset"]))  # fmt: skip
    path = dataset if name == "dataset" else run / name
    path.write_bytes(damaged_bytes(path.read_bytes(), data))
    capsys.readouterr()
    before = digests(run)
    argv = (
        ["inspect", str(dataset)]
        if name == "dataset"
        else ["eval", "--run", str(run), "--tests", "1", "--quiet"]
    )
    code = main(argv)
    err = capsys.readouterr().err
    assert code in (0, 2) and "Traceback" not in err, err
    if code == 2:
        assert len(err.strip().splitlines()) == 1 and digests(run) == before


@pytest.fixture(scope="module")
def experiment_out(tmp_path_factory) -> tuple[Path, list[str]]:
    """A finished tiny compare experiment (the rule, 2 runs of 1 test) and its command."""
    out, argv = rule_experiment(tmp_path_factory.mktemp("experiment"), '["rule", "forward"]')
    assert main(argv) == 0
    return out, argv


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_damage_to_an_experiment_s_files_is_refused_or_recomputed_never_a_traceback(
    experiment_out, tmp_path_factory, capsys, data
):
    """A cell, experiment.json or results.json of a finished experiment, truncated, byte-flipped or
    replaced by JSON of another shape: `compare --report` and `compare` exit 0 (a damaged cell is
    left out of the report, then computed again) or 2 with one error line and the directory as it
    was."""
    import shutil

    finished, argv = experiment_out
    out = tmp_path_factory.mktemp("damaged") / "out"
    shutil.copytree(finished, out)
    argv = [str(out) if a == str(finished) else a for a in argv]
    files = sorted(p.relative_to(out) for p in [*out.glob("cells/*.json"), out / "experiment.json",
                                                 out / "results.json"])  # fmt: skip
    path = out / data.draw(st.sampled_from(files))
    path.write_bytes(damaged_bytes(path.read_bytes(), data))
    for command in ([*argv, "--report"], argv):
        capsys.readouterr()
        before = tree_digests(out)
        code = main(command)
        err = capsys.readouterr().err
        assert code in (0, 2) and "Traceback" not in err, err
        if code == 2:
            assert len(err.strip().splitlines()) == 1 and tree_digests(out) == before, err


@pytest.mark.parametrize(
    ("damage", "said"),
    [(lambda text: text[: len(text) // 2], "is not JSON (a write cut short?)"),
     (lambda text: "[1, 2]", "holds no result"),
     (lambda text: text.replace('"id": "c-run000"', '"id": "d-run001"'), "holds cell d-run001"),
     (lambda text: text.replace('"result": 7', '"result": -1'),
      "holds a result that cannot be this cell's: negative")],
)  # fmt: skip
def test_a_damaged_cell_file_is_named_with_what_is_wrong_and_computed_again(tmp_path, damage, said):
    """A stored cell that holds no finished cell is not silently dropped: the run says which file
    and why, once, then computes the cell again (and stores it whole)."""
    from nirl_mj.experiments.executors import Cell, CellStore, Executor

    store = CellStore(tmp_path / "cells", check=lambda result, cell_id: "negative" if result < 0 else None)
    store.save("c-run000", 7, seconds=0.1, attempts=1)
    path = store.path("c-run000")
    assert store.problem("c-run000") is None and store.problem("never-run") is None
    path.write_text(damage(path.read_text()))
    assert store.problem("c-run000") == said and store.load("c-run000") is None
    told = []
    with Executor("serial") as executor:
        report = executor.run(
            [Cell("c-run000", int, ("7",))], store, on_retry=lambda i, why: told.append((i, why))
        )
    assert told == [("c-run000", f"{path} {said}: computed again")]
    assert (
        report.results == {"c-run000": 7}
        and store.load("c-run000") == 7
        and store.problem("c-run000") is None
    )


def test_an_output_whose_lock_cannot_be_written_is_refused_naming_where_the_lock_goes(tmp_path, monkeypatch):
    """The lock goes beside the output; where that directory is not writable the refusal says so
    (not a bare errno), and nothing is left behind. (Root writes anywhere, so the refusal of the
    operating system is simulated.)"""
    from nirl_mj.data import lock as lock_module

    real_open = os.open

    def refusing_open(path, *args, **kwargs):
        if str(path).endswith(".lock"):
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(lock_module.os, "open", refusing_open)
    said = r"its lock .*\.out\.lock \(in the output's parent directory\) cannot be written: Permission denied"
    with pytest.raises(PermissionError, match=said):
        lock_module.DirectoryLock(tmp_path / "out").acquire()
    assert list(tmp_path.iterdir()) == []


def test_a_writer_that_waited_for_a_released_lock_holds_the_new_lock_file_so_a_third_is_refused(
    tmp_path, monkeypatch
):
    """A releasing holder removes its lock file: a writer that was waiting (``wait=True``, as an
    eval.json update does) then holds a removed file, and must lock the file there now; else a third
    writer, which opens the new file, would write alongside it. (Locks of one process's threads
    conflict as other processes' do: flock locks each open file.)"""
    import fcntl
    import threading

    from nirl_mj.data.lock import DirectoryLock, LockedError

    out = tmp_path / "out"
    first = DirectoryLock(out).acquire()
    waiting, failed = threading.Event(), []
    flock = fcntl.flock

    def spied_flock(fd, operation):
        if operation == fcntl.LOCK_EX:  # the blocking wait behind the first writer: the second writer
            waiting.set()  # holds the file the first removes, whether released before this call or in it
        return flock(fd, operation)

    def wait_for_it() -> None:
        try:
            second.acquire()
        except BaseException as exc:  # reported below, not lost in the thread
            failed.append(exc)
        finally:
            waiting.set()

    monkeypatch.setattr(fcntl, "flock", spied_flock)
    second = DirectoryLock(out, wait=True)
    thread = threading.Thread(target=wait_for_it)
    thread.start()
    assert waiting.wait(timeout=600)  # a guard against a hang if the wait is ever reached otherwise
    first.release()
    thread.join(timeout=600)
    monkeypatch.undo()
    assert not thread.is_alive()
    assert not failed and second.lock_file.is_file()
    with pytest.raises(LockedError, match=f"being written by process {os.getpid()}"):
        DirectoryLock(out).acquire()
    second.release()


def test_a_damaged_training_run_of_an_experiment_fails_its_cell_naming_the_file(tmp_path, capsys):
    """A damaged stored run is never trained on or tested as if whole: its cell fails (retried, as a
    failed read may pass), and the line says which file."""
    from helpers import TINY_CONFIG, TINY_TABLES

    spec = tmp_path / "e.toml"
    spec.write_text(f'kind = "compare"\nruns = 1\ntests = 1\nmethods = ["NIRL"]\n{TINY_TABLES}{TINY_CONFIG}')
    out = tmp_path / "out"
    argv = ["compare", "--task", str(spec), "--out", str(out), "--executor", "serial", "--quiet"]
    assert main(argv) == 0
    (out / "cells" / "NIRL-run000.json").unlink()
    policy = next((out / "runs" / "NIRL").glob(f"*/{POLICY_FILE}"))
    policy.write_bytes(policy.read_bytes()[:300])
    capsys.readouterr()
    assert main(argv) == 1
    failed = [line for line in capsys.readouterr().err.splitlines() if line.startswith("FAILED")]
    assert len(failed) == 1 and f"{policy} is corrupted" in failed[0]


def test_a_resume_whose_checkpoint_is_gone_is_refused_not_started_over(demos, finished, tmp_path, capsys):
    """Only a run killed before its first checkpoint starts over; one with iterations recorded and no
    checkpoint would have them replaced."""
    import shutil

    run = shutil.copytree(finished, tmp_path / "run")
    (run / CHECKPOINT_FILE).unlink()
    before = digests(run)
    capsys.readouterr()
    assert main(resume_args(demos, run)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"has iterations recorded but no {CHECKPOINT_FILE}" in err[0]
    assert digests(run) == before  # nothing replaced
