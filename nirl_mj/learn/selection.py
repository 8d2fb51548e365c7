"""Which of a run's scored iterates it keeps: one rule for every method.

A run with iterates (the IRL loop's policies, BC's epochs, an RL run's checkpoints) keeps the one
with the highest selection score, and **the latest of them on a tie**. Scores tie often: once a
policy reproduces every demonstrated action of one or a few demonstrations, every later iterate
scores the same 1.0, and keeping the first of them keeps a policy that had barely started to learn
(docs/RESULTS.md, "Suites"). ``nirl_mj.experiments.rl`` applies the same rule checkpoint by
checkpoint as the scores arrive.
"""

from __future__ import annotations

from collections.abc import Sequence


def latest_best(scores: Sequence[float]) -> int:
    """Index of the highest score, the latest of equal ones; -1 for no scores.

    NaN never wins (it compares false with everything), unless every score is NaN: then the last.
    """
    best = -1
    for i, score in enumerate(scores):
        if best < 0 or score >= scores[best] or scores[best] != scores[best]:
            best = i
    return best
