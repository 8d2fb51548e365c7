"""One tie rule for every method with iterates: the latest of the best (nirl_mj.learn.selection)."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

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

    monkeypatch.setattr(training, "_greedy", lambda net, config: None)
    monkeypatch.setattr(training, "evaluate", lambda *a, **k: [{"success_rate": 0.5}])
    scores = [0.3, 0.8, 0.8, 0.8, 0.6]
    learner = SimpleNamespace(scores=scores, kept=[object()] * 5, config=None, selected=latest_best(scores),
                              loop=SimpleNamespace(selection="validation", final_candidates=2))  # fmt: skip
    chosen = training.select(learner, rollouts=None, second_round=[1, 2])
    assert sorted(chosen["candidates"]) == ["2", "3"] and chosen["iteration"] == 3
    assert chosen["first_round_best"] == 3 and chosen["ties"] == "latest"
    # a NaN score (no demonstrated pair scored) is never a candidate before a number
    learner.scores, learner.selected = [0.3, NAN, 0.8, NAN], 2
    assert sorted(training.select(learner, rollouts=None, second_round=[1])["candidates"]) == ["0", "2"]
