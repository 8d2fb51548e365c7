"""DAgger: the expert labels the states the learner's policy visits; the data set grows; it learns."""

from types import SimpleNamespace

import numpy as np
import pytest
from helpers import OPEN

from nirl_mj.data.dataset import save_dataset
from nirl_mj.data.trajectory import stack_pairs
from nirl_mj.experiments.dagger import DaggerConfig, LabellingAgent, train_dagger
from nirl_mj.experiments.definition import from_dict
from nirl_mj.experiments.demos import ExpertConfig, collect
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.kinds import KINDS
from nirl_mj.experiments.seeds import domain_seeds
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import make_env


class CountingExpert:
    """Labels every state 3 and counts what it was shown."""

    kind = "counting"

    def __init__(self) -> None:
        self.resets, self.seen = 0, 0

    def reset(self, env, timestep) -> None:
        self.resets += 1

    def act(self, timestep) -> int:
        self.seen += 1
        return 3


def test_the_learner_drives_and_the_expert_labels_every_visited_state():
    expert = CountingExpert()
    agent = LabellingAgent(lambda phi: 0, expert)
    trajectory = run_episode(make_env(OPEN), agent, 7)
    assert set(trajectory.actions.tolist()) == {0}  # the learner's actions were executed
    assert agent.labels == [3] * len(trajectory)  # the expert's labels were recorded, one per decision
    np.testing.assert_array_equal(np.stack(agent.phi), trajectory.features[:-1])
    assert (expert.resets, expert.seen) == (1, len(trajectory))


def test_bad_config_is_refused():
    with pytest.raises(ValueError, match="rounds >= 0 and episodes >= 1"):
        DaggerConfig(rounds=1, episodes=0)


def test_a_short_dagger_run_beats_the_uniform_random_policy():
    demos = collect(OPEN, ExpertConfig("rule"), episodes=1, seed=0)
    rounds = []
    config = DaggerConfig(rounds=2, episodes=2)
    policy, arenas = train_dagger(OPEN, demos, 0, "rule", config, lambda r, n: rounds.append((r, n)))
    assert arenas == domain_seeds("train", 0, 4)
    # the data set grew in each round (by the states the expert labelled)
    assert [r for r, _ in rounds] == [1, 2] and len(stack_pairs(demos)[1]) < rounds[0][1] < rounds[1][1]
    tests = domain_seeds("test", 0, 4)
    learned, _ = evaluate(make_env(OPEN), policy, tests)
    rng = np.random.default_rng(0)
    random, _ = evaluate(make_env(OPEN), lambda phi: int(rng.integers(6)), tests)
    assert learned["success_rate"] >= 0.75 > random["success_rate"]


def test_a_dagger_rows_settings_set_the_experts_budget_and_enter_its_identity_only_when_set(tmp_path):
    data = {"kind": "compare", "methods": ["DAgger", "D1"],
            "method": {"D1": {"kind": "dagger", "settings": {"rounds": 1, "episodes": 2}}}}  # fmt: skip
    experiment = from_dict(data, "e.toml")
    default, small = experiment.methods
    assert DaggerConfig.of(default.settings) == DaggerConfig()
    assert DaggerConfig.of(small.settings) == DaggerConfig(rounds=1, episodes=2)
    # the built-in row's identity is as it was before settings existed; the other one carries them
    identities = {m["name"]: m for m in experiment.identity()["methods"]}
    assert "settings" not in identities["DAgger"]
    assert identities["D1"]["settings"] == {"rounds": 1, "episodes": 2}

    # the cell trains with that budget: 1 round of 2 learner episodes, on the first 2 training arenas
    demos = tmp_path / "demos.npz"
    save_dataset(demos, collect(OPEN, ExpertConfig("rule"), episodes=1, seed=0))
    job = SimpleNamespace(task=OPEN, demos_path=demos, seed=3, expert="rule", method=small)
    trained = KINDS["dagger"](job, True)
    assert trained.seen == frozenset(domain_seeds("train", 3, 2))
