"""One information budget: what each method reads, recorded, and checked against what its code touches.

A learner from demonstrations reads the demonstrations, phi(s) and that its own episodes ended
(``nirl_mj/experiments/reads.py``). The learned value of an episode's end (``learn/terminal.py``)
replaces the arrival value that read the task's outcome; the selection rules that read no task
signal replace success on validation arenas.
"""

import dataclasses

import numpy as np
import pytest
from helpers import random_trajectory

from nirl_mj.data.trajectory import Trajectory
from nirl_mj.experiments import compare, sweep
from nirl_mj.experiments.definition import BUILTIN_METHODS, from_dict, load_experiment
from nirl_mj.experiments.reads import (
    LEARNER_BUDGET,
    TASK_SIGNALS,
    VOCABULARY,
    check_words,
    is_reference,
    learner_reads,
    method_reads,
)
from nirl_mj.learn.config import LearnerConfig
from nirl_mj.learn.loop import IrlLoop
from nirl_mj.learn.reward import state_reward_features
from nirl_mj.learn.terminal import absorbing_values

REFERENCES = ("DAgger", "PPO-reward", "DQN-reward", "rule", "forward", "expert")
"""The built-in methods that read more than a learner from demonstrations may; every other is one."""
LEARNERS_FROM_DEMONSTRATIONS = tuple(name for name in BUILTIN_METHODS if name not in REFERENCES)


# -- the vocabulary and every built-in method's entry --------------------------------------------


def test_every_builtin_method_reads_words_of_the_vocabulary():
    for name, method in BUILTIN_METHODS.items():
        reads = method_reads(method)
        check_words(reads, name)
        assert reads == [w for w in VOCABULARY if w in reads], f"{name}: not in the vocabulary's order"


@pytest.mark.parametrize("name", LEARNERS_FROM_DEMONSTRATIONS)
def test_learners_from_demonstrations_read_no_task_signal(name):
    reads = method_reads(BUILTIN_METHODS[name])
    assert set(reads) <= set(LEARNER_BUDGET) and "demonstrations" in reads
    assert not is_reference(reads)


def test_references_say_what_more_they_read():
    assert all(is_reference(method_reads(BUILTIN_METHODS[n])) for n in REFERENCES if n in BUILTIN_METHODS)
    assert method_reads(BUILTIN_METHODS["DAgger"]) == ["demonstrations", "features", "interactive_expert"]
    assert {"task_reward", "task_outcome"} <= set(method_reads(BUILTIN_METHODS["PPO-reward"]))
    assert method_reads(BUILTIN_METHODS["rule"]) == ["features", "hand_written"]
    assert method_reads(BUILTIN_METHODS["forward"]) == ["hand_written"]
    assert all(is_reference(method_reads(BUILTIN_METHODS[n])) for n in ("DAgger", "PPO-reward", "rule"))
    # DQN-reward chooses its checkpoint by success on validation arenas: it reads the task's success too
    assert method_reads(BUILTIN_METHODS["DQN-reward"]) == method_reads(BUILTIN_METHODS["PPO-reward"])
    assert "task_success_selection" in method_reads(BUILTIN_METHODS["DQN-reward"])


def test_an_oracle_setting_is_named_in_reads():
    oracle = LearnerConfig.preset("default", selection="validation", terminal_value="outcome")
    assert learner_reads(oracle) == ["demonstrations", "features", "episode_end", "task_outcome",
                                     "task_success_selection"]  # fmt: skip
    assert "task_reward" in learner_reads(LearnerConfig.preset("default", reward_source="progress"))
    # the paper's targets: "outcome" with an arrival worth 0 reads nothing of the outcome
    assert learner_reads(LearnerConfig.preset("paper")) == list(LEARNER_BUDGET)


def test_unknown_words_are_refused():
    with pytest.raises(ValueError, match="unknown reads word"):
        check_words(["features", "success"], "x")
    assert set(TASK_SIGNALS) <= set(VOCABULARY)


def test_the_compare_summary_and_table_carry_reads():
    e = from_dict({"kind": "compare", "methods": ["NIRL", "BC", "DAgger", "forward"], "runs": 1})
    summary = compare.summarise(e, {})
    assert summary["methods"]["NIRL"]["reads"] == ["demonstrations", "features", "episode_end"]
    table = compare.markdown_table(summary)
    assert "| demonstrations, features, episode_end |" in table
    assert "**reference:** demonstrations, features, interactive_expert" in table


def test_the_figure_sweep_labels_its_pinned_nirl_a_reference():
    """tasks/fig6.toml keeps NIRL's settings of its time (selection on validation arenas, an arrival
    worth 1): its sweep's summary and table say that this NIRL reads the task's outcome and success."""
    e = load_experiment("fig6", kind="sweep")
    summary = sweep.summarise(e, {})
    pinned = ["demonstrations", "features", "episode_end", "task_outcome", "task_success_selection"]
    assert summary["reads"] == {"NIRL": pinned, "forward": ["hand_written"]}
    table = sweep.markdown_table(summary, e)
    assert table.splitlines()[0].endswith("| 50 obstacles | reads |")
    assert table.count(f"| **reference:** {', '.join(pinned)} |") == len(e.speeds)


# -- the learner touches what its reads say --------------------------------------------------------


SWAP = {"target": "collision", "collision": "target", "physics_error": "target", "timeout": "timeout"}


def _scramble(t: Trajectory, rng: np.random.Generator) -> Trajectory:
    """The same phi(s), actions and episode end, but the outcome swapped (an arrival reads as a
    collision and the other way round), and the poses and the target redrawn: all that the task's
    reward (progress towards the target, +-1 at the end) is computed from."""
    task = {**t.task, "arena": {"target": list(rng.uniform(0, 100, 2))}}
    poses = rng.uniform(0, 100, t.poses.shape)
    return dataclasses.replace(t, outcome=SWAP[t.outcome], poses=poses, task=task)


def _run_loop(config: LearnerConfig, scrambled: bool) -> dict:
    """Two iterations of the loop on fixed fake rollouts; ``scrambled`` scrambles the task's
    outcome and reward of every rollout (:func:`_scramble`)."""
    rng = np.random.default_rng(0)
    demos = [random_trajectory(rng, 12, "target") for _ in range(3)]
    outcomes = ["target", "collision", "timeout", "collision"]

    def rollouts(agent, seeds):
        batch = np.random.default_rng(seeds[0])
        trajectories = [random_trajectory(batch, 8, outcomes[i % 4]) for i in range(len(seeds))]
        if scrambled:
            trajectories = [_scramble(t, batch) for t in trajectories]
        return trajectories

    loop = IrlLoop(config, demos, seed=3)
    for i in range(2):
        loop.step(rollouts, [100 * i + k for k in range(4)])
    return loop.state()


@pytest.mark.parametrize("method", ["nirl", "al", "re", "scirl"])
def test_a_learner_from_demonstrations_is_blind_to_the_task_outcome(method):
    """The default learner (any reward step) ends in the same state, bit for bit, when every
    rollout's outcome and reward are scrambled; the outcome reading and the progress control (which
    read them) do not: the test can fail."""
    config = LearnerConfig.preset("default", method=method, trajectories_per_episode=4, replay_episodes=2)
    assert "task_outcome" not in learner_reads(config)
    same, scrambled = _run_loop(config, False), _run_loop(config, True)
    for key in same:
        np.testing.assert_array_equal(same[key], scrambled[key], err_msg=key)
    oracle = config.replace(terminal_value="outcome")
    assert "task_outcome" in learner_reads(oracle)
    a, b = _run_loop(oracle, False), _run_loop(oracle, True)
    assert not np.array_equal(a["net_W2"], b["net_W2"])
    progress = config.replace(reward_source="progress")
    assert "task_reward" in learner_reads(progress)
    a, b = _run_loop(progress, False), _run_loop(progress, True)
    assert not np.array_equal(a["net_W2"], b["net_W2"])


LOOP_LEARNERS = [
    name for name, m in BUILTIN_METHODS.items() if m.kind == "irl" and not is_reference(method_reads(m))
]


@pytest.mark.parametrize("name", LOOP_LEARNERS)
def test_every_built_in_loop_learner_is_blind_to_the_task_outcome(name):
    """As above, for each built-in row of the loop as its experiment builds it (the paper preset, the
    trajectory readings, the classifier margin, the last iterate): what ``reads`` says, the code does."""
    config = BUILTIN_METHODS[name].learner_config({"trajectories_per_episode": 4, "replay_episodes": 2})
    same, scrambled = _run_loop(config, False), _run_loop(config, True)
    for key in same:
        np.testing.assert_array_equal(same[key], scrambled[key], err_msg=f"{name}: {key}")


def test_behaviour_cloning_is_blind_to_the_demonstrations_outcomes(monkeypatch):
    """BC reads the demonstrations' phi(s) and actions only: with every demonstration's outcome swapped
    (:func:`_scramble`; half arrivals, half collisions, so that keeping only arrivals would differ) it
    trains the same network, bit for bit, and so acts alike."""
    from nirl_mj.learn import bc, network

    rng = np.random.default_rng(2)
    demos = [random_trajectory(rng, 12, outcome) for outcome in ["target", "collision"] * 3]
    scrambled = [_scramble(t, rng) for t in demos]
    assert [t.outcome for t in scrambled] == ["collision", "target"] * 3
    nets = []
    greedy_policy = bc.greedy_policy

    def kept(net, inputs):
        nets.append(net)
        return greedy_policy(net, inputs)

    monkeypatch.setattr(bc, "greedy_policy", kept)
    policies = [bc.behaviour_cloning(d, seed=4) for d in (demos, scrambled)]
    (w1, w2), (s1, s2) = (tuple(network.get_weights(net).values()) for net in nets)
    np.testing.assert_array_equal(w1, s1)
    np.testing.assert_array_equal(w2, s2)
    phi = random_trajectory(rng, 199, "timeout").features  # 200 states
    assert [policies[0](p) for p in phi] == [policies[1](p) for p in phi]


def test_a_trained_run_is_blind_to_its_episodes_outcomes_end_to_end(tmp_path, monkeypatch):
    """Through ``training.train`` (rollouts, selection, checkpoints, as a Table I cell trains): the
    default NIRL keeps the same iteration and weights when every episode's outcome is swapped (target
    and collision); the outcome reading of an episode's end does not (the test can fail)."""
    from helpers import OPEN

    from nirl_mj.data import trajectory
    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.data.rundir import RunDir
    from nirl_mj.experiments.demos import ExpertConfig, collect
    from nirl_mj.experiments.training import train
    from nirl_mj.sim import spec as specs

    task = specs.replace(OPEN, arena={"static_obstacles": 8}, control={"step_budget": 40})
    demos = tmp_path / "demos.npz"
    save_dataset(demos, collect(task, ExpertConfig("rule"), episodes=2, seed=0))
    finish = trajectory.TrajectoryRecorder.finish
    ends = []

    def swapped(self, outcome, *args, **kwargs):
        ends.append(trajectory._outcome_name(outcome))
        return finish(self, SWAP[ends[-1]], *args, **kwargs)

    records = []

    def trained(config: LearnerConfig, scrambled: bool) -> tuple[int, dict]:
        out = tmp_path / f"run{len(list(tmp_path.glob('run*')))}"
        with monkeypatch.context() as patch:
            if scrambled:
                patch.setattr(trajectory.TrajectoryRecorder, "finish", swapped)
            record = train(out, task, demos, config, seed=0)
        records.append(record)
        with np.load(RunDir(out).file("policy.npz")) as policy:
            return record["selected_iteration"], {k: policy[k] for k in policy.files}

    config = LearnerConfig.preset("default", episodes=3, trajectories_per_episode=3, validation_arenas=2,
                                  replay_episodes=2)  # fmt: skip
    assert "task_outcome" not in learner_reads(config)
    (kept, same), (kept_scrambled, scrambled) = trained(config, False), trained(config, True)
    assert {"target", "collision"} & set(ends), ends  # the swap changed what the episodes said
    assert kept == kept_scrambled
    for key in same:
        np.testing.assert_array_equal(same[key], scrambled[key], err_msg=key)
    # the end check drives its candidates on validation arenas and reads only that they ended
    checked = config.replace(end_check_arenas=3)
    (kept, same), (kept_scrambled, scrambled) = trained(checked, False), trained(checked, True)
    check = records[-1]["selection"]
    assert check["end_check_arenas"] == 3 and records[-2]["selection"] == check
    # here the check overrules the rule (a candidate whose episodes all end against ones that time
    # out), so a check that read which end would choose differently once the ends are swapped
    assert check["iteration"] != check["first_round_best"], check
    assert kept == kept_scrambled
    for key in same:
        np.testing.assert_array_equal(same[key], scrambled[key], err_msg=f"end check: {key}")
    oracle = config.replace(terminal_value="outcome")
    _, a = trained(oracle, False)
    _, b = trained(oracle, True)
    assert any(not np.array_equal(a[k], b[k]) for k in a)


# -- the learned value of an episode's end (learn/terminal.py) --------------------------------------


def _phi(danger: float = 0, sector: int = 1, detected: int = 0) -> np.ndarray:
    phi = np.zeros(16)
    phi[:7], phi[7], phi[8] = danger, sector, detected
    return phi


def test_absorbing_values_by_hand():
    """Expert ends: target detected, no danger. Learner ends: one like the expert's, two collisions
    (danger 7 on every sensor). With the "extended" block b = [D/7 (7), V one-hot (9), I, U (7), 1]:
    mu_E = [0]*7 + e_V1 + I=1 + 0 + 1; mu_pi = (1 x expert end + 2 x collision) / 3, so
    w = mu_E - mu_pi has D components -2/3, I component 2/3, the rest 0. Scores w . b: the
    learner's expert-like end 2/3, each collision 7 x (-2/3) = -14/3; the expert's mean 2/3.
    Values (s - min) / (top - min): 1, 0, 0."""
    expert = np.array([_phi(detected=1), _phi(detected=1)])
    learner = np.array([_phi(detected=1), _phi(danger=7), _phi(danger=7)])
    w = state_reward_features(expert, "extended").mean(0) - state_reward_features(learner, "extended").mean(0)
    np.testing.assert_allclose(w[:7], -2 / 3)
    assert w[16] == pytest.approx(2 / 3)
    np.testing.assert_allclose(absorbing_values(expert, learner, "extended"), [1.0, 0.0, 0.0])
    # a collision that also sees the target lies between. Now mu_pi's I is 2/3, so w's I component is
    # 1/3 (D still -2/3): scores 1/3, -14/3 and -14/3 + 1/3, the expert's mean 1/3; the third end is
    # worth (-13/3 + 14/3) / (1/3 + 14/3) = 1/15
    learner = np.array([_phi(detected=1), _phi(danger=7), _phi(danger=7, detected=1)])
    values = absorbing_values(expert, learner, "extended")
    w = state_reward_features(expert, "extended").mean(0) - state_reward_features(learner, "extended").mean(0)
    scores = state_reward_features(learner, "extended") @ w
    top = state_reward_features(expert, "extended").mean(0) @ w
    np.testing.assert_allclose(values, np.clip((scores - scores.min()) / (top - scores.min()), 0, 1))
    np.testing.assert_allclose(values, [1.0, 0.0, 1 / 15])


def test_absorbing_values_edge_cases():
    """The scale is relative to the batch of the learner's ends (learn/terminal.py says so): its
    worst end is worth 0 whatever it is, so a lone end is worth 0 and, among arrivals only, the
    least expert-like arrival is worth 0 too."""
    expert = np.array([_phi(detected=1)])
    assert absorbing_values(expert, np.zeros((0, 16)), "bearing").shape == (0,)
    np.testing.assert_array_equal(absorbing_values(np.zeros((0, 16)), expert, "bearing"), [0.0])
    lone = np.array([_phi(danger=1, detected=1)])
    np.testing.assert_array_equal(absorbing_values(expert, lone, "bearing"), [0.0])
    # w's danger components: 0 - (1 + 2) / 2 / 7 = -1.5/7 each; scores 7 (d/7)(-1.5/7) = -1.5/7 and
    # -3/7, the expert's 0: values (s + 3/7) / (3/7) = 0.5 and 0
    arrivals = np.array([_phi(danger=1, detected=1), _phi(danger=2, detected=1)])
    np.testing.assert_allclose(absorbing_values(expert, arrivals, "bearing"), [0.5, 0.0])
    collisions = np.array([_phi(danger=7), _phi(danger=6)])
    assert absorbing_values(expert, collisions, "bearing")[0] == 0.0
    # every learner end where the expert's ends: nothing to tell apart, each worth an expert's end
    np.testing.assert_array_equal(
        absorbing_values(expert, np.array([_phi(detected=1)] * 2), "bearing"), [1, 1]
    )


def test_a_learner_end_more_expert_like_than_the_experts_mean_is_worth_1_not_more():
    """Expert ends: target detected, without and with danger 1; learner ends: target detected, and a
    collision (danger 7). "extended" blocks b = [D/7 (7), V one-hot (9), I, U (7), 1]: w = mu_E - mu_pi
    has D components 1/14 - 1/2 = -3/7, I component 1 - 1/2 = 1/2, the rest 0. Scores: the learner's
    arrival 1/2, its collision 7 x (-3/7) = -3; the expert's mean 7 x (1/14)(-3/7) + 1/2 = 2/7. The
    arrival's (1/2 + 3) / (2/7 + 3) = 49/46 is clipped to 1: no end is worth more than the expert's."""
    expert = np.array([_phi(detected=1), _phi(danger=1, detected=1)])
    learner = np.array([_phi(detected=1), _phi(danger=7)])
    np.testing.assert_allclose(absorbing_values(expert, learner, "extended"), [1.0, 0.0])


# -- selection without a task signal ---------------------------------------------------------------


def test_selection_rules_read_no_validation():
    rng = np.random.default_rng(1)
    demos = [random_trajectory(rng, 10, "target") for _ in range(2)]
    for rule in ("demo_balanced", "last", "demo_accuracy"):
        config = LearnerConfig.preset("default", selection=rule, trajectories_per_episode=2)
        loop = IrlLoop(config, demos, seed=0)
        assert loop._score(0.9, 0.3, None) == {"demo_balanced": 0.3, "last": 0.0, "demo_accuracy": 0.9}[rule]
        loop.iteration = 4
        assert loop._score(0.9, 0.3, 0.7) == {"demo_balanced": 0.3, "last": 4.0, "demo_accuracy": 0.9}[rule]
    oracle = IrlLoop(LearnerConfig.preset("default", selection="validation"), demos, seed=0)
    assert oracle._score(0.9, 0.3, 0.7) == 0.7 and oracle._score(0.9, 0.3, None) == -1.0


def test_the_readme_table_of_what_each_method_reads_is_the_code_s():
    import re
    from pathlib import Path

    from nirl_mj.experiments.definition import load_experiment

    lines = (Path(__file__).resolve().parents[1] / "README.md").read_text().splitlines()
    start = lines.index("| method | reads | |")
    table = []
    for line in lines[start + 2 :]:
        if not line.startswith("|"):
            break
        table.append(line)
    listed = set()
    for line in table:
        names, words = line.split(" | ")[:2]
        for name in re.findall(r"`([^`]+)`", names):
            assert method_reads(BUILTIN_METHODS[name]) == words.split(", "), name
            listed.add(name)
    assert {m.name for m in load_experiment("table1").methods} <= listed


# -- GAIL and AIRL: the task's reward and outcome never reach their training --------------------------


def _adversarial_run(tmp_path, algo: str, demos, scrambled: bool, monkeypatch, row: str = "") -> dict:
    """Two PPO rollouts (2 x 1,024 decisions, a checkpoint after each) of ``algo`` on OPEN (or of
    built-in method ``row``: its algorithm, selection, environments and settings); with
    ``scrambled`` every step of the environment hands out a random reward and the opposite outcome
    (``info``). The last policy's and the discriminator's weights, the checkpoint the run's selection
    kept (its score and decisions) and that checkpoint's weights: what its tests drive."""
    from helpers import OPEN
    from stable_baselines3 import PPO

    from nirl_mj.experiments.rl import train_rl
    from nirl_mj.gym.env import NavigationEnv

    step = NavigationEnv.step
    rng = np.random.default_rng(5)

    def scramble(self, action):
        obs, reward, terminated, truncated, info = step(self, action)
        outcome = SWAP.get(info["outcome"], "collision")  # a running episode reads as one that ended
        swapped = {**info, "is_success": not info["is_success"], "outcome": outcome}
        return obs, float(rng.normal(0.0, 10.0)), terminated, truncated, swapped

    with monkeypatch.context() as patch:
        if scrambled:
            patch.setattr(NavigationEnv, "step", scramble)
        out = tmp_path / f"{row or algo}-{scrambled}"
        kwargs = {}
        if row:  # the row's algorithm (algo names it too), selection, environments and settings
            method = BUILTIN_METHODS[row]
            kwargs = {"selection": method.selection, "envs": method.envs, "changes": method.settings}
        demos = demos if algo != "ppo" else None
        record = train_rl(out, OPEN, algo, 2048, seed=0, demos=demos, checkpoint_every=1024, **kwargs)

    def policy(path):
        return {k: v.numpy() for k, v in PPO.load(path, device="cpu").policy.state_dict().items()}

    weights = policy(out / "model.zip")
    selected = record.get("selected")
    if selected:
        weights["selected"] = np.array([selected["steps"], selected["score"]])
        weights.update({f"selected_{k}": v for k, v in policy(out / selected["file"]).items()})
    if (out / "discriminator.npz").is_file():
        with np.load(out / "discriminator.npz") as saved:
            weights.update({f"disc_{k}": saved[k] for k in saved.files})
    return weights


def test_gail_and_airl_are_blind_to_the_task_reward_and_outcome(tmp_path, monkeypatch):
    """GAIL and AIRL, as Table I's rows run them (GAIL, GAIL-linear-last, AIRL: their selection,
    environments and settings) and with the absorbing state (which reads episode ends), end in the
    same policy and discriminator, bit for bit, when every step's reward and outcome are scrambled;
    PPO on the reward does not (the test can fail)."""
    pytest.importorskip("stable_baselines3")
    from helpers import OPEN

    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.experiments.demos import ExpertConfig, collect

    demos = tmp_path / "demos.npz"
    save_dataset(demos, collect(OPEN, ExpertConfig("rule"), episodes=2, seed=0))
    rows = [("gail", "GAIL"), ("gail", "GAIL-linear-last"), ("airl", "AIRL"), ("airl-absorbing", "")]
    for algo, row in rows:
        assert not row or BUILTIN_METHODS[row].algo == algo, row
        same = _adversarial_run(tmp_path, algo, demos, False, monkeypatch, row)
        scrambled = _adversarial_run(tmp_path, algo, demos, True, monkeypatch, row)
        assert any(k.startswith("disc_") for k in same), row or algo
        assert ("selected" in same) == (row != "GAIL-linear-last"), row or algo  # its last: none chosen
        for key in same:
            np.testing.assert_array_equal(same[key], scrambled[key], err_msg=f"{row or algo}: {key}")
    ppo = _adversarial_run(tmp_path, "ppo", None, False, monkeypatch)
    ppo_scrambled = _adversarial_run(tmp_path, "ppo", None, True, monkeypatch)
    assert any(not np.array_equal(ppo[k], ppo_scrambled[k]) for k in ppo)
