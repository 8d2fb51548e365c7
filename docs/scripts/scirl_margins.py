"""SCIRL's step 3 on one set of demonstrations: J, and how often the fitted reward's greedy action
is the expert's, for a few discounts and step counts (docs/notebook/algorithm.md, "SCIRL's
discount").

    nirl-mj demos --episodes 30 --expert sensor --seed 777 --out demos.npz
    python docs/scripts/scirl_margins.py demos.npz [--gammas 0.9 0.65] [--steps 40 400 2000]

Per row: J at the kept theta (0: every demonstrated pair meets its margin), the balanced accuracy
(mean per-action recall) of argmax_a r_theta(s, a) on the demonstrated pairs, and that of SCIRL's
own scores argmax_a theta^T mu_hat(s, a).
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from nirl_mj.data.dataset import load_dataset
from nirl_mj.data.trajectory import stack_pairs
from nirl_mj.learn.config import LoopConfig, ScirlConfig
from nirl_mj.learn.mmp import discounted_suffix_sums
from nirl_mj.learn.reward import RewardModel, all_action_features, trajectory_pair_features
from nirl_mj.learn.scirl import ScirlStep, heuristic_expectations


def balanced_accuracy(predicted: np.ndarray, actions: np.ndarray) -> float:
    """Mean over the demonstrated actions of the share of their pairs predicted as that action."""
    return float(np.mean([np.mean(predicted[actions == a] == a) for a in np.unique(actions)]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("demos")
    parser.add_argument("--gammas", type=float, nargs="+", default=[0.9, 0.65])
    parser.add_argument("--steps", type=int, nargs="+", default=[40, 400, 2000])
    args = parser.parse_args()
    demos = load_dataset(args.demos)
    phi, actions = stack_pairs(demos)
    loop = LoopConfig(method="scirl")
    print("gamma  steps  J       reward-greedy  scores")
    for gamma in args.gammas:
        loop = dataclasses.replace(loop, gamma=gamma)
        fs = trajectory_pair_features(demos, loop.reward_features)
        mu_taken = np.concatenate([discounted_suffix_sums(f, gamma) for f in fs])
        f_all = all_action_features(phi, loop.reward_features)
        mu_all = heuristic_expectations(mu_taken, f_all, actions, gamma)
        for steps in args.steps:
            theta, j = ScirlStep(loop, ScirlConfig(scirl_steps=steps), demos).fit()
            greedy = RewardModel(theta, loop.reward_features).rewards_all_actions(phi).argmax(axis=1)
            scores = (mu_all @ theta).argmax(axis=1)
            print(f"{gamma:<6} {steps:<6} {j:.4f}  {balanced_accuracy(greedy, actions):.3f}"
                  f"          {balanced_accuracy(scores, actions):.3f}")  # fmt: skip


if __name__ == "__main__":
    main()
