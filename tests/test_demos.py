"""Demonstration collection: noise, predictability, parallel = serial, recordings, the CLI."""

from collections import Counter

import numpy as np
import pytest
import rerun.chunk

from nirl_mj.cli import main
from nirl_mj.data.dataset import load_dataset
from nirl_mj.experiments.demos import ExpertConfig, collect
from nirl_mj.experiments.seeds import episode_seed
from nirl_mj.experts import make_expert
from nirl_mj.experts.noisy import NoisyExpert
from nirl_mj.experts.policies import PolicyAgent
from nirl_mj.inspect.recording import layout_of, record_demonstrations
from nirl_mj.learn.predictability import LogisticRegression, balanced_accuracy
from nirl_mj.sim import spec
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import make_env

# Short, fast episodes: planar drive, a 12-decision budget.
TINY = spec.replace(spec.load_task("navigate"), robot={"drive": "planar"}, control={"step_budget": 12})


class Constant:
    kind = "constant"

    def __init__(self, action):
        self.action = action

    def reset(self, env, timestep):
        pass

    def act(self, timestep):
        return self.action


@pytest.mark.parametrize("intended", [0, 1, 2, 3, 4, 5])
def test_noise_frequencies_match_the_configuration(intended):
    slip, random, n = 0.2, 0.1, 30000
    noisy = NoisyExpert(Constant(intended), slip=slip, random=random, seed=1)
    counts = Counter(noisy.perturb(intended) for _ in range(n))
    slipped_to = {0: (1, 3), 1: (2,), 2: (1,), 3: (4,), 4: (3,), 5: ()}[intended]
    for action in range(6):
        expected = random / 6
        if action == intended:
            expected += (1 - random) * (1 - slip if slipped_to else 1.0)
        if action in slipped_to:
            expected += (1 - random) * slip / len(slipped_to)
        sigma = np.sqrt(expected * (1 - expected) / n)
        assert abs(counts[action] / n - expected) < 5 * sigma + 1e-9, (action, counts[action] / n, expected)


def test_noisy_expert_rejects_bad_probabilities():
    with pytest.raises(ValueError, match="slip = 1.5: must be in"):
        NoisyExpert(Constant(0), slip=1.5)
    with pytest.raises(ValueError, match="unknown expert 'oracle'"):
        make_expert("oracle")


def test_balanced_accuracy_is_mean_per_action_recall():
    y_true = np.array([0, 0, 0, 0, 1, 1, 2, 2])
    y_pred = np.array([0, 0, 0, 0, 0, 1, 2, 0])
    # recalls 1, 1/2, 1/2 -> 2/3, while plain accuracy is 6/8.
    assert balanced_accuracy(y_true, y_pred) == pytest.approx(2 / 3)


def test_logistic_regression_learns_a_linear_rule():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(600, 3))
    y = np.where(x[:, 0] > 0.5, 1, np.where(x[:, 1] > 0.5, 2, 0))
    model = LogisticRegression(l2=1e-4).fit(x, y)
    assert balanced_accuracy(y, model.predict(x)) > 0.9


def test_parallel_collection_equals_serial():
    expert = ExpertConfig("noisy", base="rule", slip=0.3, random=0.2, seed=5)
    serial = collect(TINY, expert, episodes=3, seed=11, workers=1)
    parallel = collect(TINY, expert, episodes=3, seed=11, workers=2)
    for a, b in zip(serial, parallel, strict=True):
        assert a.arena_seed == b.arena_seed
        np.testing.assert_array_equal(a.actions, b.actions)
        np.testing.assert_array_equal(a.poses, b.poses)
        np.testing.assert_array_equal(a.features, b.features)
    assert len({t.arena_seed for t in serial}) == 3


def test_a_collection_stopped_part_way_records_only_the_episodes_it_lacks(tmp_path):
    """``demos`` keeps finished episodes beside its output until it is written: started again, the
    same collection loads them and records the rest, the same dataset as one uninterrupted run."""
    expert, keep = ExpertConfig("noisy", base="rule", slip=0.3, random=0.2, seed=5), tmp_path / ".d.episodes"
    whole = collect(TINY, expert, episodes=4, seed=11)
    recorded = []

    def stop_after_two(trajectory) -> None:
        recorded.append(trajectory)
        if len(recorded) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        collect(TINY, expert, episodes=4, seed=11, on_episode=stop_after_two, keep=keep)
    assert len(list(keep.glob("episode-*.npz"))) == 2
    said = []
    resumed = collect(TINY, expert, episodes=4, seed=11, keep=keep, log=said.append)
    assert said == [f"resumed: 2 of 4 episodes were recorded in {keep}"]
    for a, b in zip(whole, resumed, strict=True):
        np.testing.assert_array_equal(a.actions, b.actions)
        np.testing.assert_array_equal(a.features, b.features)
    # another collection's episodes there are replaced, not taken; a folder of a user's files is refused
    other = collect(TINY, expert, episodes=2, seed=12, keep=keep, log=said.append)
    assert len(said) == 1 and [t.arena_seed for t in other] == [episode_seed(12, i) for i in range(2)]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    with pytest.raises(FileExistsError, match="holds files no collection wrote \\(notes.txt\\)"):
        collect(TINY, expert, episodes=1, seed=11, keep=mine)
    assert (mine / "notes.txt").read_text() == "mine"


def test_trajectory_remembers_its_arena():
    env = make_env(TINY)
    trajectory = run_episode(env, PolicyAgent.named("rule"), episode_seed(3, 0))
    assert layout_of(trajectory) == env.task.layout
    assert trajectory.demonstrator == "rule" and len(trajectory) == 12


def test_rerun_recording_holds_every_demonstration(tmp_path):
    trajectories = collect(TINY, ExpertConfig("rule"), episodes=2, seed=0)
    path = record_demonstrations(tmp_path / "demos.rrd", trajectories)
    rows = Counter()
    for chunk in rerun.chunk.RrdReader(path).store().stream():
        rows[chunk.entity_path] += chunk.num_rows
    for i, t in enumerate(trajectories):
        assert rows[f"/demos/{i:03d}/robot"] == len(t) + 1
        assert rows[f"/demos/{i:03d}/action"] == len(t)
        assert rows[f"/demos/{i:03d}/path"] == 1
        assert rows[f"/demos/{i:03d}/arena/border"] == 1
    assert not list(tmp_path.glob("*.tmp"))


def test_cli_demos_then_inspect(tmp_path, capsys):
    task_file = tmp_path / "tiny.toml"
    task_file.write_text('[robot]\ndrive = "planar"\n[control]\nstep_budget = 6\n')
    out = tmp_path / "demos.npz"
    args = ["demos", "--task", str(task_file), "--expert", "rule", "--episodes", "2", "--out", str(out)]
    assert main([*args, "--workers", "1", "--quiet", "--json"]) == 0
    summary = capsys.readouterr().out.strip().splitlines()[-1]
    assert '"episodes": 2' in summary and '"success_rate"' in summary
    assert len(load_dataset(out)) == 2
    assert not (tmp_path / ".demos.npz.episodes").exists()  # the kept episodes go once it is written
    before = out.read_bytes()
    assert main([*args, "--quiet"]) == 2  # exists: refused, untouched
    assert "pass --overwrite" in capsys.readouterr().err
    assert out.read_bytes() == before
    assert main(["inspect", str(out)]) == 0
    assert "valid nirl-mj dataset" in capsys.readouterr().out


def test_inspect_summarises_a_dataset_whose_first_half_holds_no_decision(tmp_path, capsys):
    import dataclasses

    from nirl_mj.data.dataset import save_dataset

    task = spec.replace(spec.load_task("navigate"), robot={"drive": "planar"}, control={"step_budget": 6})
    episodes = collect(task, ExpertConfig("rule"), episodes=2, seed=0)
    first = episodes[0]
    one_state = {name: getattr(first, name)[:1] for name in ("features", "ranges", "poses", "times")}
    empty = dataclasses.replace(first, actions=first.actions[:0], **one_state)
    save_dataset(tmp_path / "d.npz", [empty, episodes[1]])
    assert main(["inspect", str(tmp_path / "d.npz"), "--json"]) == 0
    out = capsys.readouterr().out
    assert "valid nirl-mj dataset" in out and "predictability: not measured" in out
    assert out.strip().splitlines()[-1].startswith("{")


def test_cli_inspect_bad_file_is_a_clear_error(tmp_path, capsys):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a dataset")
    assert main(["inspect", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("nirl-mj inspect: error:") and "Traceback" not in err
