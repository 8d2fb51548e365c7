"""A systematically sub-optimal demonstrator: any expert acting a fixed number of decisions late.

The wrapped expert still sees every timestep (its memory and progress stay its own) and decides as
it always does; what the robot executes, and what is recorded, is the decision it made ``delay``
decisions earlier (forward for the first ``delay`` decisions, where the start area is always
clear). At the default 0.5 s decision period a delay of 2 turns one second late: the recorded
action no longer answers the recorded phi(s), the same way in every episode, which no amount of
averaging over demonstrations removes (unlike the random actions of
:class:`nirl_mj.experts.noisy.NoisyExpert`).
"""

from __future__ import annotations

from collections import deque

import dm_env

from nirl_mj.sim.episode import Agent as Expert

_FORWARD = 0


class LateExpert:
    """Wraps ``expert``; executes its decision of ``delay`` (>= 1) decisions ago."""

    def __init__(self, expert: Expert, delay: int) -> None:
        if isinstance(delay, bool) or not isinstance(delay, int) or delay < 1:
            raise ValueError(f"late expert delay = {delay!r}: must be a whole number >= 1 (decisions)")
        self.expert = expert
        self.delay = delay
        self.kind = f"late{delay}-{expert.kind}"
        self._queue: deque[int] = deque()

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        self.expert.reset(env, timestep)
        self._queue = deque([_FORWARD] * self.delay)

    def act(self, timestep: dm_env.TimeStep) -> int:
        self._queue.append(int(self.expert.act(timestep)))
        return self._queue.popleft()
