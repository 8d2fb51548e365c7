"""The run directory type owns every file of a run: names, reads, writes, clear errors."""

import numpy as np
import pytest

from nirl_mj.data.rundir import EVAL_FILE, METRICS_FILE, RunDir, RunError


def test_a_run_directory_round_trips_its_files(tmp_path):
    run = RunDir(tmp_path / "run")
    assert run.is_empty() and not run.is_run and not run.is_finished
    base = {"task": {}, "config": {}, "seed": 1, "demos": "d.npz", "demo_seeds": [], "validation_seeds": []}
    run.write_record(base)
    run.start_metrics()
    for i in range(3):
        run.append_metrics({"episode": i})
    assert run.iterations_done() == 3
    run.keep_metrics(2)  # what a resume does with a row past the checkpoint
    assert run.read_metrics() == [{"episode": 0}, {"episode": 1}]
    w = {"W1": np.arange(6.0).reshape(2, 3), "W2": np.ones((6, 3))}
    run.write_checkpoint({"theta": np.zeros(3)})
    run.write_policy(w, {k: -v for k, v in w.items()})
    np.testing.assert_array_equal(run.read_policy("last")["W1"], -w["W1"])
    assert not run.is_finished  # the final record has not been written
    run.write_record({**base, "train_seeds": []})
    assert run.is_finished and run.has_checkpoint
    run.add_evaluation("a", {"x": 1})
    run.add_evaluation("b", {"x": 2})
    assert run.read_evaluations() == {"a": {"x": 1}, "b": {"x": 2}}
    assert {METRICS_FILE, EVAL_FILE} <= run.names()


def test_missing_or_corrupt_files_give_clear_errors(tmp_path):
    run = RunDir(tmp_path)
    with pytest.raises(RunError, match="not a nirl-mj run directory"):
        run.read_record()
    with pytest.raises(RunError, match="no checkpoint to resume from"):
        run.read_checkpoint()
    with pytest.raises(RunError, match="has not finished"):
        run.read_policy()
    with pytest.raises(RunError, match="accepted: selected, last"):
        run.read_policy("best")
    run.file("run.json").write_text('{"seed": 1}')
    with pytest.raises(RunError, match="lacks task, config, demos"):
        run.read_record()
    run.file(EVAL_FILE).write_text("{")
    with pytest.raises(RunError, match="eval.json is corrupted"):
        run.read_evaluations()
    run.file("policy.npz").write_bytes(b"not a zip")
    with pytest.raises(RunError, match="policy.npz is corrupted .not an .npz archive"):
        run.read_policy()


def _add_evaluations(path, worker: int, count: int) -> None:
    run = RunDir(path)
    for i in range(count):
        run.add_evaluation(f"w{worker}-{i}", {"x": i})


def test_evaluations_of_one_run_in_several_processes_keep_every_entry(tmp_path):
    """eval.json is read, changed and written again: without its lock, two evaluations that overlap
    lose one's entry (measured without it: 30, 31 and 37 of these 100 entries kept)."""
    import multiprocessing

    path = tmp_path / "run"
    path.mkdir()
    context = multiprocessing.get_context("fork")
    workers = [context.Process(target=_add_evaluations, args=(path, w, 25)) for w in range(4)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    assert [worker.exitcode for worker in workers] == [0] * 4
    assert set(RunDir(path).read_evaluations()) == {f"w{w}-{i}" for w in range(4) for i in range(25)}
    assert RunDir(path).names() == {EVAL_FILE}  # the lock file went with its last holder


def test_metrics_rows_are_strict_json_a_missing_margin_null(tmp_path):
    """A run without a reward step (the controls) has no margin (NaN in memory): written as null."""
    import json

    def strict(constant: str) -> None:
        raise ValueError(f"not strict JSON: {constant}")

    run = RunDir(tmp_path / "run")
    run.path.mkdir()
    run.start_metrics()
    run.append_metrics({"episode": 0, "margin": float("nan"), "cost": 0.5, "validation_success": None})
    line = run.file(METRICS_FILE).read_text()
    assert json.loads(line, parse_constant=strict) == {"episode": 0, "margin": None, "cost": 0.5,
                                                        "validation_success": None}  # fmt: skip
    assert run.read_metrics()[0]["margin"] is None
