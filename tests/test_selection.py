"""One tie rule for every method with iterates: the latest of the best (nirl_mj.learn.selection)."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import random_trajectory

from nirl_mj.learn import network
from nirl_mj.learn.bc import CloneSettings, early_stopped
from nirl_mj.learn.loop import IrlLoop
from nirl_mj.learn.selection import latest_best

NAN = float("nan")


@pytest.mark.parametrize(
    ("scores", "index"),
    [([], -1), ([0.4], 0), ([0.2, 0.9, 0.5], 1), ([1.0, 1.0, 0.3, 1.0, 0.8], 3), ([NAN, 0.1, NAN], 1),
     ([0.6, NAN, 0.2], 0), ([NAN, NAN], 1)],
)  # fmt: skip
def test_latest_best_takes_the_highest_score_and_the_latest_on_a_tie(scores, index):
    assert latest_best(scores) == index


def test_the_loop_selects_the_latest_of_its_best_iterates():
    # 59 of 60 iterates at 1.0, as with one all-forward demonstration: the last of them is kept
    scores = [0.5, *[1.0] * 59]
    assert IrlLoop.selected.fget(SimpleNamespace(scores=scores)) == 59
    assert IrlLoop.selected.fget(SimpleNamespace(scores=[0.2, 0.9, 0.7])) == 1


def test_early_stopping_keeps_the_latest_of_equally_scored_epochs():
    rng = np.random.default_rng(0)
    phi = np.zeros((400, 16))
    phi[:, 0], phi[:, 7] = rng.integers(0, 8, 400), 1
    held = phi[:100].copy(), (phi[:100, 0] >= 6).astype(int)
    settings = CloneSettings.of("default")
    net, epochs, scores = early_stopped((phi, (phi[:, 0] >= 6).astype(int)), held, settings, seed=1)
    best = [i + 1 for i, s in enumerate(scores) if s == max(scores)]
    assert len(best) > 1 and epochs == best[-1]  # several epochs tie here: the latest is kept
    # the network returned is the one of that epoch: training for exactly that many gives it again
    again, count, _ = early_stopped((phi, (phi[:, 0] >= 6).astype(int)), held,
                                    dataclasses.replace(settings, epochs=epochs), seed=1)  # fmt: skip
    assert count == epochs
    mine, theirs = network.get_weights(net), network.get_weights(again)
    assert all(np.array_equal(mine[k], theirs[k]) for k in mine)


def test_the_validation_re_check_keeps_the_latest_of_tied_candidates(monkeypatch):
    import nirl_mj.experiments.training as training

    driven = []

    def evaluate(env, policy, seeds, rollouts=None):
        driven.append(list(seeds))
        return [{"success_rate": 0.5}]

    monkeypatch.setattr(training, "_greedy", lambda net, config: None)
    monkeypatch.setattr(training, "evaluate", evaluate)
    scores = [0.3, 0.8, 0.8, 0.8, 0.6]
    loop = SimpleNamespace(
        selection="validation", final_candidates=2, validation_arenas=1, end_check_arenas=0
    )
    learner = SimpleNamespace(scores=scores, kept=[object()] * 5, config=None, selected=latest_best(scores),
                              loop=loop)  # fmt: skip
    chosen = training.select(learner, rollouts=None, validation=[0, 1, 2])
    assert driven == [[1, 2], [1, 2]]  # the second round: the arenas after the first round's one
    assert sorted(chosen["candidates"]) == ["2", "3"] and chosen["iteration"] == 3
    assert chosen["first_round_best"] == 3 and chosen["ties"] == "latest"
    # a NaN score (no demonstrated pair scored) is never a candidate before a number
    learner.scores, learner.selected = [0.3, NAN, 0.8, NAN], 2
    assert sorted(training.select(learner, rollouts=None, validation=[0, 1])["candidates"]) == ["0", "2"]
    # one round of validation arenas only: the first round's best, nothing driven
    driven.clear()
    assert training.select(learner, rollouts=None, validation=[0]) == {
        "rule": "validation", "iteration": 2, "ties": "latest"}  # fmt: skip
    assert driven == []


def _end_check(monkeypatch, scores: list[float], outcomes: dict[int, list[str]], arenas: int = 4) -> dict:
    """The end check (``training._end_checked``) with iterate i's greedy policy driven as ``i`` and
    its episodes ending as ``outcomes[i]`` (one per arena; "target" where not given)."""
    import nirl_mj.experiments.training as training

    driven = []

    def evaluate(env, policy, seeds, rollouts=None):
        driven.append((policy, list(seeds)))
        ends = outcomes.get(policy, ["target"] * len(seeds))
        rng = np.random.default_rng(0)
        return {}, [random_trajectory(rng, 3, end) for end in ends]

    monkeypatch.setattr(training, "_greedy", lambda weights, config: weights)
    monkeypatch.setattr(training, "evaluate", evaluate)
    loop = SimpleNamespace(selection="demo_balanced", final_candidates=2, validation_arenas=20,
                           end_check_arenas=arenas)  # fmt: skip
    learner = SimpleNamespace(scores=scores, kept=list(range(len(scores))), config=None,
                              selected=latest_best(scores), loop=loop)  # fmt: skip
    chosen = training.select(learner, rollouts=None, validation=list(range(100, 120)))
    assert all(seeds == list(range(100, 100 + arenas)) for _, seeds in driven)  # the first N arenas
    assert sorted(policy for policy, _ in driven) == sorted(int(i) for i in chosen["candidates"])
    return chosen


def test_the_end_check_keeps_the_candidate_whose_episodes_end(monkeypatch):
    """The rule's best two (iterates 2 and 1: 0.9 each, the latest first) and the last (5) are driven;
    iterate 2 times out once in 4 arenas, 1 collides twice (an end all the same: the check reads
    that an episode ended, never how), so 1 is kept; iterate 4 (0.8) is not a candidate."""
    scores = [0.3, 0.9, 0.9, 0.5, 0.8, 0.2]
    outcomes = {
        2: ["target", "timeout", "target", "target"],
        1: ["collision", "target", "collision", "target"],
    }
    chosen = _end_check(monkeypatch, scores, outcomes)
    assert chosen["candidates"] == {"1": {"score": 0.9, "ended": 4}, "2": {"score": 0.9, "ended": 3},
                                    "5": {"score": 0.2, "ended": 4}}  # fmt: skip
    assert chosen["iteration"] == 1 and chosen["first_round_best"] == 2 and chosen["end_check_arenas"] == 4
    # every candidate's episodes end: the rule's choice
    assert _end_check(monkeypatch, scores, {})["iteration"] == 2
    # only the last iterate's end: the last, however low its score
    looping = {i: ["timeout"] * 4 for i in (1, 2)}
    assert _end_check(monkeypatch, scores, looping)["iteration"] == 5
    # the last among the rule's best: no fifth candidate
    chosen = _end_check(monkeypatch, [0.3, 0.9, 0.95], {2: ["timeout"] * 4})
    assert sorted(chosen["candidates"]) == ["1", "2"] and chosen["iteration"] == 1


def test_the_end_check_goes_with_a_rule_that_reads_the_demonstrations():
    from nirl_mj.learn.config import LearnerConfig

    for rule in ("last", "validation"):
        with pytest.raises(ValueError, match="end_check_arenas = 20 .*demo_balanced.*set it to 0"):
            LearnerConfig.preset("default", selection=rule, end_check_arenas=20)
    with pytest.raises(ValueError, match="end_check_arenas = -1: expected a whole number >= 0"):
        LearnerConfig.preset("default", end_check_arenas=-1)
    assert (
        LearnerConfig.preset("default", selection="demo_accuracy", end_check_arenas=5).loop.end_check_arenas
        == 5
    )
