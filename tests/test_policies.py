"""Reference policies on hand-made feature vectors."""

import numpy as np

from nirl_mj.experts.policies import always_forward, rule_policy


def phi(danger=(0,) * 7, region=1, detected=0, wall=(0,) * 7):
    return np.array([*danger, region, detected, *wall], dtype=np.float32)


def test_always_forward():
    assert always_forward(phi(danger=(7,) * 7)) == 0


def test_rule_heads_for_the_target_sector_in_open_space():
    assert rule_policy(phi(region=1)) == 0
    assert rule_policy(phi(region=2)) in (1, 2)
    assert rule_policy(phi(region=9)) in (3, 4)
    assert rule_policy(phi(region=5)) == 2  # behind, left side: sharpest left


def test_rule_avoids_danger_ahead_and_backs_off_when_boxed_in():
    # Obstacle ahead and to the right, target straight ahead: turn left.
    assert rule_policy(phi(danger=(4, 0, 0, 0, 0, 3, 4))) in (1, 2)
    # Too close to turn away at speed: back off.
    assert rule_policy(phi(danger=(7, 2, 0, 0, 0, 6, 7))) == 5
    assert rule_policy(phi(danger=(7, 7, 7, 0, 0, 7, 7))) == 5
