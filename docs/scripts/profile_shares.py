"""Inclusive share of the samples in each function of a py-spy profile (``--format raw``).

    py-spy record --format raw -r 50 -o PROFILE.raw -- nirl-mj compare ...
    python docs/scripts/profile_shares.py PROFILE.raw [TOP]

A function's share counts every sample in which it is on the stack (once per sample, however
deep), so a caller's share includes its callees'. Used for the AIRL cell's profile
(docs/results/airl_profile/, PERFORMANCE.md).
"""

from __future__ import annotations

import re
import sys
from collections import Counter
from pathlib import Path


def shares(raw: Path) -> tuple[int, Counter]:
    """(samples, samples per function name) of a py-spy raw (collapsed-stack) file."""
    total, inclusive = 0, Counter()
    for line in raw.read_text().splitlines():
        stack, _, count = line.rpartition(" ")
        total += int(count)
        for name in {re.sub(r" \(.*\)$", "", frame) for frame in stack.split(";")}:
            inclusive[name] += int(count)
    return total, inclusive


def main(raw: Path, top: int = 40) -> None:
    total, inclusive = shares(raw)
    print(f"{total} samples; inclusive share of each function (a caller's includes its callees')")
    for name, count in inclusive.most_common(top):
        print(f"{count / total:6.1%}  {name}")


if __name__ == "__main__":
    main(Path(sys.argv[1]), *(int(a) for a in sys.argv[2:3]))
