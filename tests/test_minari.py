"""Datasets as Minari datasets (nirl_mj.gym.minari_export, ``nirl-mj export``, ``train --demos minari:``)."""

from __future__ import annotations

import contextlib
import io
import json
import warnings

import numpy as np
import pytest

pytest.importorskip("gymnasium")  # the optional extra nirl-mj[gym]
minari = pytest.importorskip("minari")

from helpers import damaged_bytes, replay  # noqa: E402

from nirl_mj.cli import main  # noqa: E402
from nirl_mj.data.dataset import load_dataset  # noqa: E402

SMALL = ["--set", "arena.size=[24.0, 24.0]", "--set", "arena.start=[4.0, 4.0]",
         "--set", "arena.target=[20.0, 20.0]", "--set", "arena.static_obstacles=3",
         "--set", "arena.clear_radius=3.0", "--set", 'robot.drive="planar"']  # fmt: skip
ID = "nirl_mj/navigate/sensor-v0"


@pytest.fixture
def exported(tmp_path, monkeypatch):
    """Three sensor-expert demonstrations on a small task, exported to a Minari store in tmp_path."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    demos = tmp_path / "demos.npz"
    assert main(["demos", "--episodes", "3", "--seed", "1", "--workers", "1", "--quiet", "--out", str(demos),
                 *SMALL]) == 0  # fmt: skip
    assert main(["export", str(demos), "--to", "minari", "--id", ID, "--quiet"]) == 0
    return demos


def test_recovered_environment_replays_every_episode_bit_for_bit(exported):
    dataset = minari.load_dataset(ID)
    trajectories = load_dataset(exported)
    assert dataset.total_episodes == 3 and dataset.total_steps == sum(len(t) for t in trajectories)
    env = dataset.recover_environment()
    seeds = [m["seed"] for m in dataset.storage.get_episode_metadata(dataset.episode_indices)]
    assert seeds == [t.arena_seed for t in trajectories]
    for episode, seed in zip(dataset.iterate_episodes(), seeds, strict=True):
        replayed, rewards, ends = replay(env, episode, seed)
        assert set(replayed) == set(episode.observations)
        for key, values in replayed.items():
            assert np.array_equal(np.stack(values), episode.observations[key]), key
        assert np.array_equal(rewards, episode.rewards)
        assert ends == list(zip(episode.terminations, episode.truncations, strict=True))
        assert ends[-1] != (False, False) and not any(t or u for t, u in ends[:-1])


def test_a_minari_dataset_trains_like_its_file(exported, tmp_path):
    from nirl_mj.gym.minari_export import load_minari

    for a, b in zip(load_dataset(exported), load_minari(ID), strict=True):
        for field in ("features", "actions", "ranges", "poses", "times"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), field
        assert (a.arena_seed, a.task, a.speed, a.outcome, a.demonstrator) == (
            b.arena_seed, b.task, b.speed, b.outcome, b.demonstrator)  # fmt: skip
    config = [arg for kv in ("episodes=1", "trajectories_per_episode=2", "validation_arenas=2",
                             "replay_episodes=1") for arg in ("--config", kv)]  # fmt: skip
    run = tmp_path / "run"
    assert main(["train", "--demos", f"minari:{ID}", "--out", str(run), "--quiet", *SMALL, *config]) == 0
    assert json.loads((run / "run.json").read_text())["demos"] == f"minari:{ID}"
    # inspect reads minari:ID as train does: the same summary as the file's
    summaries = []
    for source in (str(exported), f"minari:{ID}"):
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert main(["inspect", source, "--json"]) == 0
        summaries.append(json.loads(out.getvalue().strip().splitlines()[-1]))
    assert summaries[0] == summaries[1]


def test_bad_minari_input_is_a_clear_error(exported, tmp_path, capsys, monkeypatch):
    capsys.readouterr()
    assert main(["export", str(exported), "--to", "minari", "--id", ID, "--quiet"]) == 2
    assert "exists; pass --overwrite to replace it" in capsys.readouterr().err
    assert main(["export", str(exported), "--to", "minari", "--id", ID, "--quiet", "--overwrite"]) == 0
    assert main(["export", str(exported), "--to", "minari", "--id", "no spaces allowed!", "--quiet"]) == 2
    assert "Minari dataset id 'no spaces allowed!'" in capsys.readouterr().err
    assert main(["train", "--demos", "minari:nirl_mj/navigate/none-v0", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "no local Minari dataset 'nirl_mj/navigate/none-v0'" in err and ID in err
    # with no datasets folder at all, the lookup makes none
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "nowhere"))
    assert main(["train", "--demos", "minari:nirl_mj/navigate/none-v0", "--out", str(tmp_path / "r")]) == 2
    assert "no datasets folder" in capsys.readouterr().err and not (tmp_path / "nowhere").exists()


def test_gail_takes_a_minari_id_as_train_does(exported, tmp_path):
    """issue 33: `rl --algo gail --demos minari:ID` was refused although `train` accepted the same id."""
    pytest.importorskip("stable_baselines3")
    run = tmp_path / "gail"
    assert main(["rl", "--algo", "gail", "--demos", f"minari:{ID}", "--steps", "1024", "--envs", "1",
                 "--out", str(run), "--quiet", *SMALL]) == 0  # fmt: skip
    record = json.loads((run / "run.json").read_text())
    assert record["demos"] == f"minari:{ID}"
    assert record["demo_seeds"] == sorted(t.arena_seed for t in load_dataset(exported))


def test_an_export_is_atomic_and_overwrite_replaces_only_a_complete_one(
    exported, tmp_path, capsys, monkeypatch
):
    """issue 34: --overwrite deleted the old dataset before the new one was written, and a killed
    export left a half dataset that both export and --overwrite refused."""
    from minari.storage.datasets_root_dir import get_dataset_path

    import nirl_mj.gym.minari_export as mx

    final = get_dataset_path(ID)
    before = sorted(p.relative_to(final) for p in final.rglob("*"))

    def dies(*args, **kwargs):
        raise KeyboardInterrupt  # killed while Minari writes the new dataset

    with monkeypatch.context() as patch, pytest.raises(KeyboardInterrupt):
        patch.setattr(minari, "create_dataset_from_buffers", dies)
        mx.export_minari(load_dataset(exported), ID, overwrite=True)
    assert sorted(p.relative_to(final) for p in final.rglob("*")) == before  # the old one is intact
    assert ID in minari.list_local_datasets() and not list(final.parent.parent.parent.glob(".nirl-mj-*"))
    # a half dataset left by an export of an older version: refused without --overwrite, replaced with it
    half = get_dataset_path("nirl_mj/navigate/half-v0")
    assert str(half).startswith(str(tmp_path))  # the test's own store
    (half / "data").mkdir(parents=True)
    assert (
        main(["export", str(exported), "--to", "minari", "--id", "nirl_mj/navigate/half-v0", "--quiet"]) == 2
    )
    assert "holds a half-written dataset" in capsys.readouterr().err
    assert main(["export", str(exported), "--to", "minari", "--id", "nirl_mj/navigate/half-v0", "--quiet",
                 "--overwrite"]) == 0  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Minari warns of the half dataset while it lists the store
        assert minari.load_dataset("nirl_mj/navigate/half-v0").total_episodes == 3


def test_minari_episodes_carry_the_outcome_and_is_success_in_their_infos(exported):
    """issue 33: the episodes' infos were empty (no is_success, no outcome)."""
    trajectories = load_dataset(exported)
    for episode, trajectory in zip(minari.load_dataset(ID).iterate_episodes(), trajectories, strict=True):
        infos = episode.infos
        assert len(infos["is_success"]) == len(trajectory) + 1  # the reset's, then one per step
        assert [o.decode() for o in infos["outcome"][:-1]] == ["running"] * len(trajectory)
        assert infos["outcome"][-1].decode() == trajectory.outcome
        assert bool(infos["is_success"][-1]) == trajectory.success and not any(infos["is_success"][:-1])
        assert list(infos["steps"]) == list(range(len(trajectory) + 1))


def test_an_export_killed_between_its_two_renames_loses_neither_dataset(exported, capsys):
    from minari.storage.datasets_root_dir import get_dataset_path

    final = get_dataset_path(ID)
    final.rename(final.with_name(f".{final.name}.old-99999-abcd"))  # set aside, the new one not yet in place
    assert main(["export", str(exported), "--to", "minari", "--id", ID, "--quiet"]) == 2
    assert "exists; pass --overwrite" in capsys.readouterr().err  # the old one is back
    assert minari.load_dataset(ID).total_episodes == 3


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """A Minari store holding one exported dataset, made once (copied by each example below)."""
    import os

    tmp = tmp_path_factory.mktemp("store")
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(tmp / "minari")
    try:
        demos = tmp / "demos.npz"
        assert main(["demos", "--episodes", "2", "--seed", "1", "--workers", "1", "--quiet", "--out",
                     str(demos), *SMALL]) == 0  # fmt: skip
        assert main(["export", str(demos), "--to", "minari", "--id", ID, "--quiet"]) == 0
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH")
        else:
            os.environ["MINARI_DATASETS_PATH"] = old
    return tmp / "minari"


from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_damage_to_a_minari_dataset_is_one_error_line_never_a_traceback(
    store, tmp_path_factory, capsys, data
):
    """A Minari dataset's files (its HDF5 data, its metadata) truncated, byte-flipped or replaced:
    `train --demos minari:ID` trains, or exits 2 with one line naming the dataset (issue 34)."""
    import os
    import shutil

    root = tmp_path_factory.mktemp("damaged") / "minari"
    shutil.copytree(store, root)
    files = sorted(p for p in root.rglob("*") if p.is_file())
    path = data.draw(st.sampled_from(files))
    path.write_bytes(damaged_bytes(path.read_bytes(), data))
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(root)
    try:
        capsys.readouterr()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # minari warns of a misconfigured dataset it then skips
            run = str(root.parent / "run")
            code = main(["train", "--demos", f"minari:{ID}", "--out", run, "--episodes", "1", "--quiet"])
    finally:
        os.environ["MINARI_DATASETS_PATH"] = old if old is not None else ""
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH")
    err = capsys.readouterr().err
    assert code in (0, 2) and "Traceback" not in err, err
    if code == 2:
        lines = [line for line in err.strip().splitlines() if line.startswith("nirl-mj")]
        assert len(lines) == 1 and ID in lines[0], err
