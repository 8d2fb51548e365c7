"""A stochastic, sub-optimal demonstrator: any expert with seeded action noise.

This is the demonstrator that MAP pretreatment (paper section IV-A, eq. 10)
exists for. Each decision, the wrapped expert chooses an action; then, with
probability ``random``, a uniformly random action replaces it; otherwise, with
probability ``slip``, the action slips (the paper's slippery road: an intended
30-degree turn executes as 60 degrees):

- left 30 <-> left 60, right 30 <-> right 60;
- forward becomes left 30 or right 30 (equally likely);
- backward does not slip.

What is recorded is the action executed, as a demonstration of a real
stochastic demonstrator would be. The noise of each episode is drawn from
``seed`` and the episode's own random state, so an episode's noise does not
depend on which episodes ran before it (parallel collection equals serial).
"""

from __future__ import annotations

import dm_env
import numpy as np

from nirl_mj.data.features import N_ACTIONS
from nirl_mj.sim.episode import Agent as Expert

_SLIPS = {0: (1, 3), 1: (2,), 2: (1,), 3: (4,), 4: (3,), 5: (5,)}


class NoisyExpert:
    """Wraps ``expert`` with action slip and random actions (probabilities in [0, 1])."""

    def __init__(self, expert: Expert, slip: float = 0.1, random: float = 0.05, seed: int = 0) -> None:
        for name, p in (("slip", slip), ("random", random)):
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"noise probability {name} = {p}: must be in [0, 1]")
        self.expert = expert
        self.kind = f"noisy-{expert.kind}"
        self.slip = slip
        self.random = random
        self._seed = seed
        self._rng = np.random.default_rng(seed)

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        # The arena is drawn; what the episode's random state gives next is
        # free to seed this episode's noise.
        self._rng = np.random.default_rng([self._seed, int(env.random_state.randint(2**31))])
        self.expert.reset(env, timestep)

    def act(self, timestep: dm_env.TimeStep) -> int:
        return self.perturb(self.expert.act(timestep))

    def perturb(self, action: int) -> int:
        """The executed action for an intended ``action``; draws exactly two random numbers
        (plus one for a choice) so noise is reproducible from the seed."""
        u_random, u_slip = self._rng.random(2)
        if u_random < self.random:
            return int(self._rng.integers(N_ACTIONS))
        if u_slip < self.slip:
            options = _SLIPS[action]
            return options[int(self._rng.integers(len(options)))] if len(options) > 1 else options[0]
        return action
