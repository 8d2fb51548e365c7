"""NIRL training runs: reproducible, resumable, and careful with what is on disk."""

import json

import numpy as np
import pytest

from nirl_mj.data.dataset import DatasetError, save_dataset
from nirl_mj.data.features import N_ACTIONS
from nirl_mj.data.rundir import CHECKPOINT_FILE, RunDir, RunError
from nirl_mj.experiments.demos import ExpertConfig, collect
from nirl_mj.experiments.training import load_policy, train
from nirl_mj.learn.config import LearnerConfig, checked_changes
from nirl_mj.learn.reward import RewardModel, reward_feature_names
from nirl_mj.sim import spec

TINY = spec.replace(spec.load_task("navigate"), robot={"drive": "planar"}, control={"step_budget": 8})


def tiny_config(**changes):
    base = dict(
        episodes=3, trajectories_per_episode=2, validation_arenas=2, validate_every=2, replay_episodes=2
    )
    return LearnerConfig.preset("default", **{**base, **changes})


@pytest.fixture(scope="module")
def demos(tmp_path_factory):
    path = tmp_path_factory.mktemp("demos") / "demos.npz"
    save_dataset(path, collect(TINY, ExpertConfig("rule"), episodes=3, seed=0))
    return path


def weights(run_dir):
    state = RunDir(run_dir).read_checkpoint()
    return state["net_W1"], state["net_W2"], state["theta"]


@pytest.mark.parametrize("variant", ["default", "paper"])
def test_same_seed_gives_identical_weights(tmp_path, demos, variant):
    config = LearnerConfig.preset(variant, episodes=2, trajectories_per_episode=2, validation_arenas=2)
    for name in ("a", "b"):
        train(tmp_path / name, TINY, demos, config, seed=3)
    for x, y in zip(weights(tmp_path / "a"), weights(tmp_path / "b"), strict=True):
        np.testing.assert_array_equal(x, y)
    train(tmp_path / "c", TINY, demos, config, seed=4)
    assert not np.array_equal(weights(tmp_path / "a")[0], weights(tmp_path / "c")[0])


def test_algorithm_1_stops_once_the_margin_is_at_most_epsilon(tmp_path, demos):
    """Lines 6-8: the loop ends after the iteration whose margin t <= epsilon (the paper preset's
    epsilon is 0); the default (None) never stops it, nor -inf, which records written before
    2026-11-30 hold: it reads as None, so that run.json is strict JSON."""

    def strict(constant: str) -> None:
        raise ValueError(f"not strict JSON: {constant}")

    for epsilon, iterations in ((float("inf"), 1), (None, 3), (float("-inf"), 3)):
        run = tmp_path / str(epsilon)
        train(run, TINY, demos, tiny_config(epsilon=epsilon), seed=1)
        assert len(RunDir(run).read_metrics()) == iterations
        assert bool(RunDir(run).read_checkpoint()["stopped"]) == (iterations == 1)
        if iterations == 3:
            record = json.loads((run / "run.json").read_text(), parse_constant=strict)
            assert record["config"]["epsilon"] is None
    assert LearnerConfig.preset("paper").loop.epsilon == 0.0
    assert LearnerConfig().loop.epsilon is None and tiny_config(epsilon=float("nan")).loop.epsilon is None
    # as an experiment file or --config spells it: stored as None too, so experiment.json stays strict
    assert checked_changes({"epsilon": float("-inf")}, "[config]") == {"epsilon": None}
    assert checked_changes({"epsilon": 0}, "[config]") == {"epsilon": 0.0}


def test_a_resume_of_a_run_stopped_by_epsilon_trains_no_further(tmp_path, demos):
    """The stop of lines 6-8 is part of the checkpoint: a resume of such a run adds no iteration."""
    run = tmp_path / "run"
    config = tiny_config(epsilon=float("inf"))  # stops after its first iteration (of 3)
    train(run, TINY, demos, config, seed=1)
    rows = (run / "metrics.jsonl").read_text()
    train(run, TINY, demos, config, seed=1, resume=True)
    assert (run / "metrics.jsonl").read_text() == rows and len(rows.splitlines()) == 1
    assert int(RunDir(run).read_checkpoint()["iteration"]) == 1


@pytest.mark.parametrize("matching", ["occupancy", "policy"])
def test_resume_ends_with_the_weights_of_an_uninterrupted_run(tmp_path, demos, matching):
    """Also for the policy matching, whose reward step keeps the learner's past policies."""
    config = tiny_config(matching=matching)
    train(tmp_path / "whole", TINY, demos, config, seed=1)

    def interrupt(metrics):
        if metrics.episode == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train(tmp_path / "split", TINY, demos, config, seed=1, on_metrics=interrupt)
    assert int(RunDir(tmp_path / "split").read_checkpoint()["iteration"]) == 2
    train(tmp_path / "split", TINY, demos, config, seed=1, resume=True)
    for x, y in zip(weights(tmp_path / "whole"), weights(tmp_path / "split"), strict=True):
        np.testing.assert_array_equal(x, y)
    lines = (tmp_path / "split" / "metrics.jsonl").read_text().splitlines()
    assert len(lines) == 3
    assert lines == (tmp_path / "whole" / "metrics.jsonl").read_text().splitlines()


def test_a_resume_drops_the_metrics_row_written_past_its_checkpoint(tmp_path, demos, monkeypatch):
    """An iteration appends its metrics row, then writes its checkpoint: a stop between the two leaves a
    row the checkpoint does not cover, which the resume writes again (kept, it would be there twice)."""
    config = tiny_config()
    train(tmp_path / "whole", TINY, demos, config, seed=1)
    write_checkpoint, calls = RunDir.write_checkpoint, []

    def stopped(self, arrays):
        calls.append(int(arrays["iteration"]))
        if len(calls) == 2:
            raise KeyboardInterrupt  # the second iteration's row is written, its checkpoint not
        write_checkpoint(self, arrays)

    split = tmp_path / "split"
    with monkeypatch.context() as patch:
        patch.setattr(RunDir, "write_checkpoint", stopped)
        with pytest.raises(KeyboardInterrupt):
            train(split, TINY, demos, config, seed=1)
    assert calls == [1, 2] and len(RunDir(split).read_metrics()) == 2
    assert int(RunDir(split).read_checkpoint()["iteration"]) == 1
    train(split, TINY, demos, config, seed=1, resume=True)
    assert (split / "metrics.jsonl").read_text() == (tmp_path / "whole" / "metrics.jsonl").read_text()


def test_runs_are_never_overwritten_or_mixed(tmp_path, demos):
    config = tiny_config(episodes=1)
    run = tmp_path / "run"
    train(run, TINY, demos, config, seed=0)
    before = (run / CHECKPOINT_FILE).read_bytes()
    with pytest.raises(RunError, match="exists and is not empty; pass --resume"):
        train(run, TINY, demos, config, seed=0)
    with pytest.raises(RunError, match="trained with another config"):
        train(run, TINY, demos, tiny_config(episodes=1, eta=7.5), seed=0, resume=True)
    # a folder without a run record: neither a new run nor a resume, and each says so
    other = tmp_path / "other"
    other.mkdir()
    (other / CHECKPOINT_FILE).write_bytes(before)
    with pytest.raises(RunError, match="holds no run of nirl-mj train .no run.json.: nothing there can be"):
        train(other, TINY, demos, config, seed=0)
    with pytest.raises(RunError, match="not a nirl-mj run directory"):
        train(other, TINY, demos, config, seed=0, resume=True)
    with pytest.raises(RunError, match="trained with another task"):
        train(run, spec.replace(TINY, control={"speed": 3.0}), demos, config, seed=0, resume=True)
    assert (run / CHECKPOINT_FILE).read_bytes() == before
    (run / CHECKPOINT_FILE).write_bytes(before[:100])
    with pytest.raises(RunError, match="corrupted"):
        train(run, TINY, demos, config, seed=0, resume=True)
    with pytest.raises(RunError, match="not a nirl-mj run directory"):
        load_policy(tmp_path)


def test_an_experiments_run_directory_holding_a_strangers_file_is_refused_and_the_file_kept(tmp_path, demos):
    """ensure_trained starts afresh a run killed before its first checkpoint (removing its directory),
    but not a directory holding anything a training does not write."""
    from nirl_mj.experiments.training import ensure_trained

    run = tmp_path / "run"
    run.mkdir()
    (run / "notes.txt").write_text("mine")
    with pytest.raises(RunError, match=rf"holds \['notes.txt'\] but no {CHECKPOINT_FILE}"):
        ensure_trained(run, TINY, demos, tiny_config(), seed=0)
    assert (run / "notes.txt").read_text() == "mine"


def test_foreign_demonstrations_are_a_clear_error(tmp_path):
    bad = tmp_path / "demos.npz"
    np.savez(bad, something=np.zeros(3))
    with pytest.raises(DatasetError):
        train(tmp_path / "run", TINY, bad, tiny_config(), seed=0)
    assert not (tmp_path / "run").exists()


def test_trained_policy_and_named_reward_are_usable(tmp_path, demos):
    run = tmp_path / "run"
    train(run, TINY, demos, tiny_config(episodes=2), seed=0)
    policy, record = load_policy(run)
    assert 0 <= policy(np.zeros(16, dtype=np.float32) + np.eye(16)[7]) < N_ACTIONS
    assert record["task"] == TINY.to_dict()
    reward = RewardModel.from_dict(RunDir(run).read_reward())
    assert set(reward.named()) == set(reward_feature_names("bearing"))  # the default reward features
    phi = np.array([[3, 0, 0, 0, 0, 0, 2, 1, 0, 0, 0, 0, 0, 0, 0, 0]], dtype=np.float32)
    r_all = reward.rewards_all_actions(phi)
    assert r_all.shape == (1, N_ACTIONS)
    assert reward.reward(phi, 4) == pytest.approx(r_all[0, 4])


def test_the_default_selection_runs_no_validation_episode(tmp_path, demos, monkeypatch):
    """The default chooses its policy without the task's success: no validation arena is driven
    (``evaluate`` is the only way a training run measures success)."""
    import nirl_mj.experiments.training as training

    def refuse(*args, **kwargs):
        raise AssertionError("a validation episode ran")

    monkeypatch.setattr(training, "evaluate", refuse)
    record = train(tmp_path / "run", TINY, demos, tiny_config(episodes=3, validate_every=1), seed=0)
    assert record["selection"]["rule"] == "demo_balanced" and "task_success_selection" not in record["reads"]
    monkeypatch.undo()
    with pytest.raises(AssertionError, match="a validation episode ran"):
        monkeypatch.setattr(training, "evaluate", refuse)
        train(tmp_path / "oracle", TINY, demos, tiny_config(episodes=1, selection="validation"), seed=0)


def test_any_kept_iteration_and_the_second_validation_round(tmp_path, demos):
    run = tmp_path / "run"
    record = train(
        run,
        TINY,
        demos,
        tiny_config(episodes=4, validate_every=1, final_candidates=2, selection="validation"),
        seed=0,
    )
    selection = record["selection"]
    # the two best first-round policies were re-validated on as many fresh validation arenas
    assert len(selection["candidates"]) == 2 and selection["iteration"] in map(int, selection["candidates"])
    assert len(record["validation_seeds"]) == 2 * 2 and len(set(record["validation_seeds"])) == 4
    phis = np.random.default_rng(0).integers(0, 8, size=(50, 16))
    for which, iteration in (("last", 3), ("selected", selection["iteration"])):
        a, _ = load_policy(run, which)
        b, _ = load_policy(run, str(iteration))
        assert [a(p) for p in phis] == [b(p) for p in phis]
    with pytest.raises(RunError, match="no iteration 4"):
        load_policy(run, "4")
    with pytest.raises(RunError, match="accepted: selected, last"):
        load_policy(run, "best")
