"""How a run's timeouts end: the cycle of actions each timed-out test episode repeats at its end.

A greedy policy on phi(s) has no memory, so a timeout can be a limit cycle (forward, backward,
forward, ... in front of an obstacle; a turn repeated on a circle near the target). This evaluates a
run's policy on its held-out test arenas (as ``nirl-mj eval``, nothing written) and prints the
outcome rates, then for each timeout the cycle it ends in (``nirl_mj.data.cycles.final_cycle``), how
many decisions it lasts, how far (metres) the robot's positions over it stray from their mean, the
states of its last period (D levels of S1-S4 and S7-S9, V, I, wall flags U) and, for a run with a
learned reward, the mean r_theta(s, a) per decision over the cycle; then the count of timeouts by
cycle (a cycle met at another phase counts as the same), and r_theta per decision over the episodes
that reached the target, to set the cycles' beside.

    python docs/scripts/timeouts.py RUN [--tests 10] [--seed 0] [--which selected]
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter

import numpy as np

from nirl_mj.data.cycles import final_cycle
from nirl_mj.data.features import ACTION_NAMES
from nirl_mj.data.rundir import RunError
from nirl_mj.data.trajectory import Trajectory
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.subjects import run_subject
from nirl_mj.inspect.text import phi_text
from nirl_mj.sim.task import make_env


def lowest_rotation(actions: tuple[int, ...]) -> tuple[int, ...]:
    """The smallest of a cycle's rotations, so one cycle met at different phases is named once."""
    return min(actions[i:] + actions[:i] for i in range(len(actions)))


def reward_per_decision(reward, t: Trajectory, last: int | None = None) -> float:
    """Mean r_theta(s_t, a_t) over an episode's decisions, or over its ``last`` ones."""
    n = len(t.actions) if last is None else last
    start = len(t.actions) - n
    return float(np.mean(reward.reward(t.features[start : start + n], t.actions[start:])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="run directory (nirl-mj train, or a suite's or compare's run)")
    parser.add_argument("--tests", type=int, default=10, help="test arenas (default 10)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the test arenas (as for eval)")
    parser.add_argument("--which", default="selected", help="selected, last or an iteration number")
    args = parser.parse_args()
    if args.tests < 1:
        sys.exit(f"error: --tests {args.tests}: expected at least 1")
    try:
        subject = run_subject(args.run, args.which, None)
    except (RunError, FileNotFoundError, ValueError) as e:
        sys.exit(f"error: {e}")
    reward = subject.reward()
    env = make_env(subject.task)
    metrics, trajectories = evaluate(
        env, subject.policy, subject.test_seeds(args.seed, args.tests), subject.name
    )
    print(
        f"{args.run} ({args.which}): success {metrics['success_rate']:.0%}, collision "
        f"{metrics['collision_rate']:.0%}, timeout {metrics['timeout_rate']:.0%} over {args.tests} arenas"
    )
    kinds: Counter[str] = Counter()
    for i, t in enumerate(trajectories):
        if t.outcome != "timeout":
            continue
        cycle = final_cycle(t)
        if cycle is None:
            kinds["no cycle"] += 1
            why = "continuous actions" if np.ndim(t.actions) == 2 else "no period <= 12 repeats over 24"
            print(f"arena {i}: timeout, no cycle ({why})")
            continue
        names = ", ".join(ACTION_NAMES[a] for a in cycle.actions)
        kinds[", ".join(ACTION_NAMES[a] for a in lowest_rotation(cycle.actions))] += 1
        states = "; ".join(phi_text(phi) for phi in cycle.states)
        paid = (
            ""
            if reward is None
            else f", r_theta {reward_per_decision(reward, t, cycle.length):+.3f} per decision"
        )
        print(f"arena {i}: timeout in a cycle of {cycle.period} ({names}) over its last {cycle.length} "
              f"decisions, within {cycle.radius:.1f} m{paid}; states: {states}")  # fmt: skip
    for names, n in kinds.most_common():
        print(f"{n} timeout(s): {names}")
    arrived = [t for t in trajectories if t.outcome == "target"]
    if reward is not None and arrived:
        per = [reward_per_decision(reward, t) for t in arrived]
        print(f"episodes that reached the target ({len(arrived)}): r_theta {np.mean(per):+.3f} per decision "
              f"(from {min(per):+.3f} to {max(per):+.3f})")  # fmt: skip


if __name__ == "__main__":
    main()
