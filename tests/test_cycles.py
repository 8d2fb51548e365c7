"""The cycle an episode ends in (nirl_mj.data.cycles), on hand-built action sequences."""

import numpy as np
import pytest

from nirl_mj.data.cycles import final_cycle
from nirl_mj.data.trajectory import Trajectory
from nirl_mj.sim import spec

F, B, L30 = 0, 5, 1


def episode(actions: list[int], positions: np.ndarray | None = None) -> Trajectory:
    """A timed-out episode with these actions; phi(s)'s first value counts the decisions, so a test
    can tell which states a cycle reports."""
    t = len(actions)
    features = np.zeros((t + 1, 16), np.float32)
    features[:, 0] = np.arange(t + 1) % 8
    features[:, 7] = 1
    poses = np.zeros((t + 1, 3))
    if positions is not None:
        poses[:, :2] = positions
    return Trajectory(features=features, actions=np.array(actions, np.int8), ranges=np.zeros((t + 1, 9)),
                      poses=poses, times=np.arange(t + 1) * 0.5, arena_seed=1,
                      task=spec.load_task("navigate").to_dict(), speed=2.0, outcome="timeout",
                      demonstrator="nirl")  # fmt: skip


def test_the_longest_periodic_tail_wins_over_a_shorter_period():
    # (L30, B, B), then (F, F, F, B, B, B) five times: period 1 explains only the last 3
    # decisions, period 6 the last 32 (the two backwards before the cycle fit it too, L30 does not).
    actions = [L30, B, B] + [F, F, F, B, B, B] * 5
    cycle = final_cycle(episode(actions), min_length=12)
    assert cycle.actions == (F, F, F, B, B, B)
    assert cycle.period == 6
    assert cycle.length == 32
    # The last period's states are those of decisions 27..32 (value = index mod 8).
    assert cycle.states[:, 0].tolist() == [i % 8 for i in range(27, 33)]


def test_radius_is_the_largest_distance_from_the_tails_mean_position():
    actions = [F, B] * 15
    x = np.array([0.0, 1.0] * 15 + [0.0])  # back and forth between x = 0 and 1 m
    cycle = final_cycle(episode(actions, np.stack([x, np.zeros_like(x)], 1)))
    assert cycle.actions == (F, B)
    assert cycle.length == 30
    # 16 positions at 0 and 15 at 1: mean 15/31; farthest is x = 1, 16/31 m away.
    assert cycle.radius == pytest.approx(16 / 31)


def test_a_period_needs_two_repeats_so_a_long_period_cannot_hide_a_short_cycle():
    # Varied actions, then (F, B) five times: period 12 explains no repeat at all and must not
    # count as a 12-decision tail that outranks the 10 decisions of (F, B).
    actions = [0, 1, 2, 3, 4, 5, 4, 3, 2, 1, 0, 2, 4, 1, 5, 3] + [F, B] * 5
    cycle = final_cycle(episode(actions), min_length=4)
    assert (cycle.actions, cycle.length) == ((F, B), 10)
    assert final_cycle(episode(actions[:-1] + [L30]), min_length=4) is None  # the last repeat broken


def test_continuous_actions_have_no_cycle():
    t = episode([F] * 30)
    shares = np.zeros((30, 2), np.float32)
    continuous = Trajectory(**{**{f: getattr(t, f) for f in t.__dataclass_fields__}, "actions": shares})
    assert final_cycle(continuous) is None


def test_no_cycle_when_the_tail_is_short_or_the_actions_vary():
    assert final_cycle(episode([L30] * 10)) is None  # 10 < min_length 24
    assert final_cycle(episode([L30] * 30)).actions == (L30,)
    rng = np.random.default_rng(0)
    assert final_cycle(episode(rng.integers(0, 6, 300).tolist())) is None
    with pytest.raises(ValueError, match="min_length >= 2"):
        final_cycle(episode([F] * 30), min_length=1)
