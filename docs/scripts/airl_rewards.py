"""What AIRL's (or GAIL's) policy is paid per decision: its reward on its own and the expert's pairs.

AIRL's policy reward is the discriminator's logit l = f(s, a, s') - ln pi(a | s), with
f = g(s, a) + gamma h(s') - h(s) and h(s') = 0 after a terminal state (a collision or an arrival).
If l is mostly negative on the learner's own pairs, a shorter episode earns more: ending it with a
collision is rewarded (the termination bias of adversarial imitation with terminal states; Kostrikov
et al. 2019). This script measures that on a trained AIRL run of a compare experiment.

    python docs/scripts/airl_rewards.py OUT [RUN ...] [--method AIRL-absorbing]
    (OUT: the experiment's --out; default run 0, whose seed names its run directory and, with
    demonstrations drawn per run, its OUT/demos/runNNN.npz; --method: the row, default AIRL)

GAIL's reward is softplus of the logit, always positive. Prints, per run: the mean reward per
decision on 20 of its own training-arena episodes (sampled actions, as trained) and on the
experiment's demonstrations, the share of negative rewards, and the outcomes of those episodes.
With an absorbing state ("-absorbing" algos), also the reward at s_a and what a terminal step gains
from it, gamma / (1 - gamma) times that reward. With "-norm", also the running mean and standard
deviation the rewards were normalised by at the end of training, and both means normalised.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
from stable_baselines3 import PPO

from nirl_mj.data.dataset import load_dataset
from nirl_mj.data.rundir import RunDir
from nirl_mj.data.transitions import Transitions
from nirl_mj.experiments.adversarial import AdversarialReward, expert_transitions, read_discriminator
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.rl import load_rl_policy, observation_code
from nirl_mj.experiments.seeds import domain_seeds
from nirl_mj.sim import spec as specs
from nirl_mj.sim.task import make_env


def rewards_of(reward: AdversarialReward, trajectories, code) -> np.ndarray:
    """The policy's reward per decision (AIRL's is the logit; GAIL's softplus of it); ``code``: phi(s)
    -> the run's observation."""
    logits = reward.logits(expert_transitions(trajectories, code))
    return reward.discriminator.policy_reward(logits).detach().numpy()


def main(out: Path, runs: list[int], method: str = "AIRL") -> None:
    for r in runs:
        # demonstrations drawn per run (OUT/demos/runNNN.npz), or one set for every run (OUT/demos.npz)
        shared = out / "demos.npz"
        demos = load_dataset(shared if shared.is_file() else out / "demos" / f"run{r:03d}.npz")
        run_dir = out / "runs" / method / str(r)
        record = RunDir(run_dir).read_record()
        policy, _ = load_rl_policy(run_dir, seed=r)
        model = PPO.load(RunDir(run_dir).model_file(), device="cpu")
        gamma = float(record["config"]["gamma"])
        code, _ = observation_code(record["config"])
        reward = AdversarialReward(record["algo"], gamma, expert_transitions(demos, code), seed=0)
        reward.load_state(read_discriminator(RunDir(run_dir)))
        reward.policy = model.policy
        env = make_env(specs.from_dict(record["task"]))
        metrics, episodes = evaluate(env, policy, domain_seeds("train", r, 20))
        with torch.no_grad():
            own, expert = rewards_of(reward, episodes, code), rewards_of(reward, demos, code)
        lengths = [len(t) for t in episodes]
        own_part = f"mean reward {own.mean():+.2f} per decision, {100 * (own < 0).mean():.0f} % negative"
        success, collision = 100 * metrics["success_rate"], 100 * metrics["collision_rate"]
        outcomes = f"success {success:.0f} %, collision {collision:.0f} %"
        demo_part = f"mean reward {expert.mean():+.2f}, {100 * (expert < 0).mean():.0f} % negative"
        extra = ""
        if reward.absorbing:
            with torch.no_grad():
                stay = reward.logits(Transitions.absorbing_pairs(1, reward.width))
                at = float(reward.discriminator.policy_reward(stay)[0])
            tail = gamma / (1 - gamma) * at
            extra = f" | s_a: reward {at:+.2f} per step, {tail:+.1f} to a terminal step"
        if reward.norm is not None:  # what PPO was paid at the end of training: (r - mean) / std
            norm = reward.norm
            scale = np.sqrt(norm.var + norm.eps)
            extra += (f" | normalised (mean {norm.mean:+.2f}, std {scale:.2f}): own "
                          f"{(own.mean() - norm.mean) / scale:+.2f}, demonstrations "
                          f"{(expert.mean() - norm.mean) / scale:+.2f}")  # fmt: skip
        print(f"run {r}: own pairs: {own_part}, {np.mean(lengths):.0f} decisions per episode, {outcomes} "
              f"| demonstrations: {demo_part}{extra}")  # fmt: skip


if __name__ == "__main__":
    args = sys.argv[1:]
    name = "AIRL"
    if "--method" in args:
        at = args.index("--method")
        name = args[at + 1]
        del args[at : at + 2]
    main(Path(args[0]), [int(x) for x in args[1:]] or [0], name)
