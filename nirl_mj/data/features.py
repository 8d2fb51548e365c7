"""The paper's state and state-action features (section III-A, eq. 4-5).

Pure numpy: range readings and the target's bearing in, phi(s) (16 values) and
f(s, a) (96 values) out. Sensors are numbered S1..S9 at 0, 40, ..., 320 degrees
counter-clockwise from the robot's front; the paper leaves out the rear pair
S5 and S6.

Danger bands, with c the clearance from the robot's outline, R the sensing
range and c7 the danger-7 clearance (defaults R = 5 m, c7 = 1 m, band width
w = (R - c7) / 6 = 0.667 m):

- 0: nothing within R (c >= R);
- 7: c < c7, contact or a collision within one decision at 2 m/s;
- k in 1..6: c7 + (6 - k) w <= c < c7 + (7 - k) w; by default 6 is [1, 1.667),
  5 is [1.667, 2.333), ..., 1 is [4.333, 5).
"""

from __future__ import annotations

import numpy as np

N_SENSORS = 9
N_FEATURES = 16
N_ACTIONS = 6
SENSOR_ANGLES = np.deg2rad(np.arange(N_SENSORS) * 40.0)
"""Sensor directions S1..S9, radians counter-clockwise from the front, shape (9,)."""
SECTOR_WIDTH = np.deg2rad(40.0)

FEATURE_SENSORS = (0, 1, 2, 3, 6, 7, 8)
"""Zero-based indices of S1, S2, S3, S4, S7, S8, S9: the sensors in phi(s)."""

_SENSOR_NAMES = [f"S{i + 1}" for i in FEATURE_SENSORS]
FEATURE_NAMES = (
    *(f"D_{s}" for s in _SENSOR_NAMES),
    "V",
    "I",
    *(f"U_{s}" for s in _SENSOR_NAMES),
)
"""Names of the 16 components of phi(s), in order: [D (7), V, I, U (7)]."""

ACTION_NAMES = ("forward", "left30", "left60", "right30", "right60", "backward")
"""The six discrete actions u1..u6 of the paper, in action-index order 0..5."""


def danger_levels(clearance: np.ndarray, sensing_range: float, danger7_clearance: float) -> np.ndarray:
    """Quantises clearances (metres, any shape; ``inf`` for no hit) into danger levels 0..7 (int8)."""
    c = np.asarray(clearance, dtype=np.float64)
    width = (sensing_range - danger7_clearance) / 6.0
    # Level 6 for the band just outside c7, decreasing by one per band; the
    # epsilon puts a clearance exactly on a band edge into the farther band.
    banded = 6 - np.floor((c - danger7_clearance) / width + 1e-9)
    levels = np.where(c < danger7_clearance, 7, np.clip(banded, 1, 6))
    levels = np.where(c >= sensing_range, 0, levels)
    return levels.astype(np.int8)


def sector_centre(phi: np.ndarray) -> np.ndarray:
    """The centre of the target's sector V as a bearing, radians counter-clockwise from the front:
    phi (..., 16) -> (...). The direction the learner's bearing features are built from."""
    return SENSOR_ANGLES[np.asarray(phi)[..., 7].astype(int) - 1]


def target_region(bearing: float | np.ndarray) -> np.ndarray:
    """Sector 1..9 whose 40-degree cone contains the bearing (radians, counter-clockwise
    from the front; any real value)."""
    b = np.mod(np.asarray(bearing, dtype=np.float64) + SECTOR_WIDTH / 2, 2 * np.pi)
    return (np.floor(b / SECTOR_WIDTH).astype(np.int64) % N_SENSORS + 1).astype(np.int8)


def state_features(
    danger: np.ndarray, wall: np.ndarray, region: int | np.ndarray, detected: bool | np.ndarray
) -> np.ndarray:
    """phi(s) = [D_t, V_t, I_t, U_t] (paper section III-A), float32 of shape (16,).

    ``danger`` and ``wall`` hold all nine sensors, shape (9,); only S1-S4 and
    S7-S9 enter phi. A batch works alike: ``danger`` and ``wall`` (..., 9), ``region`` and
    ``detected`` (...) -> (..., 16).
    """
    danger = np.asarray(danger)
    phi = np.empty((*danger.shape[:-1], N_FEATURES), dtype=np.float32)
    phi[..., 0:7] = danger[..., list(FEATURE_SENSORS)]
    phi[..., 7] = region
    phi[..., 8] = np.asarray(detected, dtype=np.float32)
    phi[..., 9:16] = np.asarray(wall)[..., list(FEATURE_SENSORS)]
    return phi


def state_action_features(phi: np.ndarray, action: int | np.ndarray) -> np.ndarray:
    """f(s, a) of eq. 4-5: phi placed in the block of the taken action, zeros elsewhere.

    ``phi`` (..., 16) and ``action`` (...) integers in 0..5 -> (..., 96).
    """
    phi = np.asarray(phi)
    action = np.asarray(action)
    if np.any((action < 0) | (action >= N_ACTIONS)):
        raise ValueError(f"action must be in 0..{N_ACTIONS - 1}, got {action}")
    out = np.zeros((*phi.shape[:-1], N_ACTIONS, phi.shape[-1]), dtype=phi.dtype)
    np.put_along_axis(out, action[..., None, None], phi[..., None, :], axis=-2)
    return out.reshape(*phi.shape[:-1], N_ACTIONS * phi.shape[-1])
