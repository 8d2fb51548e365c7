"""MAP pretreatment of sub-optimal demonstrations (paper section IV-A, eq. 10).

A demonstrator may take different actions in the same state (here: the same
phi(s), compared exactly). Every such ambiguous state gets one action,

    a_hat(s) = argmax_a P(s | a) P(a),                                  (10)

with the likelihood counted over the whole dataset, P(s | a) = count(s, a) /
count(a), and every occurrence of the state is relabelled with a_hat(s).
States seen with a single action are left as they are.

Priors:

- ``None`` or ``"uniform"`` (the paper's default): P(a) = 1/6, so a_hat is the
  maximum-likelihood action argmax_a count(s, a) / count(a). A rare action
  (e.g. backward) can win a state although it was taken there less often than
  a common one, because it is taken *mostly* there.
- ``"empirical"``: P(a) = count(a) / N, which reduces a_hat to the most
  frequent action in s.
- an array of 6 probabilities (non-negative, summing to 1).

Scores are compared exactly (rational arithmetic on the counts and the prior's
float values), so ties are real ties; a tie is broken towards the lowest action
index (forward < left30 < left60 < right30 < right60 < backward). Only actions
observed in s compete (the others have likelihood 0); if the prior gives all of
them probability 0 the lowest observed action index wins.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from fractions import Fraction

import numpy as np

from nirl_mj.data.features import N_ACTIONS
from nirl_mj.data.trajectory import Trajectory, stack_pairs


@dataclass(frozen=True)
class MapReport:
    """What :func:`map_pretreat` did.

    ``pairs_changed``: state-action pairs whose action was relabelled;
    ``ambiguous_states``: distinct phi(s) seen with more than one action;
    ``pairs_total``: state-action pairs in the dataset; ``states_total``:
    distinct phi(s); ``ambiguous_pairs``: pairs in ambiguous states;
    ``prior``: P(a) used, (6,) probabilities.
    """

    pairs_changed: int
    ambiguous_states: int
    pairs_total: int
    states_total: int
    ambiguous_pairs: int
    prior: tuple[float, ...]

    def to_dict(self) -> dict:
        return asdict(self)


def _prior_fractions(
    prior: str | Sequence[float] | np.ndarray | None, action_counts: np.ndarray
) -> list[Fraction]:
    """P(a) as exact fractions (floats are converted exactly)."""
    if prior is None or (isinstance(prior, str) and prior == "uniform"):
        return [Fraction(1, N_ACTIONS)] * N_ACTIONS
    if isinstance(prior, str):
        if prior == "empirical":
            total = int(action_counts.sum())
            return [Fraction(int(c), total) if total else Fraction(1, N_ACTIONS) for c in action_counts]
        raise ValueError(
            f"prior must be None, 'uniform', 'empirical' or {N_ACTIONS} probabilities, got {prior!r}"
        )
    try:
        p = np.asarray(prior, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(
            f"prior must be None, 'uniform', 'empirical' or {N_ACTIONS} probabilities, got {prior!r}"
        ) from None
    if p.shape != (N_ACTIONS,):
        raise ValueError(f"prior must hold {N_ACTIONS} probabilities (one per action), got shape {p.shape}")
    if not np.all(np.isfinite(p)) or np.any(p < 0):
        raise ValueError(f"prior probabilities must be finite and non-negative, got {p.tolist()}")
    if abs(p.sum() - 1.0) > 1e-6:
        raise ValueError(f"prior probabilities must sum to 1, got sum {p.sum():.6g} ({p.tolist()})")
    return [Fraction(float(v)) for v in p]


def _state_counts(states: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Groups identical phi(s) rows (exact equality of the float32 values): the distinct states
    (S, 16), each pair's state id (M,), and the action counts per state (S, 6)."""
    unique, state_id = np.unique(states, axis=0, return_inverse=True)
    state_id = state_id.reshape(-1)
    counts = np.zeros((len(unique), N_ACTIONS), dtype=np.int64)
    np.add.at(counts, (state_id, actions.astype(np.int64)), 1)
    return unique, state_id, counts


def map_pretreat(
    trajectories: Sequence[Trajectory], prior: str | Sequence[float] | np.ndarray | None = None
) -> tuple[list[Trajectory], MapReport]:
    """Relabels the actions of ambiguous states with the MAP action of eq. 10.

    Returns new trajectories (the unchanged ones are returned as they are; only
    ``actions`` ever differs) and a :class:`MapReport`. ``prior``: ``None`` or
    ``"uniform"`` (default), ``"empirical"``, or (6,) probabilities; see the
    module docstring for tie-breaking.
    """
    trajectories = list(trajectories)
    states, actions = stack_pairs(trajectories)
    m = int(actions.shape[0])
    if m == 0:
        probs = _prior_fractions(prior, np.zeros(N_ACTIONS, np.int64))
        return trajectories, MapReport(0, 0, 0, 0, 0, tuple(float(p) for p in probs))
    _, state_id, counts = _state_counts(states, actions)
    n_states = counts.shape[0]
    action_counts = counts.sum(axis=0)
    probs = _prior_fractions(prior, action_counts)

    # Every state's label: its own action unless ambiguous (then a_hat).
    label = np.argmax(counts, axis=1).astype(np.int8)
    ambiguous = np.flatnonzero((counts > 0).sum(axis=1) > 1)
    for s in ambiguous.tolist():
        observed = np.flatnonzero(counts[s]).tolist()  # ascending: first max = lowest index
        best_a, best = observed[0], None
        for a in observed:
            score = Fraction(int(counts[s, a]), int(action_counts[a])) * probs[a]
            if best is None or score > best:
                best_a, best = a, score
        label[s] = best_a

    is_ambiguous = np.zeros(n_states, dtype=bool)
    is_ambiguous[ambiguous] = True
    new_actions = np.where(is_ambiguous[state_id], label[state_id], actions).astype(np.int8)
    changed = new_actions != actions

    out = []
    start = 0
    for t in trajectories:
        end = start + len(t)
        if changed[start:end].any():
            out.append(t.with_actions(new_actions[start:end].copy()))
        else:
            out.append(t)
        start = end
    report = MapReport(
        pairs_changed=int(changed.sum()),
        ambiguous_states=int(ambiguous.size),
        pairs_total=m,
        states_total=n_states,
        ambiguous_pairs=int(is_ambiguous[state_id].sum()),
        prior=tuple(float(p) for p in probs),
    )
    return out, report


@dataclass(frozen=True)
class Relabelled:
    """One state that :func:`map_pretreat` relabelled: ``phi`` (16,), ``recorded`` (6,) action counts
    as demonstrated, ``action`` the label every pair of the state now has."""

    phi: np.ndarray
    recorded: np.ndarray
    action: int

    @property
    def changed(self) -> int:
        """Pairs of this state whose action changed."""
        return int(self.recorded.sum() - self.recorded[self.action])


def relabelled_states(
    before: Sequence[Trajectory], after: Sequence[Trajectory], top: int = 3
) -> list[Relabelled]:
    """The ``top`` states whose relabelling changed the most pairs (most first; ties by phi's order),
    from a dataset and :func:`map_pretreat`'s output for it."""
    states, recorded = stack_pairs(list(before))
    _, relabelled = stack_pairs(list(after))
    if recorded.size == 0:
        return []
    unique, state_id, counts = _state_counts(states, recorded)
    diff = recorded != relabelled
    changed = np.bincount(state_id, weights=diff, minlength=len(unique)).astype(np.int64)
    label = np.zeros(len(unique), dtype=np.int64)
    label[state_id[diff]] = relabelled[diff]  # map_pretreat gives every pair of a state one label
    order = [s for s in np.argsort(-changed, kind="stable") if changed[s] > 0][:top]
    return [Relabelled(unique[s], counts[s], int(label[s])) for s in order]
