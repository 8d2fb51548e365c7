"""RE-IRL's per-state reward on an experiment's demonstrations, for several L1 widths.

    python docs/scripts/re_widths.py OUT
    (OUT: a compare experiment's --out, for its demos.npz)

In the per-state reading (``re_expectations = "state"``, Table I's RE row) the learner's rollouts
drop out of RE's dual (learn/reirl.py), so its reward can be computed from the demonstrations alone:
the same ascent as a 60-iteration run (30 proximal steps per iteration, warm-started), at
- the default widths: Hoeffding's bound with N_T = 30 demonstrations (``re_confidence = 0.95``);
- the same bound over the demonstrated pairs instead (N = 3,583 in Table I), 11 times narrower;
- no L1 term (``re_confidence = 0``, the ``RE-noL1`` row of tasks/ablations/re_l1.toml).
Prints, for each, the widest epsilon_i, the non-zero components of theta and the largest ones.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

from nirl_mj.data.dataset import load_dataset
from nirl_mj.learn.config import LearnerConfig
from nirl_mj.learn.reirl import RelativeEntropyStep, hoeffding_widths
from nirl_mj.learn.reward import RewardModel

ITERATIONS = 60  # the default loop's iterations; re_steps ascent steps each


def main(out: Path) -> None:
    demos = load_dataset(out / "demos.npz")
    config = LearnerConfig.preset("default", method="re")
    loop, own = config.loop, config.steps["re"]
    pairs = sum(len(d) for d in demos)
    for label, confidence, count in (
        ("default: N_T = 30 demonstrations", own.re_confidence, None),
        (f"N = {pairs} demonstrated pairs", own.re_confidence, pairs),
        ("no L1 term (re_confidence = 0)", 0.0, None),
    ):
        step = RelativeEntropyStep(loop, dataclasses.replace(own, re_confidence=confidence), demos)
        if count is not None:
            spread = step.per_action.max(axis=(0, 1)) - step.per_action.min(axis=(0, 1))
            step.eps = hoeffding_widths(spread, count, loop.gamma, 1, confidence)
        theta = np.zeros(step.dim)
        for iteration in range(ITERATIONS):
            theta, _ = step.update(theta, [], iteration, None)
        named = RewardModel(theta, loop.reward_features).named()
        used = sorted(((k, v) for k, v in named.items() if abs(v) > 1e-9), key=lambda kv: -abs(kv[1]))
        print(
            f"{label}: widest epsilon {step.eps.max():.3f}, {len(used)} of {len(named)} components "
            "non-zero: " + ", ".join(f"{k} {v:+.2f}" for k, v in used[:4])
        )


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    main(Path(sys.argv[1]))
