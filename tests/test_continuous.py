"""Continuous actions in datasets (issue 33): demonstrations, replay, Minari export, evaluation, refusals.

Written from the user's side: a tiny task with continuous actions (24 m arena, 3 obstacles, a short
budget, the planar drive), the commands as a user types them, and what comes back checked.
"""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest
from helpers import replay, run_dataset_doc

from nirl_mj.cli import main
from nirl_mj.data.dataset import DatasetError, dataset_digest, load_dataset, save_dataset
from nirl_mj.sim import spec
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import make_env

TINY = ["arena.size=[24.0, 24.0]", "arena.start=[4.0, 4.0]", "arena.target=[20.0, 20.0]",
        "arena.static_obstacles=3", "arena.clear_radius=3.0", 'robot.drive="planar"',
        "control.step_budget=60", 'control.actions="continuous"']  # fmt: skip
SET = [arg for kv in TINY for arg in ("--set", kv)]
TASK = spec.apply_overrides(spec.load_task("navigate"), TINY)


@pytest.fixture(scope="module")
def demos(tmp_path_factory):
    """Three continuous demonstrations of the sensor expert, recorded as a user does."""
    path = tmp_path_factory.mktemp("continuous") / "demos.npz"
    assert main(["demos", "--expert", "sensor", "--episodes", "3", "--seed", "1", "--workers", "1", "--quiet",
                 "--out", str(path), *SET]) == 0  # fmt: skip
    return path


def _one_line_error(capsys, argv: list[str]) -> str:
    capsys.readouterr()
    assert main([*argv, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err and err.startswith(f"nirl-mj {argv[0]}: error: "), err
    return err


class _Replay:
    """An agent that drives a trajectory's recorded actions again."""

    kind = "replay"

    def __init__(self, actions: np.ndarray) -> None:
        self.actions = actions

    def reset(self, env, timestep) -> None:
        self.t = 0

    def act(self, timestep):
        self.t += 1
        return self.actions[self.t - 1]


def test_continuous_demonstrations_are_float_shares_that_reload_and_say_their_kind(demos, capsys):
    trajectories = load_dataset(demos)
    assert len(trajectories) == 3 and any(t.success for t in trajectories)
    for t in trajectories:
        assert t.action_kind == "continuous" and t.demonstrator == "sensor"
        assert t.actions.dtype == np.float32 and t.actions.shape == (len(t), 2)
        assert np.all(np.abs(t.actions) <= 1.0) and t.task["control"]["actions"] == "continuous"
    shares = np.concatenate([t.actions for t in trajectories])
    assert np.any(shares[:, 1] != 0)  # it turned
    with np.load(demos, allow_pickle=False) as z:  # the record says what it holds (docs/DATASET.md)
        assert int(z["version"]) == 2 and str(z["action_kind"]) == "continuous"
        assert z["actions"].dtype == np.float32 and z["actions"].shape == (sum(map(len, trajectories)), 2)
    capsys.readouterr()
    assert main(["inspect", str(demos), "--json"]) == 0
    out = capsys.readouterr().out
    assert "continuous actions (" in out and "MAP pretreatment" not in out
    summary = json.loads(out.strip().splitlines()[-1])
    namespace = run_dataset_doc(demos)  # docs/DATASET.md's readers, on a continuous file
    assert namespace["kind"] == "continuous" and np.array_equal(namespace["actions"], trajectories[0].actions)
    assert summary["action_kind"] == "continuous" and summary["pairs"] == len(shares)
    assert summary["mean_action"]["forward"] == pytest.approx(float(shares[:, 0].astype(np.float64).mean()))


def test_continuous_demonstrations_replay_bit_for_bit_from_their_arena_seeds(demos):
    from nirl_mj.experiments.demos import ExpertConfig, collect

    trajectories = load_dataset(demos)
    # the expert again, from the same seeds: the same file content
    assert dataset_digest(collect(TASK, ExpertConfig("sensor"), 3, 1)) == dataset_digest(trajectories)
    # the recorded actions alone, from each arena seed: the same states, dm_env and Gymnasium alike
    env = make_env(TASK)
    for t in trajectories:
        again = run_episode(env, _Replay(t.actions), t.arena_seed)
        for field in ("features", "actions", "ranges", "poses", "times"):
            assert np.array_equal(getattr(again, field), getattr(t, field)), field
        assert again.outcome == t.outcome
    gymnasium = pytest.importorskip("gymnasium")
    import nirl_mj  # noqa: F401  (registers the ids)

    t = trajectories[0]
    genv = gymnasium.make("nirl_mj/Navigate-v0", task=t.task)
    assert genv.action_space == gymnasium.spaces.Box(-1.0, 1.0, (2,), np.float32)
    obs, _ = genv.reset(seed=t.arena_seed)
    for i, action in enumerate(t.actions):
        assert genv.action_space.contains(action)
        obs, _, terminated, truncated, info = genv.step(action)
        assert np.array_equal(obs["pose"], t.poses[i + 1])
        assert np.array_equal(obs["features"], t.features[i + 1])
    assert (terminated or truncated) and info["outcome"] == t.outcome
    # the sensor expert as a Gymnasium policy of this environment takes the recorded shares
    from nirl_mj.gym.policies import ExpertPolicy

    policy, taken = ExpertPolicy("sensor", env=genv), []
    obs, _ = genv.reset(seed=t.arena_seed)
    for _ in range(len(t)):
        taken.append(policy(obs))
        obs, *_ = genv.step(taken[-1])
    assert np.array_equal(np.stack(taken), t.actions) and taken[0].dtype == np.float32


def test_continuous_demonstrations_export_to_minari_and_the_recovered_env_replays_them(
    demos, tmp_path, monkeypatch
):
    gymnasium = pytest.importorskip("gymnasium")
    minari = pytest.importorskip("minari")
    from nirl_mj.gym.minari_export import load_minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    dataset_id = "nirl_mj/navigate/continuous-v0"
    assert main(["export", str(demos), "--to", "minari", "--id", dataset_id, "--quiet"]) == 0
    dataset = minari.load_dataset(dataset_id)
    trajectories = load_dataset(demos)
    assert dataset.total_episodes == 3 and dataset.total_steps == sum(len(t) for t in trajectories)
    box = gymnasium.spaces.Box(-1.0, 1.0, (2,), np.float32)
    assert dataset.spec.action_space == box  # the dataset's own record of its action space
    env = dataset.recover_environment()
    assert env.action_space == box and env.unwrapped.task_spec == TASK
    seeds = [m["seed"] for m in dataset.storage.get_episode_metadata(dataset.episode_indices)]
    assert seeds == [t.arena_seed for t in trajectories]
    for episode, seed, t in zip(dataset.iterate_episodes(), seeds, trajectories, strict=True):
        actions = np.asarray(episode.actions)
        assert actions.dtype == np.float32 and actions.shape == (len(t), 2)
        assert np.array_equal(actions, t.actions)
        replayed, rewards, ends = replay(env, episode, seed)
        for key, values in replayed.items():
            assert np.array_equal(np.stack(values), episode.observations[key]), key
        assert np.array_equal(rewards, episode.rewards)
        assert ends == list(zip(episode.terminations, episode.truncations, strict=True))
        assert ends[-1] != (False, False)
    for a, b in zip(trajectories, load_minari(dataset_id), strict=True):  # and back, as the file's
        for field in ("features", "actions", "ranges", "poses", "times"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), field
        assert b.action_kind == "continuous" and (a.arena_seed, a.outcome) == (b.arena_seed, b.outcome)


def test_eval_and_rollout_drive_a_continuous_task(tmp_path, capsys):
    capsys.readouterr()
    assert main(["rollout", "--policy", "rule", "--episodes", "2", "--quiet", *SET]) == 0
    assert "continuous actions (" in capsys.readouterr().out
    assert main(["eval", "--policy", "rule", "--tests", "2", "--quiet", "--json", *SET]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["tests"] == 2 and result["policy"] == "rule"


def test_eval_of_a_continuous_ppo_run_records_the_policys_own_shares(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from nirl_mj.experiments.evaluation import evaluate
    from nirl_mj.experiments.subjects import run_subject

    run = tmp_path / "ppo"
    assert main(["rl", "--algo", "ppo", "--steps", "64", "--envs", "1", "--out", str(run), "--quiet",
                 *SET]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["eval", "--run", str(run), "--tests", "2", "--quiet", "--json"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["tests"] == 2 and result["task"] == TASK.name
    assert json.loads((run / "eval.json").read_text())  # stored with the run
    subject = run_subject(run)
    _, (t,) = evaluate(make_env(subject.task), subject.policy, subject.test_seeds(0, 1), subject.name)
    assert t.action_kind == "continuous" and len(t)
    for phi, action in zip(t.features[:-1], t.actions, strict=True):  # what the model answered, as shares
        assert np.array_equal(action, subject.policy(phi))


def test_discrete_learners_refuse_continuous_demonstrations_in_one_line(demos, tmp_path, capsys):
    accepted = "accepted: demonstrations of discrete actions 0..5"
    err = _one_line_error(capsys, ["train", "--demos", str(demos), "--out", str(tmp_path / "nirl")])
    assert str(demos) in err and "holds continuous actions" in err and accepted in err
    assert not (tmp_path / "nirl" / "run.json").exists()
    err = _one_line_error(capsys, ["eval", "--policy", "bc", "--demos", str(demos), "--tests", "1"])
    assert str(demos) in err and accepted in err
    if importlib.util.find_spec("stable_baselines3"):  # the optional extra nirl-mj[gym]
        err = _one_line_error(capsys, ["rl", "--algo", "gail", "--demos", str(demos), "--steps", "64",
                                       "--out", str(tmp_path / "gail")])  # fmt: skip
        assert str(demos) in err and accepted in err
    err = _one_line_error(capsys, ["demos", "--episodes", "1", "--out", str(tmp_path / "d.npz"), "--rerun",
                                   str(tmp_path / "d.rrd"), *SET])  # fmt: skip
    assert "--rerun: task" in err and not (tmp_path / "d.npz").exists()
    # NIRL on a continuous task is refused as such, before anything is written
    err = _one_line_error(capsys, ["train", "--demos", str(demos), "--out", str(tmp_path / "n2"), *SET])
    assert "has continuous actions" in err and 'accepted: a task with [control] actions = "discrete"' in err
    assert not (tmp_path / "n2").exists()
    from nirl_mj.learn.bc import behaviour_cloning  # and the library, given the trajectories themselves

    with pytest.raises(ValueError, match="holds continuous actions"):
        behaviour_cloning(load_dataset(demos))


def _corrupted(demos, tmp_path, **changes) -> str:
    with np.load(demos, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    for key, value in changes.items():
        if value is None:
            del arrays[key]
        else:
            arrays[key] = value
    path = tmp_path / "bad.npz"
    np.savez_compressed(path, **arrays)
    return str(path)


def test_a_corrupted_continuous_dataset_is_refused_in_one_line_naming_the_file(demos, tmp_path):
    with np.load(demos, allow_pickle=False) as z:
        actions, tasks = z["actions"], z["tasks"]
    nan = actions.copy()
    nan[3, 1] = np.nan
    beyond = actions.copy()
    beyond[2, 0] = 1.5
    discrete_task = json.loads(str(tasks[0]))
    del discrete_task["control"]["actions"]
    cases = {
        "non-finite value (NaN or inf) in 'actions' at row 3": {"actions": nan},
        "wrong shape for 'actions': ": {"actions": np.zeros((len(actions), 3), np.float32)},
        "expected (n, 2)": {"actions": actions[:, :1].copy()},
        "wrong dtype for 'actions': int8, expected float32": {"actions": np.zeros(len(actions), np.int8)},
        "continuous action out of range: actions[2] = [1.5, ": {"actions": beyond},
        "missing key 'action_kind'": {"action_kind": None},
        "unknown action_kind 'sideways'": {"action_kind": np.array("sideways")},
        "tasks[0] has discrete actions": {"tasks": np.array([json.dumps(discrete_task, sort_keys=True)])},
    }
    for needle, changes in cases.items():
        path = _corrupted(demos, tmp_path, **changes)
        with pytest.raises(DatasetError) as caught:
            load_dataset(path)
        message = str(caught.value)
        assert message.startswith(path) and needle in message and "\n" not in message, (needle, message)


def test_discrete_datasets_keep_their_format_and_kinds_do_not_mix(demos, tmp_path):
    from nirl_mj.experts import make_expert

    discrete_task = spec.apply_overrides(TASK, ['control.actions="discrete"'])
    discrete = run_episode(make_env(discrete_task), make_expert("sensor"), 5)
    path = save_dataset(tmp_path / "discrete.npz", [discrete])
    with np.load(path, allow_pickle=False) as z:  # version 1, no new key: files as they always were
        assert int(z["version"]) == 1 and "action_kind" not in z.files and z["actions"].dtype == np.int8
    assert load_dataset(path)[0].action_kind == "discrete"
    with pytest.raises(ValueError, match="mix discrete and continuous actions"):
        save_dataset(tmp_path / "mixed.npz", [discrete, load_dataset(demos)[0]])


def test_the_main_job_and_experiments_refuse_a_continuous_task_before_any_work(tmp_path, capsys):
    """`nirl-mj run` and `nirl-mj compare` on a task with continuous actions refuse the learners that
    choose among six actions in one line, before a demonstration is recorded; the references and PPO
    are accepted on it."""
    from nirl_mj.experiments.definition import ExperimentError, load_experiment

    err = _one_line_error(capsys, ["run", "--out", str(tmp_path / "main"), *SET])
    assert "has continuous actions" in err and "NIRL" in err and "accepted on it: rule" in err
    assert not (tmp_path / "main").exists()
    experiment = tmp_path / "e.toml"
    body = 'kind = "compare"\nruns = 1\ntests = 2\nmethods = {}\n[set.control]\nactions = "continuous"\n'
    experiment.write_text(body.format('["BC", "rule"]'))
    with pytest.raises(ExperimentError, match=r"BC choose among the six discrete actions"):
        load_experiment(experiment)
    experiment.write_text(body.format('["rule", "forward", "expert", "PPO-reward"]'))
    names = [m.name for m in load_experiment(experiment).methods]
    assert names == ["rule", "forward", "expert", "PPO-reward"]
