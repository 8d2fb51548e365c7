"""What a held-out test or a rendering shows: a trained run's policy or a reference policy.

A :class:`Subject` carries the policy on phi(s), the task it is tested on and the
arenas it has seen (which held-out tests skip: ``seeds.held_out_seeds``). ``eval``
and ``render`` number their test arenas alike, so ``render --episode i`` shows the
episode of ``eval``'s i-th test.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nirl_mj.data.dataset import load_dataset
from nirl_mj.data.rundir import POLICIES as RUN_POLICIES
from nirl_mj.data.rundir import RUN_FILE, RunDir, RunError
from nirl_mj.data.trajectory import require_discrete
from nirl_mj.experiments.seeds import held_out_seeds, seen_seeds
from nirl_mj.experiments.training import load_policy
from nirl_mj.experts.policies import POLICIES
from nirl_mj.learn.bc import behaviour_cloning
from nirl_mj.learn.reward import RewardModel
from nirl_mj.sim import spec as specs

REFERENCES = (*sorted(POLICIES), "bc")
"""Reference policies by name: always forward, the rule on phi(s), behaviour cloning of demonstrations."""


@dataclass(frozen=True)
class Subject:
    """A policy to test: ``name`` is recorded as the agent of its episodes."""

    policy: Callable[[np.ndarray], int]
    name: str
    task: specs.TaskSpec
    seen: frozenset[int] = field(default_factory=frozenset)
    run: RunDir | None = None

    def test_seeds(self, seed: int, count: int) -> list[int]:
        """The first ``count`` held-out test arenas of ``seed`` for this subject."""
        return held_out_seeds(seed, count, set(self.seen))

    def reward(self) -> RewardModel | None:
        """A trained run's selected reward (an AIRL run's: its g(s, a)); None for a reference policy."""
        if self.run is None:
            return None
        record = self.run.read_record()
        if record.get("kind") == "rl" and str(record.get("algo")).startswith("airl"):
            from nirl_mj.experiments.adversarial import AirlReward

            return AirlReward(self.run.path, record["config"]["gamma"])
        if not self.run.has_reward:
            return None
        return RewardModel.from_dict(self.run.read_reward(), str(self.run.path))


def run_subject(run_dir: str | os.PathLike, which: str = "selected", task: str | None = None) -> Subject:
    """A trained run's policy (greedy; an RL run's as ``experiments.rl.load_rl_policy`` gives it;
    ``which``: selected, last or an iteration number; an RL run
    (``nirl-mj rl``) has its selected and last checkpoints only), on its own task unless ``task`` (a
    name or path) is given."""
    run = RunDir(run_dir)
    if run.read_record().get("kind") == "rl":  # a reinforcement-learning reference (nirl-mj rl)
        if which not in RUN_POLICIES:
            raise RunError(f"{run} is an RL run: --which takes {' or '.join(RUN_POLICIES)} (got {which!r})")
        from nirl_mj.experiments.rl import load_rl_policy  # needs the optional extra nirl-mj[gym]

        policy, record = load_rl_policy(run_dir, policy=which, shares=True)
        name = f"rl-{record['algo']}"
    else:
        (policy, record), name = load_policy(run_dir, which), "nirl"
    spec = specs.load_task(task) if task else specs.from_dict(record["task"], f"{run.file(RUN_FILE)}: task")
    return Subject(policy, name, spec, frozenset(seen_seeds(record)), run)


def reference_subject(
    name: str, task: str | None = None, demos: str | os.PathLike | None = None, train_seed: int = 0
) -> Subject:
    """A reference policy of :data:`REFERENCES` on ``task`` (default: navigate); the arenas of
    ``demos`` are held out, and ``bc`` clones them (trained with ``train_seed``)."""
    if name not in REFERENCES:
        raise ValueError(f"unknown reference policy {name!r}; accepted: {', '.join(REFERENCES)}")
    trajectories = load_dataset(demos) if demos else []
    if name == "bc":
        if not trajectories:
            raise FileNotFoundError("the bc policy needs --demos (the demonstrations to clone)")
        require_discrete(trajectories, str(demos))
        policy = behaviour_cloning(trajectories, seed=train_seed)
    else:
        policy = POLICIES[name]
    seen = frozenset(t.arena_seed for t in trajectories)
    return Subject(policy, name, specs.load_task(task or "navigate"), seen)
