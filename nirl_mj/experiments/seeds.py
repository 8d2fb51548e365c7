"""Every arena seed of the project, from disjoint domains.

- Demonstrations: episode ``i`` of a dataset seeded ``S`` runs in the arena of
  :func:`episode_seed` (S, i), independent of the order in which episodes run, so
  they can be split across processes.
- Training rollouts, validation and test arenas: :func:`domain_seed` with their own
  domain word, so they never draw the same stream. Two test domains: ``"test"``, the
  development arenas on which designs were compared and tuned, and ``"final"``, drawn only
  for the reported tables (an experiment's ``test_domain``; docs/RESULTS.md).
- A held-out evaluation skips every arena a run has seen (:func:`seen_seeds`, from
  the sets its run record stores).
"""

from __future__ import annotations

import numpy as np

DOMAINS = {"train": 101, "validation": 102, "test": 103, "final": 104}
TEST_DOMAINS = ("test", "final")


def episode_seed(seed: int, episode: int) -> int:
    """The arena seed of demonstration ``episode`` in a dataset seeded ``seed``."""
    return int(np.random.SeedSequence([seed, episode]).generate_state(1)[0])


def domain_seed(domain: str, seed: int, index: int) -> int:
    """Arena seed ``index`` of ``domain`` (a key of :data:`DOMAINS`) for run seed ``seed``."""
    return int(np.random.SeedSequence([DOMAINS[domain], seed, index]).generate_state(1)[0])


def domain_seeds(domain: str, seed: int, count: int, start: int = 0) -> list[int]:
    """Arena seeds ``start .. start + count - 1`` of ``domain`` for run seed ``seed``."""
    return [domain_seed(domain, seed, i) for i in range(start, start + count)]


def held_out_seeds(seed: int, count: int, seen: set[int], domain: str = "test") -> list[int]:
    """``count`` test-arena seeds of ``seed`` in ``domain`` (:data:`TEST_DOMAINS`), skipping any
    arena in ``seen``."""
    if domain not in TEST_DOMAINS:
        raise ValueError(f"unknown test domain {domain!r}; accepted: {', '.join(TEST_DOMAINS)}")
    seeds, i = [], 0
    while len(seeds) < count:
        s = domain_seed(domain, seed, i)
        i += 1
        if s not in seen:
            seeds.append(s)
    return seeds


def seen_seeds(record: dict) -> set[int]:
    """Every arena seed a run's learner saw: demonstrations, training rollouts, validation."""
    return {
        *record.get("demo_seeds", []),
        *record.get("validation_seeds", []),
        *record.get("train_seeds", []),
    }
