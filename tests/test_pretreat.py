"""MAP pretreatment (paper eq. 10) on hand-made datasets with known answers."""

import numpy as np
import pytest

from nirl_mj.data.trajectory import Trajectory, stack_pairs
from nirl_mj.learn.pretreat import MapReport, map_pretreat

FWD, L30, L60, R30, R60, BACK = range(6)


def phi(state: int) -> np.ndarray:
    """A distinct, valid phi(s) per state id (target sector V = 1 + id % 9, danger = id // 9)."""
    f = np.zeros(16, np.float32)
    f[7] = 1 + state % 9
    f[0] = state // 9
    return f


def traj(pairs: list[tuple[int, int]], final_state: int = 99) -> Trajectory:
    """A trajectory visiting the given (state id, action) pairs, then ``final_state``."""
    states = [s for s, _ in pairs] + [final_state]
    t = len(pairs)
    return Trajectory(
        features=np.stack([phi(s) for s in states]),
        actions=np.array([a for _, a in pairs], np.int8),
        ranges=np.full((t + 1, 9), 5.0),
        poses=np.zeros((t + 1, 3)),
        times=np.arange(t + 1) * 0.5,
        arena_seed=0,
        task={},
        speed=2.0,
        outcome="target",
        demonstrator="noisy-planner",
    )


PAIRS = [
    [(0, FWD), (1, FWD), (0, BACK), (2, L30), (1, FWD), (1, FWD)],
    [(0, FWD), (1, FWD), (3, L60), (0, BACK), (1, FWD)],
    [(0, FWD), (2, R30), (1, FWD), (1, FWD)],
]


@pytest.fixture
def dataset():
    """State A (id 0): forward 3 times, backward 2 times. Forward is common overall
    (10 times: 7 more in state B), backward rare (only the 2 in A). So

    - uniform prior: P(A|fwd) = 3/10 < P(A|back) = 2/2 -> backward;
    - empirical prior: most frequent action in A -> forward.

    State C (id 2): left30 once, right30 once, each taken only there: a tie
    under both priors -> left30 (lowest index). State D (id 3): left60 only.
    """
    return [traj(pairs) for pairs in PAIRS]


def labels(trajs):
    return [t.actions.tolist() for t in trajs]


def test_uniform_prior_is_maximum_likelihood(dataset):
    for prior in (None, "uniform"):
        out, report = map_pretreat(dataset, prior)
        assert labels(out) == [
            [BACK, FWD, BACK, L30, FWD, FWD],
            [BACK, FWD, L60, BACK, FWD],
            [BACK, L30, FWD, FWD],
        ]
        assert report == MapReport(
            pairs_changed=4,  # three forwards in A, one right30 in C
            ambiguous_states=2,
            pairs_total=15,
            states_total=4,
            ambiguous_pairs=7,
            prior=(1 / 6,) * 6,
        )


def test_empirical_prior_takes_most_frequent_action(dataset):
    out, report = map_pretreat(dataset, "empirical")
    assert labels(out) == [
        [FWD, FWD, FWD, L30, FWD, FWD],
        [FWD, FWD, L60, FWD, FWD],
        [FWD, L30, FWD, FWD],
    ]
    assert (report.pairs_changed, report.ambiguous_states, report.pairs_total) == (3, 2, 15)
    counts = np.bincount(stack_pairs(dataset)[1], minlength=6)
    np.testing.assert_allclose(report.prior, counts / counts.sum())


def test_explicit_prior(dataset):
    # Forward strongly favoured: 3/10 * 0.9 = 0.27 > 2/2 * 0.02 -> forward in A.
    # In C: 1/1 * 0.02 (left30) < 1/1 * 0.04 (right30) -> right30.
    out, report = map_pretreat(dataset, np.array([0.9, 0.02, 0.02, 0.04, 0.0, 0.02]))
    assert labels(out) == [
        [FWD, FWD, FWD, R30, FWD, FWD],
        [FWD, FWD, L60, FWD, FWD],
        [FWD, R30, FWD, FWD],
    ]
    assert report.pairs_changed == 3  # two backwards in A, the left30 in C
    # Backward favoured enough: 3/10 * 0.25 = 0.075 < 1 * 0.25 -> backward.
    out, _ = map_pretreat(dataset, [0.25, 0.25, 0.0, 0.0, 0.25, 0.25])
    assert out[0].actions[0] == BACK


def test_exact_ties_go_to_lowest_index():
    # In state 0: forward 2 of 4, left30 1 of 2: equal likelihoods 1/2 exactly.
    data = [traj([(0, FWD), (0, FWD), (1, FWD), (1, FWD), (0, L30), (2, L30)])]
    out, report = map_pretreat(data)
    assert out[0].actions.tolist() == [FWD, FWD, FWD, FWD, FWD, L30]
    assert report.pairs_changed == 1
    # Empirical prior: count(s, a) ties exactly (one right60, one left30) -> left30.
    data = [traj([(0, R60), (0, L30), (1, L30), (2, R60)])]
    out, report = map_pretreat(data, "empirical")
    assert out[0].actions.tolist() == [L30, L30, L30, R60]
    assert report.pairs_changed == 1


def test_zero_prior_for_all_observed_actions_takes_lowest_observed():
    data = [traj([(0, L60), (0, R60), (1, FWD)])]
    out, _ = map_pretreat(data, [1.0, 0, 0, 0, 0, 0])
    assert out[0].actions.tolist() == [L60, L60, FWD]


def test_unambiguous_dataset_unchanged(dataset):
    clean = [traj([(0, FWD), (1, L30), (2, R30)]), traj([(0, FWD), (3, BACK)])]
    out, report = map_pretreat(clean)
    assert all(a is b for a, b in zip(out, clean, strict=True))
    assert (report.pairs_changed, report.ambiguous_states, report.ambiguous_pairs) == (0, 0, 0)


def test_only_actions_change_and_input_untouched(dataset):
    before = labels(dataset)
    out, _ = map_pretreat(dataset)
    assert labels(dataset) == before
    for a, b in zip(dataset, out, strict=True):
        for name in ("features", "ranges", "poses", "times"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert (a.arena_seed, a.task, a.speed, a.outcome, a.demonstrator) == (
            b.arena_seed,
            b.task,
            b.speed,
            b.outcome,
            b.demonstrator,
        )
        assert b.actions.dtype == np.int8


def test_final_states_do_not_count(dataset):
    # The final state (id 99) is never paired with an action, so it is not a state of D_E.
    _, report = map_pretreat(dataset)
    assert report.states_total == 4


def test_idempotent(dataset):
    once, _ = map_pretreat(dataset)
    twice, report = map_pretreat(once)
    assert labels(once) == labels(twice) and report.pairs_changed == 0


def test_empty():
    out, report = map_pretreat([])
    assert out == [] and report.pairs_total == 0
    out, report = map_pretreat([traj([])])
    assert report.pairs_total == 0 and len(out) == 1


@pytest.mark.parametrize(
    "prior, match",
    [
        ("bayes", "prior must be None, 'uniform', 'empirical'"),
        ([0.5, 0.5], "6 probabilities"),
        ([0.5, 0.5, 0.5, -0.5, 0.0, 0.0], "non-negative"),
        ([0.1] * 6, "sum to 1"),
        ([np.nan, 1, 0, 0, 0, 0], "finite"),
        (["a"] * 6, "prior must be"),
    ],
)
def test_prior_validation(dataset, prior, match):
    with pytest.raises(ValueError, match=match):
        map_pretreat(dataset, prior)


def test_the_learner_trains_on_the_pretreated_demonstrations_when_asked(dataset):
    from nirl_mj.learn.config import LearnerConfig
    from nirl_mj.learn.loop import IrlLoop

    relabelled, report = map_pretreat(dataset)
    majority, _ = map_pretreat(dataset, "empirical")
    assert report.pairs_changed > 0  # the dataset has ambiguous states: a test that can fail
    # ... on which the two priors disagree (state A: uniform -> backward, empirical -> forward)
    assert stack_pairs(relabelled)[1].tolist() != stack_pairs(majority)[1].tolist()
    on = IrlLoop(LearnerConfig.preset("default", pretreatment="map"), dataset, seed=0)
    by_majority = IrlLoop(LearnerConfig.preset("default", pretreatment="map-majority"), dataset, seed=0)
    off = IrlLoop(LearnerConfig.preset("default"), dataset, seed=0)
    assert on.demo_actions.tolist() == stack_pairs(relabelled)[1].tolist()
    assert by_majority.demo_actions.tolist() == stack_pairs(majority)[1].tolist()
    assert off.demo_actions.tolist() == stack_pairs(dataset)[1].tolist()
    assert LearnerConfig.from_record({}).loop.pretreatment == "none"  # records before it: as recorded
    with pytest.raises(ValueError, match="unknown pretreatment 'mle'; accepted: none, map, map-majority"):
        LearnerConfig.preset("default", pretreatment="mle")


def test_inspect_reports_what_each_prior_would_relabel(tmp_path, capsys):
    """``nirl-mj inspect``: state A's 3 forwards become backward under the uniform prior, its 2
    backwards forward under the empirical one; state C's right30 becomes left30 under both (a tie)."""
    import dataclasses
    import json

    from nirl_mj.cli import main
    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.sim import spec

    task = spec.load_task("navigate").to_dict()
    path = tmp_path / "d.npz"
    # the fixture's dataset, ending in state 8: its final state 99 has a danger level no sensor gives
    save_dataset(path, [dataclasses.replace(traj(pairs, final_state=8), task=task) for pairs in PAIRS])
    assert main(["inspect", str(path), "--json"]) == 0
    out = capsys.readouterr().out
    summary = json.loads(out.strip().splitlines()[-1])
    assert (summary["map_pairs_changed"], summary["map_majority_pairs_changed"]) == (4, 3)
    # 15 pairs: uniform leaves forward 7 (10 - 3) and backward 5; empirical forward 12, backward 0.
    assert 'pretreatment = "map") would relabel 4 of 15 pairs' in out and "backward 33.3%" in out
    assert 'pretreatment = "map-majority") would relabel 3 of 15 pairs' in out and "forward 80.0%" in out
    # the states each prior relabels most, state A first (phi: V = 1, nothing else)
    assert "  D 0000000 V 1 I 0 U 0000000: 5 pairs (forward 3, backward 2) -> backward\n" in out
    assert "  D 0000000 V 1 I 0 U 0000000: 5 pairs (forward 3, backward 2) -> forward\n" in out


def test_relabelled_states_lists_the_states_that_changed_most(dataset):
    from nirl_mj.learn.pretreat import relabelled_states

    uniform = relabelled_states(dataset, map_pretreat(dataset)[0])
    # state A (fwd 3, back 2) -> backward: 3 pairs changed; state C (left30 1, right30 1) -> left30: 1.
    assert [(int(r.phi[7]), r.recorded.tolist(), r.action, r.changed) for r in uniform] == [
        (1, [3, 0, 0, 0, 0, 2], BACK, 3),
        (3, [0, 1, 0, 1, 0, 0], L30, 1),
    ]
    majority = relabelled_states(dataset, map_pretreat(dataset, "empirical")[0], top=1)
    assert [(int(r.phi[7]), r.action, r.changed) for r in majority] == [(1, FWD, 2)]
    assert relabelled_states(dataset, dataset) == []  # nothing relabelled
