"""The IRL methods that share NIRL's loop, and the rows of a comparison.

Every trainable method runs the same loop (:class:`nirl_mj.learn.nirl.Nirl`:
rollouts of the neural policy, a reward step, SARSA targets and
backpropagation, selection of the kept policy); what differs is the reward
step, chosen by ``NirlConfig.method``:

- ``"nirl"``: maximum margin planning (paper eq. 11-13), :class:`nirl_mj.learn.mmp.MaxMarginStep`;
- ``"al"``, ``"re"``, ``"scirl"``: the baselines of the paper's Table I
  (apprenticeship learning, relative entropy IRL, SCIRL), registered below
  when their modules exist.

A reward step has ``update(theta, trajectories, iteration, greedy_on_demos) ->
(theta, convergence)``, ``state()`` and ``load_state(state)`` (arrays only, for
checkpoints).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from nirl_mj.learn.nirl import NirlConfig
    from nirl_mj.trajectory import Trajectory


class RewardStep(Protocol):
    """How a method turns the demonstrations and the learner's rollouts into theta."""

    def update(
        self,
        theta: np.ndarray,
        trajectories: Sequence[Trajectory],
        iteration: int,
        greedy_on_demos: np.ndarray,
    ) -> tuple[np.ndarray, float]:
        """The next theta and the method's convergence measure (NIRL: the margin t)."""
        ...

    def state(self) -> dict[str, np.ndarray]: ...

    def load_state(self, state: dict[str, np.ndarray]) -> None: ...


def _max_margin(config: NirlConfig, demos: Sequence[Trajectory]) -> RewardStep:
    from nirl_mj.learn.mmp import MaxMarginStep

    return MaxMarginStep(config, demos)


REWARD_STEPS: dict[str, Callable[[NirlConfig, Sequence[Trajectory]], RewardStep]] = {"nirl": _max_margin}


def reward_step(config: NirlConfig, demos: Sequence[Trajectory]) -> RewardStep:
    """The reward step of ``config.method``."""
    try:
        make = REWARD_STEPS[config.method]
    except KeyError:
        raise ValueError(f"unknown method {config.method!r}; accepted: {', '.join(REWARD_STEPS)}") from None
    return make(config, demos)
