"""What the policy network sees of phi(s) (eq. 6: its input layer).

The paper feeds phi(s) as it is: danger levels 0..7, the target's sector V in
1..9, and the flags I and U. The default scales D by 1/7 and V by 1/9 so every
input lies in [0, 1] for the sigmoid units. V/9 is a poor code for a direction:
sectors 1 and 9 are neighbours (0 and -40 degrees) at opposite ends of the
scale, and "the target is behind" (V = 4..7) is a band in the middle. With
``bearing`` the network sees the sector's centre as (cos, sin) in V's place,
17 inputs, where "behind" is cos < 0 and "to the left" is sin > 0
(docs/notebook/algorithm.md, "Bearing features").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nirl_mj.data.features import N_FEATURES, sector_centre

_SCALE = np.array([7.0] * 7 + [9.0] + [1.0] * 8)
_V = 7


@dataclass(frozen=True)
class NetworkInputs:
    """The input code: ``scaled`` D/7 and V/9 (else raw phi); ``bearing`` (cos, sin) of V's centre
    instead of V. Called on phi (N, 16) it returns the network's input (N, :attr:`size`)."""

    scaled: bool = True
    bearing: bool = False

    @classmethod
    def of(cls, loop: object) -> NetworkInputs:
        """The code a loop config (``input_scaling``, ``input_bearing``) chooses."""
        return cls(bool(loop.input_scaling), bool(loop.input_bearing))

    @property
    def size(self) -> int:
        """Inputs per state: 16, or 17 with ``bearing``."""
        return N_FEATURES + 1 if self.bearing else N_FEATURES

    def __call__(self, phi: np.ndarray) -> np.ndarray:
        x = np.asarray(phi, dtype=np.float64)
        if self.scaled:
            x = x / _SCALE
        if not self.bearing:
            return x
        centre = sector_centre(phi)
        return np.concatenate(
            [x[..., :_V], np.cos(centre)[..., None], np.sin(centre)[..., None], x[..., _V + 1 :]], axis=-1
        )
