"""Reference policies on hand-made feature vectors."""

import numpy as np

from nirl_mj.experts.policies import PolicyAgent, always_forward, rule_actions, rule_policy


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


def test_batch_forms_choose_what_the_policies_choose_state_by_state():
    rng = np.random.default_rng(0)
    batch = np.zeros((3000, 16), dtype=np.float32)
    batch[:, :7] = rng.integers(0, 8, (3000, 7))
    batch[:, 7] = rng.integers(1, 10, 3000)
    for name in ("rule", "forward"):
        agent = PolicyAgent.named(name)
        chosen = agent.act_batch(batch)
        assert chosen.shape == (3000,)
        assert chosen.tolist() == [agent.policy(p) for p in batch]
    # The rule's batch form covers every action, backing off included (not a constant answer).
    assert set(rule_actions(batch).tolist()) == set(range(6))
    # A policy without a batch form is asked state by state.
    assert PolicyAgent(lambda p: int(p[7]) % 6, "custom").act_batch(batch[:5]).tolist() == [
        int(p[7]) % 6 for p in batch[:5]
    ]
