"""Behaviour cloning: the reference that imitates without a reward, given the same care as NIRL.

The network of eq. 6-7 is fitted to state-action pairs with the cross-entropy cost of eq. 15,
every output at once: 1 for the demonstrated action, 0 for the others. Plain minibatch SGD as
in NIRL's network step, so the two differ only in where the targets come from.

:class:`CloneSettings` says how. ``CloneSettings.of("default")`` gives the default NIRL's inputs
and width (``learn/config.py``: D/7, the target's bearing as (cos, sin), 32 hidden units), a
class-balanced loss (each pair weighted by N / (K n_a), K the actions present and n_a the pairs
of its action, so that the 91 % "forward" of the demonstrations weighs as much as each other
action), and early stopping on held-out demonstrations: every ``held_out``-th trajectory is kept
back, and the network is kept at the epoch whose greedy actions predict it best (balanced
accuracy, mean per-action recall). ``CloneSettings.of("paper")`` is the
paper's 16-10-6 network (inputs D/7 and V/9), unweighted, 30 epochs: the BC row of Table I until
2026-11-26, now BC-paper.

:func:`clone_pairs` fits any labelled pairs (DAgger's aggregated data set,
``nirl_mj.experiments.dagger``); :func:`behaviour_cloning` the demonstrations.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from nirl_mj.data.features import N_ACTIONS
from nirl_mj.data.trajectory import Trajectory, stack_pairs
from nirl_mj.learn import network
from nirl_mj.learn.config import LearnerConfig
from nirl_mj.learn.inputs import NetworkInputs
from nirl_mj.learn.loop import demonstrated_pairs, greedy_policy
from nirl_mj.learn.predictability import balanced_accuracy
from nirl_mj.learn.selection import latest_best

Pairs = tuple[np.ndarray, np.ndarray]
"""phi(s) (N, 16) and actions (N,)."""


@dataclass(frozen=True)
class CloneSettings:
    """How a network is fitted to labelled pairs: its width and inputs, the loss, the epochs."""

    hidden_units: int = 32
    inputs: NetworkInputs = field(default_factory=lambda: NetworkInputs(scaled=True, bearing=True))
    balanced: bool = True  # each action's pairs weigh alike in the loss
    epochs: int = 40  # the most epochs (with held-out pairs), or exactly this many (without)
    held_out: int = 5  # every held_out-th trajectory chooses the epoch count (0: none held out)
    step: float = 0.4
    l2: float = 1e-3
    batch_size: int = 64

    @classmethod
    def of(cls, variant: str = "default") -> CloneSettings:
        """``"default"``: the default NIRL's inputs and width (``learn/config.py``), balanced, stopped
        early; ``"paper"``: the BC of Table I until 2026-11-26 (the paper's 10 hidden units, inputs
        scaled as NIRL's then, unweighted, 30 epochs)."""
        loop = LearnerConfig.preset(variant).loop
        if variant == "paper":  # the BC of Table I until 2026-11-26, inputs scaled as NIRL's then
            return cls(loop.hidden_units, NetworkInputs(scaled=True), balanced=False, epochs=30, held_out=0)
        return cls(loop.hidden_units, NetworkInputs.of(loop))


def class_weights(actions: np.ndarray) -> np.ndarray:
    """Per-pair weights N / (K n_a) (N,), K the actions present and n_a the pairs of action a:
    each present action's pairs sum to N / K, and the weights to N (their mean is 1)."""
    actions = np.asarray(actions, dtype=np.int64)
    counts = np.bincount(actions, minlength=N_ACTIONS).astype(np.float64)
    present = int(np.count_nonzero(counts))
    return len(actions) / (present * counts[actions])


def _problem(phi: np.ndarray, actions: np.ndarray, settings: CloneSettings) -> tuple:
    """The fit's arrays, made once: every output of every pair (inputs, output index, target 1 for
    the label and 0 for the others) and each row's weight (None: unweighted)."""
    x = np.repeat(settings.inputs(np.asarray(phi)), N_ACTIONS, axis=0)
    outputs = np.tile(np.arange(N_ACTIONS), len(actions))
    targets = (outputs == np.repeat(np.asarray(actions), N_ACTIONS)).astype(np.float64)
    weights = np.repeat(class_weights(actions), N_ACTIONS) if settings.balanced else None
    return x, outputs, targets, weights


def _epochs(net: network.QNetwork, problem: tuple, settings: CloneSettings, epochs: int,
            rng: np.random.Generator) -> None:  # fmt: skip
    """``epochs`` epochs of minibatch SGD on eq. 15 over a :func:`_problem`."""
    x, outputs, targets, weights = problem
    network.minibatch_epochs(net, x, outputs, targets, settings.l2, settings.step, epochs,
                             settings.batch_size, rng, weights)  # fmt: skip


def _fresh(settings: CloneSettings, seed: int) -> tuple[network.QNetwork, np.random.Generator]:
    net = network.QNetwork(settings.inputs.size, settings.hidden_units, seed=seed)
    return net, np.random.default_rng(seed)


def early_stopped(
    train: Pairs, held_out: Pairs, settings: CloneSettings, seed: int
) -> tuple[network.QNetwork, int, list[float]]:
    """The network fitted to ``train`` for the epoch count (1..``settings.epochs``) that predicts
    the ``held_out`` actions best (balanced accuracy; the latest of the best,
    ``nirl_mj.learn.selection``), that count, and every
    epoch's score: early stopping, the network kept as it was validated."""
    net, rng = _fresh(settings, seed)
    problem, held_inputs = _problem(*train, settings), settings.inputs(held_out[0])
    scores, best, best_weights = [], -1.0, network.get_weights(net)
    for _ in range(settings.epochs):
        _epochs(net, problem, settings, 1, rng)
        predicted = network.greedy_actions(network.q_values(net, held_inputs))
        scores.append(balanced_accuracy(held_out[1], predicted))
        if scores[-1] >= best:
            best, best_weights = scores[-1], network.get_weights(net)
    network.set_weights(net, best_weights)
    return net, latest_best(scores) + 1, scores


def clone_pairs(
    phi: np.ndarray,
    actions: np.ndarray,
    seed: int = 0,
    settings: CloneSettings | None = None,
    held_out: Pairs | None = None,
) -> Callable[[np.ndarray], int]:
    """The greedy policy on phi(s) of a network trained to predict ``actions`` (N,) from ``phi``
    (N, 16): with ``held_out`` pairs, stopped at the epoch that predicts them best
    (:func:`early_stopped`); else after ``settings.epochs`` epochs."""
    settings = settings or CloneSettings.of("default")
    phi, actions = np.asarray(phi), np.asarray(actions, dtype=np.int64)
    if held_out is not None and len(held_out[1]):
        net, _, _ = early_stopped((phi, actions), held_out, settings, seed)
    else:
        net, rng = _fresh(settings, seed)
        _epochs(net, _problem(phi, actions, settings), settings, settings.epochs, rng)
    return greedy_policy(net, settings.inputs)


def split_demonstrations(demos: Sequence[Trajectory], every: int) -> tuple[list, list]:
    """(kept, held out): every ``every``-th trajectory (the 1st, (every+1)-th, ...) is held out;
    none with ``every`` = 0 or when that would leave nothing to train on."""
    if every <= 0 or len(demos) < 2:
        return list(demos), []
    held = [t for i, t in enumerate(demos) if i % every == 0]
    kept = [t for i, t in enumerate(demos) if i % every]
    return (kept, held) if kept else (list(demos), [])


def training_pairs(demos: Sequence[Trajectory], settings: CloneSettings) -> tuple[Pairs, Pairs | None]:
    """The demonstrated pairs to fit, and the held-out ones that stop the fit (None: none held out,
    ``settings.held_out`` = 0)."""
    kept, held = split_demonstrations(list(demos), settings.held_out)
    return demonstrated_pairs(kept), (stack_pairs(held) if held else None)


def behaviour_cloning(
    demos: Sequence[Trajectory], seed: int = 0, settings: CloneSettings | None = None
) -> Callable[[np.ndarray], int]:
    """The greedy policy on phi(s) of a network trained to predict the demonstrated actions,
    stopped early on held-out demonstrations (``settings.held_out``)."""
    settings = settings or CloneSettings.of("default")
    pairs, held = training_pairs(demos, settings)
    return clone_pairs(*pairs, seed=seed, settings=settings, held_out=held)
