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

Seeds are 32-bit words (:data:`SEED_LIMIT`): numpy's ``SeedSequence`` splits a larger one into
two words, and pads a short entropy list with zeros, so a larger seed would draw another seed's
arenas. The padding leaves one overlap that is kept, so that recorded datasets stay
reproducible: a dataset seeded with a domain word (101 to 104) drives, in its episode ``e``,
arena 0 of that domain for run seed ``e`` (``episode_seed(104, e) == domain_seed("final", e, 0)``).
A run never sees its own test arenas (:func:`held_out_seeds` skips them); docs/RESULTS.md says
where the published experiments meet this overlap.
"""

from __future__ import annotations

import numpy as np

DOMAINS = {"train": 101, "validation": 102, "test": 103, "final": 104}
TEST_DOMAINS = ("test", "final")
SEED_LIMIT = 2**32
"""Every seed and index lies in 0 .. SEED_LIMIT - 1 (one 32-bit word of a ``SeedSequence``)."""


def _word(value: int, what: str) -> int:
    if not 0 <= value < SEED_LIMIT:
        raise ValueError(f"{what} = {value}: a seed is a whole number in 0 .. 2^32 - 1")
    return value


def episode_seed(seed: int, episode: int) -> int:
    """The arena seed of demonstration ``episode`` in a dataset seeded ``seed``."""
    entropy = [_word(seed, "dataset seed"), _word(episode, "episode")]
    return int(np.random.SeedSequence(entropy).generate_state(1)[0])


def domain_seed(domain: str, seed: int, index: int) -> int:
    """Arena seed ``index`` of ``domain`` (a key of :data:`DOMAINS`) for run seed ``seed``."""
    entropy = [DOMAINS[domain], _word(seed, "run seed"), _word(index, "arena index")]
    return int(np.random.SeedSequence(entropy).generate_state(1)[0])


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
