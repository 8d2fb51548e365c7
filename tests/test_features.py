"""phi(s) and f(s, a) (paper section III-A, eq. 4-5) on hand-computed cases."""

import numpy as np
import pytest

from nirl_mj.data import features


@pytest.mark.parametrize(
    ("clearance", "level"),
    [
        (np.inf, 0),
        (5.0, 0),  # at the range: not sensed
        (4.99, 1),
        (4.4, 1),
        (4.3, 2),
        (3.0, 3),  # exactly 3 bands of 4/6 m out: 6 - 3
        (2.99, 4),
        (1.7, 5),
        (1.6, 6),
        (1.0, 6),
        (0.99, 7),
        (0.0, 7),
        # edges that floating point puts just below the band's (1 + 4/6 = 1.6666666666666665): the
        # epsilon keeps them in the farther band
        (1.0 + 4.0 / 6, 5),
        (1.0 + 2 * (4.0 / 6), 4),
    ],
)
def test_danger_bands_default(clearance, level):
    assert features.danger_levels(clearance, 5.0, 1.0) == level


def test_danger_bands_follow_the_tasks_range_and_danger7_clearance():
    # R = 3 m, c7 = 0.6 m: six bands of 0.4 m, [0.6, 1.0) level 6 down to [2.6, 3.0) level 1
    clearances = [0.0, 0.59, 0.6, 0.99, 1.0, 2.59, 2.6, 2.99, 3.0, np.inf]
    levels = features.danger_levels(np.array(clearances), 3.0, 0.6)
    assert levels.tolist() == [7, 7, 6, 6, 5, 2, 1, 1, 0, 0]


def test_danger_is_monotone_in_clearance():
    c = np.linspace(0, 6, 601)
    levels = features.danger_levels(c, 5.0, 1.0)
    assert np.all(np.diff(levels.astype(int)) <= 0)
    assert set(levels.tolist()) == set(range(8))


@pytest.mark.parametrize(
    ("degrees", "region"),
    [
        (0, 1),
        (19.9, 1),
        (20.1, 2),
        (40, 2),
        (80, 3),
        (160, 5),
        (200, 6),
        (-40, 9),
        (-20.1, 9),
        (339, 9),
        (340, 1),
        (720, 1),
    ],
)
def test_target_region(degrees, region):
    assert features.target_region(np.deg2rad(degrees)) == region


def test_state_features_layout_drops_rear_sensors():
    danger = np.arange(9)  # S_i has danger i - 1
    wall = np.array([1, 0, 0, 0, 1, 1, 0, 0, 1], dtype=bool)
    phi = features.state_features(danger, wall, region=4, detected=True)
    assert phi.shape == (16,)
    np.testing.assert_array_equal(phi[:7], [0, 1, 2, 3, 6, 7, 8])  # S1-S4, S7-S9
    assert phi[7] == 4 and phi[8] == 1
    np.testing.assert_array_equal(phi[9:], [1, 0, 0, 0, 0, 0, 1])
    assert features.FEATURE_NAMES[4] == "D_S7" and features.FEATURE_NAMES[15] == "U_S9"


def test_state_action_features_place_phi_in_the_action_block():
    phi = np.arange(1, 17, dtype=np.float32)
    for a in range(6):
        f = features.state_action_features(phi, a)
        assert f.shape == (96,)
        np.testing.assert_array_equal(f[16 * a : 16 * (a + 1)], phi)
        assert np.count_nonzero(f) == 16
    batch = features.state_action_features(np.stack([phi, 2 * phi]), np.array([5, 0]))
    np.testing.assert_array_equal(batch[0, 80:], phi)
    np.testing.assert_array_equal(batch[1, :16], 2 * phi)


def test_state_action_features_rejects_bad_action():
    with pytest.raises(ValueError, match="0..5"):
        features.state_action_features(np.zeros(16), 6)
