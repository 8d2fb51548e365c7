"""Whether the demonstrations show the states a run's limit cycles pass through, and what the expert
did there.

Reads the output of ``docs/scripts/timeouts.py`` (its ``states:`` lists, phi(s) as
``nirl_mj.inspect.text.phi_text`` writes it) and a demonstration dataset; prints, for every distinct
state of the cycles with the action the policy took in it, how many demonstrated pairs have exactly
that phi(s) and the expert's actions there.

    python docs/scripts/cycle_coverage.py TIMEOUTS.txt DEMOS.npz
"""

from __future__ import annotations

import argparse
import re
from collections import Counter

from nirl_mj.data.dataset import load_dataset
from nirl_mj.data.features import ACTION_NAMES
from nirl_mj.data.trajectory import require_discrete, stack_pairs
from nirl_mj.inspect.text import phi_text

_CYCLE = re.compile(r"in a cycle of \d+ \(([^)]*)\).*states: (.*)$")


def cycle_pairs(text: str) -> Counter:
    """(state text, action name) -> how many cycles (of the file's timeouts) pass through the pair."""
    pairs: Counter = Counter()
    for line in text.splitlines():
        match = _CYCLE.search(line)
        if not match:
            continue
        actions = [a.strip() for a in match.group(1).split(",")]
        states = [s.strip() for s in match.group(2).split(";")]
        if len(actions) != len(states):
            raise ValueError(f"a cycle of {len(actions)} actions lists {len(states)} states: {line[:80]}")
        pairs.update(set(zip(states, actions, strict=True)))
    return pairs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("timeouts", help="a file written by docs/scripts/timeouts.py")
    parser.add_argument("demos", help="the run's demonstrations (.npz)")
    args = parser.parse_args()
    try:
        with open(args.timeouts, encoding="utf-8") as f:
            pairs = cycle_pairs(f.read())
        trajectories = load_dataset(args.demos)
    except (OSError, ValueError) as exc:  # a missing file, a malformed cycle line or dataset
        raise SystemExit(str(exc)) from None
    if not pairs:
        raise SystemExit(f"{args.timeouts}: no cycle found (expected lines of docs/scripts/timeouts.py)")
    try:
        require_discrete(trajectories, args.demos)
    except ValueError as exc:
        raise SystemExit(str(exc)) from None
    phi, actions = stack_pairs(trajectories)
    shown: dict[str, Counter] = {}
    for row, action in zip(phi, actions, strict=True):
        shown.setdefault(phi_text(row), Counter())[ACTION_NAMES[int(action)]] += 1
    print(f"{args.demos}: {len(actions)} demonstrated pairs; the cycles of {args.timeouts}:")
    demonstrated = agreeing = 0
    for (state, action), cycles in sorted(pairs.items(), key=lambda kv: (-kv[1], kv[0])):
        expert = shown.get(state, Counter())
        seen = ", ".join(f"{a} {n}" for a, n in expert.most_common()) or "never demonstrated"
        print(f"  {state}: policy {action} (in {cycles} cycles); expert: {seen}")
        demonstrated += bool(expert)
        # a tie among the expert's most frequent actions counts as agreeing with any of them
        agreeing += bool(expert) and expert[action] == max(expert.values())
    print(
        f"{len(pairs)} (state, action) pairs in the cycles: {demonstrated} in demonstrated states, "
        f"{agreeing} of those the expert's most frequent action there (or one of those tied)"
    )


if __name__ == "__main__":
    main()
