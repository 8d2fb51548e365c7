"""The RL reference (nirl_mj.experiments.rl, ``nirl-mj rl``) and Stable-Baselines3 on the environments."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

pytest.importorskip("gymnasium")  # the optional extra nirl-mj[gym]
sb3 = pytest.importorskip("stable_baselines3")

from nirl_mj.cli import main  # noqa: E402
from nirl_mj.experiments.definition import ExperimentError, from_dict  # noqa: E402

SMALL = ["--set", "arena.size=[24.0, 24.0]", "--set", "arena.start=[4.0, 4.0]",
         "--set", "arena.target=[20.0, 20.0]", "--set", "arena.static_obstacles=3",
         "--set", "arena.clear_radius=3.0", "--set", 'robot.drive="planar"']  # fmt: skip
GYM_SMALL = [SMALL[i + 1] for i in range(0, len(SMALL), 2)]


def test_ppo_on_the_full_dict_through_subprocess_vector_environments(tmp_path, monkeypatch):
    from stable_baselines3.common.env_util import make_vec_env

    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path))  # SB3's own logger: its folder here, not in /tmp
    from stable_baselines3.common.vec_env import SubprocVecEnv

    # "nirl_mj:" imports nirl_mj in each worker process, which registers the id there.
    envs = make_vec_env("nirl_mj:nirl_mj/Navigate-v0", n_envs=2, seed=0, vec_env_cls=SubprocVecEnv,
                        env_kwargs={"set": GYM_SMALL})  # fmt: skip
    model = sb3.PPO("MultiInputPolicy", envs, n_steps=64, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(128)
    assert model.num_timesteps == 128
    obs = envs.reset()
    actions, _ = model.predict(obs, deterministic=True)
    assert actions.shape == (2,) and set(actions.tolist()) <= set(range(6))
    envs.close()


def test_rl_trains_evaluates_on_held_out_arenas_and_refuses_to_overwrite(tmp_path, capsys):
    run = tmp_path / "dqn"
    # DQN: it trains exactly the steps asked (PPO rounds up to its 1024-decision rollouts).
    args = ["rl", "--algo", "dqn", "--steps", "64", "--seed", "3", "--out", str(run), "--quiet", *SMALL]
    assert main(args) == 0
    record = json.loads((run / "run.json").read_text())
    assert record["kind"] == "rl" and record["steps_done"] == 64 and record["train_seeds"]
    assert (run / "model.zip").is_file()
    assert main(["eval", "--run", str(run), "--tests", "3", "--quiet"]) == 0
    result = json.loads((run / "eval.json").read_text())
    (key,) = result
    assert result[key]["tests"] == 3
    # Held out: the arenas eval drove (its subject's) are none of the training arenas.
    from nirl_mj.experiments.subjects import run_subject

    train, tested = set(record["train_seeds"]), run_subject(run).test_seeds(0, 3)
    assert len(tested) == 3 and not set(tested) & train

    capsys.readouterr()
    assert main(args) == 2
    assert "pass --resume to continue it, --overwrite to replace it" in capsys.readouterr().err
    # on to a larger total, with the run's own task, algorithm and seed (not given: the run's)
    assert main(["rl", "--steps", "128", "--out", str(run), "--quiet", "--resume"]) == 0
    assert json.loads((run / "run.json").read_text())["steps_done"] == 128
    assert main(["rl", "--seed", "4", "--out", str(run), "--quiet", "--resume"]) == 2  # given: checked
    assert "was trained with another seed" in capsys.readouterr().err
    assert main(["rl", "--out", str(tmp_path / "none"), "--quiet", "--resume"]) == 2
    assert "nothing to resume in" in capsys.readouterr().err and not (tmp_path / "none").exists()
    assert main([*args, "--overwrite"]) == 0
    assert main(["eval", "--run", str(run), "--which", "last", "--tests", "2", "--quiet"]) == 0
    assert main(["eval", "--run", str(run), "--which", "3", "--quiet"]) == 2
    assert "an RL run: --which takes selected or last (got '3')" in capsys.readouterr().err


def test_overwrite_replaces_only_an_rl_run(tmp_path, capsys):
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    (other / ".fig.png.0123abcd.tmp.png").write_text("another writer's")  # not this command's to delete
    assert main(["rl", "--steps", "8", "--out", str(other), "--overwrite", "--quiet", *SMALL]) == 2
    assert "not an RL run directory" in capsys.readouterr().err
    assert (other / "notes.txt").read_text() == "mine" and len(list(other.iterdir())) == 2


def test_an_overwrite_with_a_bad_argument_keeps_the_run_it_would_replace(tmp_path, capsys):
    """--overwrite removes the old run only once every argument has been checked (it removed it
    first, and then refused the task name)."""
    run = tmp_path / "run"
    assert main(["rl", "--steps", "8", "--out", str(run), "--quiet", *SMALL]) == 0
    before = {p.name: p.read_bytes() for p in run.iterdir()}
    for bad in (
        ["--task", "no_such_task"],
        ["--envs", "3"],
        ["--algo", "gail", "--demos", str(tmp_path / "x.npz")],
    ):
        assert main(["rl", "--steps", "8", "--out", str(run), "--overwrite", "--quiet", *SMALL, *bad]) == 2
        capsys.readouterr()
        assert {p.name: p.read_bytes() for p in run.iterdir()} == before, bad


def test_gail_and_airl_need_demos_and_the_others_refuse_them(tmp_path, capsys):
    assert main(["rl", "--algo", "gail", "--out", str(tmp_path / "g"), "--quiet", *SMALL]) == 2
    assert "--demos goes with --algo gail or airl" in capsys.readouterr().err
    ppo = ["rl", "--algo", "ppo", "--demos", "d.npz", "--out", str(tmp_path / "p"), "--quiet", *SMALL]
    assert main(ppo) == 2
    assert "got --algo ppo with --demos" in capsys.readouterr().err
    assert not (tmp_path / "g").exists() and not (tmp_path / "p").exists()


def test_rl_methods_are_validated_in_experiment_files():
    data = {"kind": "compare", "methods": ["PPO-reward", "DQN"],
            "method": {"DQN": {"kind": "rl", "algo": "dqn", "steps": 100}}}  # fmt: skip
    experiment = from_dict(data)
    assert [(m.kind, m.algo, m.steps) for m in experiment.methods] == [
        ("rl", "ppo", 100_000),
        ("rl", "dqn", 100),
    ]
    with pytest.raises(ExperimentError, match="accepted: ppo, dqn, gail, airl"):
        from_dict({**data, "method": {"DQN": {"kind": "rl", "algo": "a2c"}}})
    with pytest.raises(
        ExperimentError, match='algo, steps, selection, envs, settings, train_drive apply to kind = "rl" only'
    ):
        from_dict({"kind": "compare", "methods": ["X"], "method": {"X": {"kind": "bc", "steps": 3}}})
    with pytest.raises(ExperimentError, match="compare and suite experiments, not in a sweep"):
        from_dict({"kind": "sweep", "methods": ["PPO-reward"], "obstacles": [5], "speeds": [2.0]})
    # An experiment without an RL method keeps the identity it had before RL methods existed.
    assert "algo" not in from_dict({"kind": "compare", "methods": ["rule"]}).identity()["methods"][0]


def test_compare_runs_an_rl_method_next_to_the_others(tmp_path):
    spec = tmp_path / "rl.toml"
    spec.write_text(
        'kind = "compare"\nruns = 1\ntests = 2\nmethods = ["PPO", "rule"]\n'
        '[method.PPO]\nkind = "rl"\nsteps = 64\n[demos]\nepisodes = 1\n'
        "[set.arena]\nsize = [24.0, 24.0]\nstart = [4.0, 4.0]\ntarget = [20.0, 20.0]\nstatic_obstacles = 3\n"
        '[set.robot]\ndrive = "planar"\n'
    )
    out = tmp_path / "out"
    assert main(["compare", "--task", str(spec), "--out", str(out), "--executor", "serial", "--quiet"]) == 0
    results = json.loads((out / "results.json").read_text())
    assert results["methods"]["PPO"]["runs"] == 1 and results["cells"]["PPO-run000"]["tests"] == 2
    record = json.loads((out / "runs" / "PPO" / "0" / "run.json").read_text())
    assert record["kind"] == "rl" and np.isfinite(results["methods"]["PPO"]["avg"])
    # PPO acts by sampling its policy with a seeded generator: the same actions every time.
    from nirl_mj.experiments.rl import load_rl_policy

    phis = np.random.default_rng(0).integers(0, 2, (30, 16)).astype(np.float32)
    runs = [[load_rl_policy(out / "runs" / "PPO" / "0")[0](phi) for phi in phis] for _ in range(2)]
    assert runs[0] == runs[1] and all(isinstance(a, int) and 0 <= a < 6 for a in runs[0])


def _rule_demos(tmp_path, episodes: int = 2):
    from helpers import OPEN

    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.experiments.demos import ExpertConfig, collect

    path = tmp_path / "demos.npz"
    save_dataset(path, collect(OPEN, ExpertConfig("rule"), episodes=episodes, seed=0))
    return path


def test_every_checkpoint_is_scored_on_the_demonstrations_and_the_best_kept(tmp_path):
    from helpers import OPEN

    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.experiments.rl import _demo_scorer, load_rl_policy, train_rl

    demos = _rule_demos(tmp_path)
    run = tmp_path / "run"
    record = train_rl(run, OPEN, "gail", 3072, seed=0, demos=demos, checkpoint_every=1024, envs=2)
    scores = record["scores"]
    assert [s["steps"] for s in scores] == [1024, 2048, 3072]
    best = max(range(len(scores)), key=lambda i: (scores[i]["score"], i))  # the later one on a tie
    assert record["selected"] == {**scores[best], "file": f"selected-{scores[best]['steps']}.zip"}
    assert record["config"]["selection"] == "demo_balanced" and record["config"]["n_steps"] == 512
    assert "task_success_selection" not in record["reads"]  # GAIL chooses on what it reads anyway
    # The files are the checkpoints the record names: each scores again what was recorded.
    trajectories = load_dataset(demos)
    assert sorted(p.name for p in run.glob("selected*")) == [record["selected"]["file"]]  # older ones removed
    for name, expected in (
        (record["selected"]["file"], scores[best]["score"]),
        ("model.zip", scores[-1]["score"]),
    ):
        model = sb3.PPO.load(run / name, device="cpu")
        assert _demo_scorer(model, trajectories)() == expected
    phi = np.random.default_rng(1).integers(0, 3, (20, 16)).astype(np.float32)
    chosen = [load_rl_policy(run, sampled=False, policy=p)[0] for p in ("selected", "last")]
    if best != len(scores) - 1:  # two different checkpoints may still agree on these states
        model_files = [(run / n).read_bytes() for n in (record["selected"]["file"], "model.zip")]
        assert model_files[0] != model_files[1]
    assert all(0 <= chosen[0](p) < 6 for p in phi)


def test_vectorised_training_draws_every_arena_once_and_scores_its_own_episodes(tmp_path, monkeypatch):
    import tempfile

    from helpers import OPEN

    from nirl_mj.experiments.rl import SUCCESS_WINDOW, train_rl
    from nirl_mj.experiments.seeds import domain_seed

    temp = tmp_path / "tmp"
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    run, envs = tmp_path / "run", 4
    record = train_rl(run, OPEN, "ppo", 1024, seed=2, checkpoint_every=512, envs=envs)
    record = train_rl(run, OPEN, "ppo", 2048, seed=2, checkpoint_every=512, envs=envs, resume=True)
    assert not list(temp.glob("SB3-*"))  # Stable-Baselines3's logger made no SB3-<time> folder there
    seeds = record["train_seeds"]
    # One stream across the environments and the resume: arenas 0, 1, 2, ... of the train domain.
    assert seeds == [domain_seed("train", 2, k) for k in range(len(seeds))]
    assert record["config"]["n_steps"] == 1024 // envs and "task_success_selection" in record["reads"]
    assert len(set(seeds)) == len(seeds) > 2 * envs  # each environment's first arena, twice, and more
    for s in record["scores"]:
        assert 0 < s["episodes"] <= SUCCESS_WINDOW and 0.0 <= s["score"] <= 1.0
    assert {k: v for k, v in record["selected"].items() if k != "file"} in record["scores"]


def test_a_legacy_run_records_no_selection_and_loads_its_last_checkpoint(tmp_path):
    from helpers import OPEN

    from nirl_mj.experiments.rl import SETTINGS, load_rl_policy, train_rl

    record = train_rl(tmp_path / "run", OPEN, "ppo", 1024, seed=0, selection="last")
    assert record["config"] == {"algo": "ppo", **SETTINGS["ppo"]}  # as runs recorded before selection
    assert "selected" not in record and "scores" not in record
    assert not list((tmp_path / "run").glob("selected*"))
    load_rl_policy(tmp_path / "run")  # the last checkpoint
    with pytest.raises(ValueError, match="demo_balanced reads demonstrations; ppo has none"):
        train_rl(tmp_path / "other", OPEN, "ppo", 1024, selection="demo_balanced")
    with pytest.raises(ValueError, match="must divide PPO's rollout"):
        train_rl(tmp_path / "other", OPEN, "ppo", 1024, envs=5)
    with pytest.raises(ValueError, match="envs = 16: must be >= 1 and divide the 5000 decisions"):
        train_rl(tmp_path / "other", OPEN, "ppo", 1024, envs=16)


def test_the_table_rows_of_ppo_gail_and_airl_select_and_say_what_they_read():
    experiment = from_dict({"kind": "compare", "methods": ["PPO-reward", "GAIL", "AIRL", "GAIL-absorbing"]})
    from nirl_mj.experiments.reads import method_reads

    rows = {m.name: m for m in experiment.methods}
    assert rows["PPO-reward"].selection == "validation_success" and "task_success_selection" in method_reads(
        rows["PPO-reward"]
    )
    assert rows["PPO-reward"].settings["act"] == "greedy"  # validated and tested by its mode
    assert rows["GAIL"].selection == rows["AIRL"].selection == "demo_balanced"
    # each chosen on the development domain (tasks/ablations/adversarial_bearing.toml, rl_greedy.toml)
    assert rows["AIRL"].settings == {"inputs": "bearing", "act": "greedy"} and rows["GAIL"].settings == {}
    assert "task_success_selection" not in method_reads(rows["GAIL"])
    identity = {m["name"]: m for m in experiment.identity()["methods"]}
    assert identity["GAIL"]["selection"] == "demo_balanced"
    assert "selection" not in identity["GAIL-absorbing"]  # issue 16's variants: as they were recorded
    with pytest.raises(ExperimentError, match="demo_balanced reads demonstrations"):
        from_dict({"kind": "compare", "methods": ["P"],
                   "method": {"P": {"kind": "rl", "algo": "ppo", "selection": "demo_balanced"}}})  # fmt: skip


def test_an_experiment_may_tune_ppo_within_its_known_settings():
    tuned = {"learning_rate": 1e-4, "n_epochs": 5}
    data = {
        "kind": "compare",
        "methods": ["P"],
        "method": {"P": {"kind": "rl", "algo": "ppo", "settings": tuned}},
    }
    (method,) = from_dict(data).methods
    from nirl_mj.experiments.rl import run_config

    config = run_config(method.algo, method.selection, method.envs, method.settings)
    assert config["learning_rate"] == 1e-4 and config["n_epochs"] == 5
    assert from_dict(data).identity()["methods"][0]["settings"] == {"learning_rate": 1e-4, "n_epochs": 5}
    # untuned methods keep the identity they had before the key existed
    assert "settings" not in from_dict({"kind": "compare", "methods": ["GAIL"]}).identity()["methods"][0]
    for bad, message in (({"lr": 1.0}, "settings.lr: accepted for ppo: learning_rate"),
                         ({"n_epochs": 2.5}, "settings.n_epochs = 2.5: expected an int >= 1"),
                         ({"learning_rate": -1.0}, r"expected a float in \(0.0, inf\)"),
                         ({"gamma": 1.5}, r"expected a float in \(0.0, 1.0\]"),
                         ({"batch_size": 1}, "expected an int >= 2")):  # fmt: skip
        with pytest.raises(ExperimentError, match=message):
            from_dict({**data, "method": {"P": {"kind": "rl", "settings": bad}}})


def test_the_last_checkpoint_holds_the_model_after_its_last_update(tmp_path):
    from helpers import OPEN

    from nirl_mj.experiments.rl import train_rl

    # 1,024 decisions are one PPO rollout; a checkpoint due at that step comes before PPO's update,
    # so the run must save again after it: the same model whatever the checkpoint spacing
    for every in (1024, 2048):
        train_rl(tmp_path / str(every), OPEN, "ppo", 1024, seed=0, checkpoint_every=every, selection="last")
    params = [
        sb3.PPO.load(tmp_path / str(e) / "model.zip", device="cpu").policy.state_dict() for e in (1024, 2048)
    ]
    assert all(np.array_equal(params[0][k].numpy(), params[1][k].numpy()) for k in params[0])


def test_a_resume_scores_on_with_its_success_window_and_a_legacy_run_resumes_from_the_command_line(tmp_path):
    from helpers import OPEN

    from nirl_mj.experiments.rl import train_rl

    run = tmp_path / "run"
    first = train_rl(run, OPEN, "ppo", 1024, seed=1, checkpoint_every=512, envs=4)
    window = first["recent_outcomes"]
    assert window and len(window) <= 30
    record = train_rl(run, OPEN, "ppo", 2048, seed=1, checkpoint_every=512, envs=4, resume=True)
    after = [s for s in record["scores"] if s["steps"] > first["steps_done"]]
    assert after and after[0]["episodes"] >= len(window)  # the saved window, then the new episodes
    # a run recorded before selection existed resumes with its own settings when none are given
    legacy = tmp_path / "legacy"
    train_rl(legacy, OPEN, "ppo", 1024, seed=0, selection="last")
    args = ["rl", "--algo", "ppo", "--steps", "2048", "--out", str(legacy), "--resume", "--quiet"]
    assert main(args) == 0
    assert "selection" not in json.loads((legacy / "run.json").read_text())["config"]


def test_a_run_stopped_while_a_checkpoint_is_scored_resumes_from_the_model_its_record_describes(
    tmp_path, monkeypatch
):
    """The model is written after the scoring (seconds of validation episodes), right before the
    record: a stop during the scoring leaves the model the record describes. One ahead of its record
    (a stop between the two writes) is refused, not trained on past the budget."""
    from helpers import OPEN

    from nirl_mj.data.rundir import RunError
    from nirl_mj.experiments import rl

    calls = []

    def stopped_scorer(model, record, task, seed):
        def score(best):
            calls.append(int(model.num_timesteps))
            if len(calls) == 2:
                raise KeyboardInterrupt  # during the second checkpoint's validation episodes
            return 0.5, 20

        return score

    run, kw = tmp_path / "run", {"seed": 0, "checkpoint_every": 512, "selection": "validation_success"}
    monkeypatch.setattr(rl, "_validation_scorer", stopped_scorer)
    with pytest.raises(KeyboardInterrupt):
        rl.train_rl(run, OPEN, "ppo", 2048, **kw)
    record = json.loads((run / "run.json").read_text())
    saved = sb3.PPO.load(run / "model.zip", device="cpu")
    assert record["steps_done"] == calls[0] == int(saved.num_timesteps) < calls[1]
    monkeypatch.undo()
    # replayed from the seed to the checkpoint, then on to the budget, as an uninterrupted run
    done = rl.train_rl(run, OPEN, "ppo", 2048, resume=True, **kw)["steps_done"]
    assert done == 2048
    # a record behind its model: refused, naming both
    record = json.loads((run / "run.json").read_text())
    (run / "run.json").write_text(json.dumps({**record, "steps_done": 1024}))
    with pytest.raises(RunError, match=f"its model holds {done} decisions but its record 1024"):
        rl.train_rl(run, OPEN, "ppo", 4096, resume=True, **kw)
    # and where the record says the budget was reached (a checkpoint inside PPO's last rollout): not
    # taken as finished either, by a resume or by an experiment's cell
    with pytest.raises(RunError, match=f"its model holds {done} decisions but its record 1024"):
        rl.train_rl(run, OPEN, "ppo", 1024, resume=True, **kw)
    with pytest.raises(RunError, match=f"its model holds {done} decisions but its record 1024"):
        rl.ensure_rl_trained(run, OPEN, "ppo", 1024, 0, selection="validation_success")


def _stopped_at(decisions: int):
    """An ``on_steps`` that stops training (as Ctrl-C would) once it has counted ``decisions``."""
    seen = [0]

    def on_steps(n: int, stats: dict) -> None:
        seen[0] += n
        if seen[0] >= decisions:
            raise KeyboardInterrupt

    return on_steps


def _run_files(run) -> dict:
    """A run's record and the bytes of its models' parameters (a zip's own bytes hold its write time)."""
    import zipfile

    out = {"record": json.loads((run / "run.json").read_text())}
    for path in sorted(run.glob("*.zip")):
        with zipfile.ZipFile(path) as archive:
            out[path.name] = {n: archive.read(n) for n in archive.namelist() if n.endswith(".pth")}
    for path in sorted(run.glob("*.npz")):
        out[path.name] = path.read_bytes()
    return out


@pytest.mark.parametrize(
    ("algo", "selection", "envs", "stop"),
    [("ppo", "validation_success", 2, 1300), ("dqn", "training_success", 1, 700),
     ("gail", "demo_balanced", 2, 900), ("ppo", "last", 1, 1300)],
)  # fmt: skip
def test_a_stopped_run_resumes_to_the_uninterrupted_run_bit_for_bit(
    tmp_path, monkeypatch, algo, selection, envs, stop
):
    """A resume replays the run from its seed to its last checkpoint (the episodes in progress, PPO's
    rollout and DQN's replay buffer are not saved) and trains on: every file ends as an uninterrupted
    run's, though the stop fell inside a rollout. The replay drives no validation episode again."""
    from helpers import OPEN

    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.experiments import rl
    from nirl_mj.experiments.demos import ExpertConfig, collect

    kw = {"seed": 3, "checkpoint_every": 512, "selection": selection, "envs": envs}
    if algo == "gail":
        kw["demos"] = tmp_path / "demos.npz"
        save_dataset(kw["demos"], collect(OPEN, ExpertConfig("rule"), episodes=2, seed=0))
    rl.train_rl(tmp_path / "whole", OPEN, algo, 2048, **kw)
    run = tmp_path / "stopped"
    with pytest.raises(KeyboardInterrupt):
        rl.train_rl(run, OPEN, algo, 2048, on_steps=_stopped_at(stop), **kw)
    stopped_at = json.loads((run / "run.json").read_text())["steps_done"]
    assert 0 < stopped_at < stop  # a checkpoint, then a stop before the next one
    validated = []
    real_scorer = rl._validation_scorer

    def counting_scorer(model, record, task, seed):
        score = real_scorer(model, record, task, seed)

        def counted(best):
            validated.append(int(model.num_timesteps))
            return score(best)

        return counted

    monkeypatch.setattr(rl, "_validation_scorer", counting_scorer)
    reported = []
    rl.train_rl(run, OPEN, algo, 2048, resume=True, on_steps=lambda n, stats: reported.append(n), **kw)
    assert _run_files(run) == _run_files(tmp_path / "whole")
    assert "inexact_resumes" not in _run_files(run)["record"]
    if selection == "validation_success":
        assert validated and min(validated) > stopped_at  # the recorded scores were kept, not driven again
    # the progress counts only the decisions after the checkpoint (the caller's count starts there)
    assert sum(reported) == _run_files(run)["record"]["steps_done"] - stopped_at


def test_a_resume_that_cannot_replay_its_checkpoint_trains_on_and_says_so(tmp_path):
    """A saved model that the replay does not reach (another machine's arithmetic, or a run resumed
    before replays existed: here another seed's model at the same checkpoint) is recorded, and the
    run trains on to its budget from the replay."""
    from helpers import OPEN

    from nirl_mj.experiments import rl

    kw = {"checkpoint_every": 512, "selection": "training_success"}
    with pytest.raises(KeyboardInterrupt):
        rl.train_rl(tmp_path / "run", OPEN, "ppo", 2048, seed=0, on_steps=_stopped_at(1100), **kw)
    done = json.loads((tmp_path / "run" / "run.json").read_text())["steps_done"]
    with pytest.raises(KeyboardInterrupt):
        rl.train_rl(tmp_path / "other", OPEN, "ppo", 2048, seed=1, on_steps=_stopped_at(1100), **kw)
    shutil.copy(
        tmp_path / "other" / "model.zip", tmp_path / "run" / "model.zip"
    )  # same decisions, other weights
    record = rl.train_rl(tmp_path / "run", OPEN, "ppo", 2048, seed=0, resume=True, **kw)
    assert record["inexact_resumes"] == [done] and record["steps_done"] == 2048
    assert json.loads((tmp_path / "run" / "run.json").read_text())["inexact_resumes"] == [done]


def test_a_checkpoint_at_the_budget_inside_ppos_last_rollout_is_not_the_end_of_the_run(tmp_path, monkeypatch):
    """A budget of whole checkpoints but not of whole rollouts (1,536 of 1,024-decision rollouts) has a
    checkpoint at 1,536 inside the loop and its end at 2,048: stopped between the two, the run is not
    taken as finished, by a resume or by an experiment's cell, and ends as the uninterrupted run."""
    from helpers import OPEN

    from nirl_mj.experiments import rl

    kw = {"seed": 0, "checkpoint_every": 512, "selection": "training_success"}
    whole = rl.train_rl(tmp_path / "whole", OPEN, "ppo", 1536, **kw)
    assert whole["steps_done"] == 2048 and whole["finished"]
    run = tmp_path / "stopped"
    with pytest.raises(KeyboardInterrupt):
        rl.train_rl(run, OPEN, "ppo", 1536, on_steps=_stopped_at(1700), **kw)
    record = json.loads((run / "run.json").read_text())
    assert record["steps_done"] == 1536 and not record["finished"]
    resumed = []  # an experiment's cell trains it on (resumes it), as the command does
    monkeypatch.setattr(rl, "train_rl", lambda *args, **kw: resumed.append(kw["resume"]) or {})
    rl.ensure_rl_trained(run, OPEN, "ppo", 1536, 0, selection="training_success")
    monkeypatch.undo()
    assert resumed == [True]
    rl.train_rl(run, OPEN, "ppo", 1536, resume=True, **kw)
    assert _run_files(run) == _run_files(tmp_path / "whole")


def test_a_stop_after_a_resume_to_a_new_total_goes_on_from_the_saved_model(tmp_path):
    """Trained to one total, then on to another: two trainings that no single one from the seed
    equals, so a stop of the second is not replayed (the record lists the budgets) but continued
    from the saved model; a lost model makes a replay unable to vouch for itself, not a crash."""
    from helpers import OPEN

    from nirl_mj.experiments import rl

    kw = {"seed": 0, "checkpoint_every": 512, "selection": "training_success"}
    rl.train_rl(tmp_path / "run", OPEN, "ppo", 1024, **kw)
    with pytest.raises(KeyboardInterrupt):
        rl.train_rl(tmp_path / "run", OPEN, "ppo", 3072, resume=True, on_steps=_stopped_at(1600), **kw)
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["budgets"] == [1024, 3072] and 1024 < record["steps_done"] < 3072
    record = rl.train_rl(tmp_path / "run", OPEN, "ppo", 3072, resume=True, **kw)
    # from the saved model: whole rollouts of 1,024 after its checkpoint, not checked against a replay
    assert record["steps_done"] >= 3072 and record["finished"] and "inexact_resumes" not in record
    # a stopped run whose model is gone: replayed, and said unchecked
    with pytest.raises(KeyboardInterrupt):
        rl.train_rl(tmp_path / "lost", OPEN, "ppo", 2048, on_steps=_stopped_at(1100), **kw)
    done = json.loads((tmp_path / "lost" / "run.json").read_text())["steps_done"]
    (tmp_path / "lost" / "model.zip").unlink()
    record = rl.train_rl(tmp_path / "lost", OPEN, "ppo", 2048, resume=True, **kw)
    assert record["inexact_resumes"] == [done] and record["finished"]


def test_a_saved_model_drives_the_documented_features_environment_through_its_loader(tmp_path):
    """issue 33: PPO.load(model.zip) on observation="features" scored 0 %: the model acts on phi(s)
    scaled by its bounds. load_rl_policy applies that scaling; the raw PPO.load does not."""
    import gymnasium

    from nirl_mj.experiments.rl import load_rl_policy, scaled

    run = tmp_path / "dqn"
    assert main(["rl", "--algo", "dqn", "--steps", "64", "--out", str(run), "--quiet", *SMALL]) == 0
    policy, _ = load_rl_policy(run)
    model = sb3.DQN.load(run / "model.zip", device="cpu")
    env = gymnasium.make("nirl_mj/Navigate-v0", set=GYM_SMALL, observation="features")
    obs, _ = env.reset(seed=0)
    assert policy(obs) == int(model.predict(scaled(obs), deterministic=True)[0])
    assert obs.max() > 1.0 and scaled(obs).max() <= 1.0  # the raw observation is not what the model reads


def test_ppo_on_continuous_actions_trains_in_the_normalised_space_and_acts_in_the_tasks(tmp_path):
    """issue 33: the continuous action space is normalised to [-1, 1]; a trained model's policy on
    phi(s) (load_rl_policy) answers in the task's units, within its bounds."""
    from nirl_mj import make_env
    from nirl_mj.experiments.rl import load_rl_policy
    from nirl_mj.sim.spec import from_dict

    run = tmp_path / "ppo"
    continuous = [*SMALL, "--set", 'control.actions="continuous"']
    assert main(["rl", "--algo", "ppo", "--steps", "64", "--envs", "1", "--out", str(run), "--quiet",
                 *continuous]) == 0  # fmt: skip
    policy, record = load_rl_policy(run)
    twist = policy(np.zeros(16, np.float32))
    assert twist.shape == (2,) and abs(twist[0]) <= 2.0 and abs(twist[1]) <= 2.0943952  # m/s, rad/s
    env = make_env(from_dict(record["task"], "record"), seed=0)
    env.reset()
    env.step(twist)  # the task takes it: within its bounds


def test_validation_selection_drives_every_checkpoint_on_the_same_validation_arenas(tmp_path, monkeypatch):
    from helpers import OPEN

    from nirl_mj.experiments import rl
    from nirl_mj.experiments.evaluation import evaluate
    from nirl_mj.experiments.seeds import domain_seed
    from nirl_mj.sim.task import make_env

    monkeypatch.setattr(rl, "VALIDATION_ARENAS", 3)
    monkeypatch.setattr(rl, "VALIDATION_CUT", False)  # every checkpoint scored in full, to compare below
    run = tmp_path / "run"
    changes = {"lr_schedule": "linear", "target_kl": 0.05}
    record = rl.train_rl(run, OPEN, "ppo", 1024, seed=3, checkpoint_every=512, envs=2,
                         selection="validation_success", changes=changes)  # fmt: skip
    assert record["validation_seeds"] == [domain_seed("validation", 3, k) for k in range(3)]
    assert "task_success_selection" in record["reads"] and record["config"]["lr_schedule"] == "linear"
    assert [(s["steps"], s["episodes"]) for s in record["scores"]] == [(512, 3), (1024, 3)]
    # each score is the saved checkpoint's success, driven as the tests drive it, on those arenas
    env = make_env(OPEN)
    checkpoints = ((record["selected"]["file"], record["selected"]), ("model.zip", record["scores"][-1]))
    for name, entry in checkpoints:
        model = sb3.PPO.load(run / name, device="cpu")
        policy = rl.model_policy(model, record, sampled=True, seed=3, shares=True)
        assert evaluate(env, policy, record["validation_seeds"])[0]["success_rate"] == entry["score"]
    # the learning rate decays linearly to 0 at the run's last decision; the saved model keeps it
    model = sb3.PPO.load(run / "model.zip", device="cpu")
    assert model.lr_schedule(1.0) == pytest.approx(3e-4) and model.lr_schedule(0.0) == 0.0
    assert model.target_kl == 0.05
    with pytest.raises(ValueError, match="settings.lr_schedule = 'cosine': accepted: constant, linear"):
        rl.tuned("ppo", {"lr_schedule": "cosine"})


def test_an_episode_is_its_arena_and_its_actions_whatever_the_environment_drove_before():
    """What validation's reuse rests on (experiments.rl._validation_scorer): an arena driven after
    others, in the same environment, is driven as in a fresh one, on the tyre wheels among obstacles."""
    from nirl_mj.experts.policies import PolicyAgent
    from nirl_mj.sim import spec
    from nirl_mj.sim.episode import run_episode
    from nirl_mj.sim.task import make_env

    arena = {"size": (30.0, 30.0), "start": (5.0, 5.0), "target": (25.0, 25.0), "static_obstacles": 6}
    task = spec.replace(spec.load_task("navigate"), arena=arena, control={"step_budget": 40})
    assert task.robot.drive == "tyre"
    rule = PolicyAgent.named("rule")
    used = make_env(task)
    for arena in (11, 12):
        run_episode(used, rule, arena)
    after, fresh = run_episode(used, rule, 13), run_episode(make_env(task), rule, 13)
    assert len(after.actions) > 5 and after.outcome == fresh.outcome
    for field in ("features", "actions", "poses"):
        np.testing.assert_array_equal(getattr(after, field), getattr(fresh, field))


def test_validation_reuses_an_arena_only_where_the_policy_would_drive_it_again(tmp_path, monkeypatch):
    import torch
    from helpers import OPEN

    from nirl_mj.experiments import rl
    from nirl_mj.experts.policies import PolicyAgent
    from nirl_mj.sim.episode import run_episode
    from nirl_mj.sim.task import make_env

    monkeypatch.setattr(rl, "VALIDATION_ARENAS", 3)
    record = rl.train_rl(tmp_path / "run", OPEN, "dqn", 64, seed=0, checkpoint_every=64,
                         selection="validation_success")  # fmt: skip
    model = sb3.DQN.load(tmp_path / "run" / "model.zip", device="cpu")
    scorer = rl._validation_scorer(model, record, OPEN, 0)
    first = scorer(None)
    assert scorer.reused == 0 and first[1] == 3
    assert scorer(None) == first and scorer.reused == 3  # the same policy: nothing driven again
    with torch.no_grad():  # other weights, the same greedy actions (every Q-value doubled)
        for parameter in model.q_net.q_net[-1].parameters():
            parameter.mul_(2.0)
    assert scorer(None) == first and scorer.reused == 6
    assert rl._validation_scorer(model, record, OPEN, 0)(None) == first
    # another policy: one action in every state, none of those the first took first
    env, policy = make_env(OPEN), rl.model_policy(model, record, None, 0, shares=True)
    firsts = {
        int(run_episode(env, PolicyAgent(policy, "x"), a).actions[0]) for a in record["validation_seeds"]
    }
    only = min(set(range(6)) - firsts)
    with torch.no_grad():
        layer = model.q_net.q_net[-1]
        layer.weight.zero_()
        layer.bias.copy_(torch.eye(6, dtype=layer.bias.dtype)[only])
    changed = scorer(None)
    assert scorer.reused == 6 and changed == rl._validation_scorer(model, record, OPEN, 0)(None)
    assert scorer(None) == changed and scorer.reused == 9  # and then its own episodes are reused


def test_reused_validation_episodes_leave_every_score_and_model_as_driving_them_does(tmp_path, monkeypatch):
    from helpers import OPEN

    from nirl_mj.experiments import rl
    from nirl_mj.sim import spec

    monkeypatch.setattr(rl, "VALIDATION_ARENAS", 3)
    monkeypatch.setattr(rl, "VALIDATION_CUT", False)  # every arena scored, so that reuse has the most to do
    reused, real_scorer = [], rl._validation_scorer

    def spy_scorer(model, record, task, seed):
        scorer = real_scorer(model, record, task, seed)

        def score(best):
            result = scorer(best)
            reused.append(scorer.reused)
            return result

        return score

    monkeypatch.setattr(rl, "_validation_scorer", spy_scorer)
    task = spec.replace(OPEN, control={"step_budget": 40})  # an untrained policy times out: soon
    for reuse in (True, False):
        monkeypatch.setattr(rl, "VALIDATION_REUSE", reuse)
        rl.train_rl(tmp_path / str(reuse), task, "ppo", 1024, seed=3, checkpoint_every=256, envs=2,
                    selection="validation_success", changes={"act": "greedy"})  # fmt: skip
    on, off = reused[: len(reused) // 2], reused[len(reused) // 2 :]
    # inside PPO's one rollout the policy stays: its episodes are reused, then driven after the update
    assert on[:3] == [0, 3, 6] and off == [0, 0, 0, 0]
    assert _run_files(tmp_path / "True") == _run_files(tmp_path / "False")


def test_of_checkpoints_with_equal_validation_scores_the_later_is_selected(tmp_path, monkeypatch):
    """Ties go to the later checkpoint (nirl_mj.learn.selection's rule): every checkpoint scored 1/2."""
    from helpers import OPEN

    from nirl_mj.experiments import rl

    def equal_scorer(model, record, task, seed):
        return lambda best: (0.5, len(record["validation_seeds"]))  # every arena driven

    monkeypatch.setattr(rl, "_validation_scorer", equal_scorer)
    record = rl.train_rl(tmp_path / "run", OPEN, "dqn", 128, seed=0, checkpoint_every=32,
                         selection="validation_success")  # fmt: skip
    assert [(s["steps"], s["score"]) for s in record["scores"]] == [(k, 0.5) for k in (32, 64, 96, 128)]
    assert record["selected"]["steps"] == 128 and (tmp_path / "run" / record["selected"]["file"]).is_file()


def test_validation_arenas_sets_how_many_arenas_score_a_checkpoint_the_defaults_first(tmp_path):
    from helpers import OPEN

    from nirl_mj.experiments import rl
    from nirl_mj.experiments.seeds import domain_seed

    record = rl.train_rl(tmp_path / "run", OPEN, "ppo", 512, seed=3, checkpoint_every=512, envs=2,
                         selection="validation_success", changes={"validation_arenas": 2})  # fmt: skip
    assert record["validation_seeds"] == [domain_seed("validation", 3, k) for k in range(2)]
    assert record["config"]["validation_arenas"] == 2 and {s["episodes"] for s in record["scores"]} == {2}
    # the default number written out is the default's configuration (and identity)
    default = rl.run_config("ppo", "validation_success", 8)
    assert (
        rl.run_config("ppo", "validation_success", 8, {"validation_arenas": rl.VALIDATION_ARENAS}) == default
    )
    with pytest.raises(
        ValueError, match="validation_arenas goes with selection validation_success, not last"
    ):
        rl.run_config("ppo", "last", 1, {"validation_arenas": 50})
    with pytest.raises(ValueError, match="settings.validation_arenas = 0: expected an int >= 1"):
        rl.tuned("ppo", {"validation_arenas": 0})


def test_ppo_may_see_phi_as_nirls_bearing_code(tmp_path):
    from helpers import OPEN

    from nirl_mj.experiments import rl
    from nirl_mj.learn.inputs import NetworkInputs

    record = rl.train_rl(tmp_path / "run", OPEN, "ppo", 256, seed=1, checkpoint_every=256, envs=2,
                         selection="last", changes={"inputs": "bearing"})  # fmt: skip
    model = sb3.PPO.load(tmp_path / "run" / "model.zip", device="cpu")
    assert model.observation_space.shape == (17,) and record["config"]["inputs"] == "bearing"
    phi = np.array([0, 0, 1, 2, 0, 0, 7, 3, 1, 0, 1, 0, 0, 0, 0, 0], np.float32)  # V = 3: left
    code, _ = rl.observation_code(record["config"])
    np.testing.assert_allclose(code(phi), NetworkInputs(scaled=True, bearing=True)(phi), rtol=1e-6)
    expected, _ = model.predict(code(phi), deterministic=True)
    assert rl.model_policy(model, record, sampled=False, seed=0, shares=True)(phi) == int(expected)
    with pytest.raises(ValueError, match="settings.inputs: accepted for dqn: exploration_fraction, valid"):
        rl.tuned("dqn", {"inputs": "bearing"})


def test_dqn_explores_over_the_same_decisions_at_half_the_budget_and_twice_the_fraction():
    from nirl_mj.experiments import rl

    def epsilons(steps: int, changes: dict) -> np.ndarray:
        settings = rl._model_settings(rl.run_config("dqn", "validation_success", 1, changes))
        model = sb3.DQN("MlpPolicy", "CartPole-v1", device="cpu", **settings)
        # Stable-Baselines3 reads the schedule at progress_remaining = 1 - decisions done / budget
        return np.array([model.exploration_schedule(1.0 - t / steps) for t in range(0, 50_001, 250)])

    default, half = epsilons(100_000, {}), epsilons(50_000, {"exploration_fraction": 0.4})
    assert default[0] == 1.0 and default[-1] == half[-1] == 0.05
    np.testing.assert_allclose(half, default, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match=r"exploration_fraction = 1.5: expected a float in \(0.0, 1.0\]"):
        rl.tuned("dqn", {"exploration_fraction": 1.5})
    # the selection's arenas are the run's, never DQN's own setting
    config = rl.run_config("dqn", "validation_success", 1, {"validation_arenas": 50})
    assert config["validation_arenas"] == 50 and "validation_arenas" not in rl._model_settings(config)


def test_checkpoint_every_scores_fewer_checkpoints_of_the_same_training(tmp_path, monkeypatch):
    """Checkpoints never change the training: every other checkpoint gives the same scores there
    and the same final model; the setting is the run's (recorded; the default written out is not)."""
    from helpers import OPEN

    from nirl_mj.experiments import rl
    from nirl_mj.sim import spec

    monkeypatch.setattr(rl, "VALIDATION_CUT", False)  # every checkpoint scored in full
    near = spec.replace(OPEN, arena={"target": (9.0, 9.0)}, control={"step_budget": 30})  # some arrive
    changes = {"validation_arenas": 6}  # sampled actions: validation draws them (its own stream)
    kw = {"seed": 3, "envs": 2, "selection": "validation_success"}
    every = rl.train_rl(tmp_path / "every", near, "ppo", 1024, checkpoint_every=256, changes=changes, **kw)
    fewer_changes = {**changes, "checkpoint_every": 512}
    fewer = rl.train_rl(tmp_path / "fewer", near, "ppo", 1024, changes=fewer_changes, **kw)
    assert fewer["config"]["checkpoint_every"] == 512 and "checkpoint_every" not in every["config"]
    scores = [(s["steps"], s["score"]) for s in every["scores"]]
    assert len({score for _, score in scores}) > 1  # scores that can tell checkpoints apart
    assert [(s["steps"], s["score"]) for s in fewer["scores"]] == [scores[1], scores[3]]
    model = rl._algorithm("ppo").load(tmp_path / "every" / rl.MODEL_FILE, device="cpu")
    assert rl._same_as_saved(rl.RunDir(tmp_path / "fewer"), model, None)
    assert rl.run_config("ppo", "last", 2, {"checkpoint_every": rl.CHECKPOINT_EVERY}) == rl.run_config(
        "ppo", "last", 2
    )
    with pytest.raises(ValueError, match="envs = 3: must be >= 1 and divide the 512 decisions"):
        rl.run_config("dqn", "last", 3, {"checkpoint_every": 512})
    with pytest.raises(ValueError, match="checkpoint_every is given twice"):
        rl.train_rl(tmp_path / "twice", OPEN, "ppo", 512, checkpoint_every=256,
                    changes={"checkpoint_every": 512}, **kw)  # fmt: skip


@pytest.mark.parametrize("algo", ["gail", "airl-absorbing"])
def test_gail_and_airl_may_see_phi_as_nirls_bearing_code_policy_and_discriminator_alike(tmp_path, algo):
    from helpers import OPEN

    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.data.rundir import DISCRIMINATOR_FILE, RunError
    from nirl_mj.experiments import rl
    from nirl_mj.experiments.adversarial import load_discriminator
    from nirl_mj.experiments.subjects import run_subject

    demos = _rule_demos(tmp_path)
    run = tmp_path / "run"
    record = rl.train_rl(run, OPEN, algo, 1024, seed=2, demos=demos, checkpoint_every=512, envs=2,
                         changes={"inputs": "bearing"})  # fmt: skip
    model = sb3.PPO.load(run / "model.zip", device="cpu")
    assert model.observation_space.shape == (17,) and record["config"]["inputs"] == "bearing"
    kind, absorbing = algo.split("-")[0], algo.endswith("absorbing")
    disc = load_discriminator(run, kind, 0.99)  # the code and the absorbing state its record names
    assert disc.inputs.width == 17 + absorbing and disc.inputs.absorbing == absorbing
    bare = tmp_path / "bare"  # a discriminator file without its run: told its width
    bare.mkdir()
    shutil.copy(run / DISCRIMINATOR_FILE, bare)
    assert load_discriminator(bare, kind, 0.99, n_inputs=17).inputs.absorbing == absorbing
    other_kind = "gail" if kind == "airl" else "airl"
    for wrong in ({"kind": other_kind}, {"n_inputs": 16}):  # the run's record decides; a mismatch is refused
        with pytest.raises(RunError, match=f"is a {algo} run on 17 inputs"):
            load_discriminator(run, **{"kind": kind, "gamma": 0.99, **wrong})
    other = tmp_path / "other"  # a record that names another code is refused, not misread
    shutil.copytree(run, other)
    saved = json.loads((other / "run.json").read_text())
    del saved["config"]["inputs"]
    (other / "run.json").write_text(json.dumps(saved))
    with pytest.raises(RunError, match=f"reads {17 + absorbing} inputs, not 16.* as its run records"):
        load_discriminator(other, kind, 0.99)
    # the selection scored the policy on the demonstrations as the policy sees them
    code, _ = rl.observation_code(record["config"])
    assert rl._demo_scorer(model, load_dataset(demos), code)() == record["scores"][-1]["score"]
    if kind == "airl":  # the subject's reward map reads phi(s) through the run's code
        rewards = run_subject(run).reward().rewards_all_actions(np.zeros((3, 16)))
        assert rewards.shape == (3, 6) and np.isfinite(rewards).all()


def test_validation_stops_a_checkpoint_that_cannot_reach_the_best_and_selects_the_same(tmp_path, monkeypatch):
    """Scripted validation outcomes (4 arenas, 4 checkpoints): a checkpoint stops once its successes
    plus the arenas left fall below the best so far, records no score but the most it could have
    scored and the arenas it drove, and the run keeps the same checkpoint as one that drives every
    arena."""
    from types import SimpleNamespace

    from helpers import OPEN

    from nirl_mj.experiments import rl
    from nirl_mj.experiments.seeds import domain_seed
    from nirl_mj.sim import episode

    monkeypatch.setattr(rl, "VALIDATION_ARENAS", 4)
    script = ["TTCC", "CCTT", "CCCC", "TTTC"]  # T arrives, C collides; per checkpoint, per arena
    arenas = [domain_seed("validation", 0, k) for k in range(4)]  # the run's validation arenas (seed 0)
    model_policy = rl.model_policy

    def run(cut: bool) -> tuple[dict, list[tuple[int, int]]]:
        driven, checkpoint = [], [-1]

        def counting_policy(*args, **kwargs):
            checkpoint[0] += 1
            return model_policy(*args, **kwargs)

        def scripted_episode(env, agent, arena):
            k = arenas.index(arena)
            driven.append((checkpoint[0], k))
            return SimpleNamespace(outcome="target" if script[checkpoint[0]][k] == "T" else "collision")

        monkeypatch.setattr(rl, "VALIDATION_CUT", cut)
        monkeypatch.setattr(rl, "model_policy", counting_policy)
        monkeypatch.setattr(episode, "run_episode", scripted_episode)
        record = rl.train_rl(tmp_path / str(cut), OPEN, "dqn", 128, seed=0, checkpoint_every=32,
                             selection="validation_success")  # fmt: skip
        return record, driven

    full, every = run(cut=False)
    cut, some = run(cut=True)
    assert [s["score"] for s in full["scores"]] == [0.5, 0.5, 0.0, 0.75] and len(every) == 16
    # checkpoint 2 stops after its third collision: 0 + 1 arena left < the 2 successes of the best
    assert [s["score"] for s in cut["scores"]] == [0.5, 0.5, None, 0.75] and len(some) == 15
    assert (cut["scores"][2]["at_most"], cut["scores"][2]["driven"]) == (0.25, 3)
    assert all("driven" not in s and "at_most" not in s for s in full["scores"])
    assert cut["selected"] == full["selected"] and cut["selected"]["steps"] == 128


def test_act_greedy_drives_validation_and_tests_by_the_mode_and_trains_as_sampled(tmp_path, monkeypatch):
    import torch
    from helpers import OPEN

    from nirl_mj.experiments import rl
    from nirl_mj.experiments.evaluation import evaluate
    from nirl_mj.sim.observations import feature_bounds
    from nirl_mj.sim.task import make_env

    monkeypatch.setattr(rl, "VALIDATION_ARENAS", 3)
    monkeypatch.setattr(rl, "VALIDATION_CUT", False)  # every checkpoint scored in full, to compare below
    runs = {act: tmp_path / act for act in ("sampled", "greedy")}
    records = {act: rl.train_rl(run, OPEN, "ppo", 1024, seed=3, checkpoint_every=512, envs=2,
                                selection="validation_success", changes={"act": act})  # fmt: skip
               for act, run in runs.items()}  # fmt: skip
    assert records["greedy"]["config"]["act"] == "greedy"
    assert "act" not in rl._model_settings(records["greedy"]["config"])  # not a setting of PPO's
    models = {act: sb3.PPO.load(run / "model.zip", device="cpu") for act, run in runs.items()}
    # the same training: act changes how validation and tests drive, nothing else
    for a, b in zip(models["sampled"].policy.parameters(), models["greedy"].policy.parameters(), strict=True):
        assert torch.equal(a, b)
    # validation drove the greedy run's checkpoint by its mode, as its tests (eval) do
    env = make_env(OPEN)
    greedy = rl.model_policy(models["greedy"], records["greedy"], sampled=False, seed=3, shares=True)
    scored = evaluate(env, greedy, records["greedy"]["validation_seeds"])[0]["success_rate"]
    assert scored == records["greedy"]["scores"][-1]["score"]
    loaded, _ = rl.load_rl_policy(runs["greedy"], policy="last", shares=True)
    rng = np.random.default_rng(0)
    for phi in rng.uniform(0, 1, (20, 16)) * feature_bounds()[1]:
        mode, _ = models["greedy"].predict(rl.scaled(phi), deterministic=True)
        assert loaded(phi) == int(mode)
    # a run that does not set act is driven sampled, as runs recorded before the setting existed
    assert "act" not in rl.run_config("ppo", "validation_success", 2)
    sampled, _ = rl.load_rl_policy(runs["sampled"], policy="last", seed=5, shares=True)
    again = rl.model_policy(models["sampled"], {**records["sampled"], "config": {}}, None, 5, True)
    draws = [(sampled(phi), again(phi)) for phi in rng.uniform(0, 1, (50, 16)) * feature_bounds()[1]]
    assert all(a == b for a, b in draws) and len({a for a, _ in draws}) > 1  # drawn, not the mode
    with pytest.raises(ValueError, match="settings.act = 'mode': accepted: sampled, greedy"):
        rl.tuned("ppo", {"act": "mode"})


def test_train_drive_drives_the_training_episodes_only_and_a_resume_keeps_it(tmp_path, monkeypatch):
    from helpers import OPEN

    from nirl_mj.experiments import rl
    from nirl_mj.sim import spec

    task = spec.replace(OPEN, robot={"drive": "tyre"})
    drives, scored = [], []
    environment, scorer = rl._environment, rl._validation_scorer

    def spy_environment(task, *args, **kwargs):
        drives.append(task.robot.drive)
        return environment(task, *args, **kwargs)

    def spy_scorer(model, record, task, seed):
        scored.append(task.robot.drive)
        return scorer(model, record, task, seed)

    monkeypatch.setattr(rl, "_environment", spy_environment)
    monkeypatch.setattr(rl, "_validation_scorer", spy_scorer)
    monkeypatch.setattr(rl, "VALIDATION_ARENAS", 2)  # a short test
    run = tmp_path / "run"
    record = rl.train_rl(run, task, "dqn", 64, seed=0, checkpoint_every=64, selection="validation_success",
                         train_drive="planar")  # fmt: skip
    assert record["config"]["train_drive"] == "planar" and record["task"]["robot"]["drive"] == "tyre"
    assert drives == ["planar"] and scored == ["tyre"]  # validation drives the tests' wheels
    record = rl.train_rl(run, task, "dqn", 128, seed=0, checkpoint_every=64, resume=True)  # none given
    assert record["steps_done"] == 128 and drives == ["planar", "planar"]
    with pytest.raises(rl.RunError, match="was trained with another config"):
        rl.train_rl(run, task, "dqn", 192, seed=0, resume=True, train_drive="tyre")
    # a run given none records none: its config is the one recorded before the key existed
    assert "train_drive" not in rl.run_config("dqn", "validation_success", 1)
    with pytest.raises(ValueError, match="train_drive 'flat': accepted: tyre, rollers, planar"):
        rl.run_config("dqn", "validation_success", 1, train_drive="flat")


def test_an_experiment_row_may_train_on_another_drive_and_an_unset_one_keeps_its_identity():
    data = {"kind": "compare", "methods": ["D"],
            "method": {"D": {"kind": "rl", "algo": "dqn", "selection": "validation_success",
                             "train_drive": "planar"}}}  # fmt: skip
    (method,) = from_dict(data).methods
    assert method.train_drive == "planar"
    assert from_dict(data).identity()["methods"][0]["train_drive"] == "planar"
    assert (
        "train_drive"
        not in from_dict({"kind": "compare", "methods": ["DQN-reward"]}).identity()["methods"][0]
    )
    data["method"]["D"]["train_drive"] = "hover"
    with pytest.raises(
        ExperimentError, match=r"method\.D\.train_drive = 'hover': accepted: tyre, rollers, planar"
    ):
        from_dict(data)
    with pytest.raises(ExperimentError, match='apply to kind = "rl" only'):
        from_dict(
            {"kind": "compare", "methods": ["B"], "method": {"B": {"kind": "bc", "train_drive": "planar"}}}
        )


def test_the_train_drive_of_a_row_and_of_the_command_line_reaches_training(tmp_path, monkeypatch):
    from types import SimpleNamespace

    from nirl_mj.experiments import kinds, rl

    given = []
    monkeypatch.setattr(rl, "ensure_rl_trained", lambda *args: given.append(args[-1]))
    monkeypatch.setattr(rl, "load_rl_policy", lambda *args, **kwargs: (None, {}))
    data = {"kind": "compare", "methods": ["D"],
            "method": {"D": {"kind": "rl", "algo": "dqn", "selection": "validation_success",
                             "train_drive": "planar"}}}  # fmt: skip
    (method,) = from_dict(data).methods
    kinds.KINDS["rl"](SimpleNamespace(method=method, run_dir="r", task=None, seed=0, demos_path=""), True)
    assert given == ["planar"]

    monkeypatch.setattr(rl, "train_rl", lambda *args, **kwargs: given.append(kwargs["train_drive"]) or
                        {"train_seeds": [], "steps_done": 1})  # fmt: skip
    base = ["rl", "--algo", "dqn", "--steps", "1", "--quiet", *SMALL]
    assert main([*base, "--out", str(tmp_path / "a"), "--train-drive", "rollers"]) == 0
    assert main([*base, "--out", str(tmp_path / "b")]) == 0
    assert given == ["planar", "rollers", None]  # None: the task's drive, or a resume's own
