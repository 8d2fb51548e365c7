"""The IRL methods that share NIRL's loop, and the rows of a comparison.

Every trainable method runs the same loop (:class:`nirl_mj.learn.loop.IrlLoop`:
rollouts of the neural policy, a reward step, SARSA targets and
backpropagation, selection of the kept policy); what differs is the reward
step, chosen by ``LoopConfig.method`` and configured by its own config
(``nirl_mj.learn.config.STEP_CONFIGS``):

- ``"nirl"``: maximum margin planning (paper eq. 11-13), :class:`nirl_mj.learn.mmp.MaxMarginStep`;
- ``"al"``, ``"re"``, ``"scirl"``: the baselines of the paper's Table I
  (apprenticeship learning, relative entropy IRL, SCIRL; ``learn/al.py``,
  ``learn/reirl.py``, ``learn/scirl.py``).

A reward step has ``update(theta, trajectories, iteration, greedy_on_demos,
context=None) -> (theta, convergence)``, ``state()`` and ``load_state(state)``
(arrays only, for checkpoints). ``context`` (:class:`RolloutContext`) describes
the policy that produced ``trajectories`` (its eta and a snapshot of its network):
NIRL's default margin (the learner's policies), AL's per-state reading and RE-IRL's
importance sampling read it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from nirl_mj.learn.config import METHODS, LearnerConfig, LoopConfig

if TYPE_CHECKING:
    from nirl_mj.data.trajectory import Trajectory


@dataclass(frozen=True)
class RolloutContext:
    """The policy that produced an iteration's rollouts: Boltzmann (eq. 8) over a network's Q.

    ``eta``: the rollouts' Boltzmann parameter (1 / Q unit); ``q_values``: phi(s)
    (N, 16) -> Q(s, .) (N, 6) of the network that drove them (a snapshot of its
    weights, so it stays valid after the network is fitted).
    """

    eta: float
    q_values: Callable[[np.ndarray], np.ndarray]

    def action_probabilities(self, phi: np.ndarray) -> np.ndarray:
        """pi(s, .) of the rollouts' policy (eq. 8) in the states phi (N, 16) -> (N, 6)."""
        from nirl_mj.learn.network import boltzmann_probabilities

        return boltzmann_probabilities(self.q_values(np.asarray(phi)), self.eta)


class RewardStep(Protocol):
    """How a method turns the demonstrations and the learner's rollouts into theta."""

    def update(
        self,
        theta: np.ndarray,
        trajectories: Sequence[Trajectory],
        iteration: int,
        greedy_on_demos: np.ndarray,
        context: RolloutContext | None = None,
    ) -> tuple[np.ndarray, float]:
        """The next theta and the method's convergence measure (NIRL: the margin t)."""
        ...

    def state(self) -> dict[str, np.ndarray]: ...

    def load_state(self, state: dict[str, np.ndarray]) -> None: ...


def _max_margin(loop: LoopConfig, own: Any, demos: Sequence[Trajectory]) -> RewardStep:
    from nirl_mj.learn.mmp import MaxMarginStep

    return MaxMarginStep(loop, own, demos)


def _apprenticeship(loop: LoopConfig, own: Any, demos: Sequence[Trajectory]) -> RewardStep:
    from nirl_mj.learn.al import ProjectionStep

    return ProjectionStep(loop, own, demos)


def _relative_entropy(loop: LoopConfig, own: Any, demos: Sequence[Trajectory]) -> RewardStep:
    from nirl_mj.learn.reirl import RelativeEntropyStep

    return RelativeEntropyStep(loop, own, demos)


def _scirl(loop: LoopConfig, own: Any, demos: Sequence[Trajectory]) -> RewardStep:
    from nirl_mj.learn.scirl import ScirlStep

    return ScirlStep(loop, own, demos)


REWARD_STEPS: dict[str, Callable[[LoopConfig, Any, Sequence[Trajectory]], RewardStep]] = {
    "nirl": _max_margin,
    "al": _apprenticeship,  # Abbeel & Ng 2004, projection variant (learn/al.py)
    "re": _relative_entropy,  # Boularias, Kober & Peters 2011 (learn/reirl.py)
    "scirl": _scirl,  # Klein, Geist, Piot & Pietquin 2012 (learn/scirl.py)
}
assert tuple(REWARD_STEPS) == METHODS, "every method of nirl_mj.learn.config has a reward step"


def reward_step(config: LearnerConfig, demos: Sequence[Trajectory]) -> RewardStep:
    """The reward step of ``config.loop.method``, with its own config."""
    method = config.loop.method
    return REWARD_STEPS[method](config.loop, config.steps[method], demos)
