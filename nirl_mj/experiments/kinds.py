"""Method kinds: how each kind of method trains, and what it hands the protocol.

Every kind is one function ``train(job, train) -> Trained``: the job
(``nirl_mj.experiments.protocol.RunJob``: the method's settings, its run's demonstrations, seed and
run directory) in; a policy and every arena seed its training drove or read out. The protocol
(:func:`nirl_mj.experiments.protocol.policy_of`) treats every kind alike: it checks the seen arenas
against the run's test arenas and tests the policy. A method from another package
(``kind = "plugin"``, ``nirl_mj.experiments.plugins``) is one more entry of :data:`KINDS`.
``train=False`` (a sweep's tests) loads an IRL run, which must have finished, and an RL run's saved
model as it is; the kinds that keep no run to load (BC, DAgger, a plugin) train as with ``True``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nirl_mj.experiments.definition import ExperimentError


@dataclass(frozen=True)
class Trained:
    """A trained method: ``policy(phi) -> action`` (for ``kind = "expert"`` an Agent reading the whole
    observation) and ``seen``, every arena seed its training drove or read."""

    policy: Any
    seen: frozenset[int] = frozenset()


def read_finished(run_dir: str | Path) -> dict:
    """The record of a finished training run; a clear error if it has not finished."""
    from nirl_mj.data.rundir import RunDir

    run = RunDir(run_dir)
    record = run.read_record() if run.is_run else {}
    if "train_seeds" not in record:
        raise ExperimentError(f"{run_dir}: its training has not finished; rerun the experiment to train it")
    return record


def ensure_trained(job) -> dict:
    """Trains the job's IRL run, resumes it from its checkpoint, or leaves a finished one; returns its
    record (``nirl_mj.experiments.training.ensure_trained``)."""
    from nirl_mj.experiments.training import ensure_trained as ensure_run
    from nirl_mj.learn.config import LearnerConfig

    # a run shared by two methods' jobs (protocol.training_owners) may be training in the other's cell
    # now, whichever started first: its lock is waited for (any other holder is refused at once)
    return ensure_run(job.run_dir, job.task, job.demos_path, LearnerConfig.from_dict(job.config), job.seed,
                      wait=job.shared_run)  # fmt: skip


def _irl(job, train: bool) -> Trained:
    from nirl_mj.experiments.seeds import seen_seeds
    from nirl_mj.experiments.training import load_policy

    record = ensure_trained(job) if train else read_finished(job.run_dir)
    policy, _ = load_policy(job.run_dir, job.policy)
    return Trained(policy, frozenset(seen_seeds(record)))


def _rl(job, train: bool) -> Trained:
    from nirl_mj.experiments.rl import ADVERSARIAL, ensure_rl_trained, load_rl_policy
    from nirl_mj.experiments.seeds import seen_seeds

    m = job.method
    if train:
        demos = job.demos_path if m.algo in ADVERSARIAL else None
        ensure_rl_trained(job.run_dir, job.task, m.algo, m.steps, job.seed, demos, m.selection, m.envs,
                          m.settings, m.train_drive)  # fmt: skip
    policy, record = load_rl_policy(job.run_dir, shares=True)
    return Trained(policy, frozenset(seen_seeds(record)))


def _dagger(job, train: bool) -> Trained:
    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.data.trajectory import require_discrete
    from nirl_mj.experiments.dagger import DaggerConfig, train_dagger
    from nirl_mj.learn.bc import CloneSettings

    settings = CloneSettings.of(job.method.variant)
    demos = load_dataset(job.demos_path)
    require_discrete(demos, str(job.demos_path))
    config = DaggerConfig.of(job.method.settings)
    policy, arenas = train_dagger(job.task, demos, job.seed, job.expert, config, settings=settings)
    return Trained(policy, frozenset(arenas))


def _bc(job, train: bool) -> Trained:
    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.data.trajectory import require_discrete
    from nirl_mj.learn.bc import CloneSettings, behaviour_cloning

    settings = CloneSettings.of(job.method.variant)
    demos = load_dataset(job.demos_path)
    require_discrete(demos, str(job.demos_path))
    return Trained(behaviour_cloning(demos, seed=job.seed, settings=settings))


def _expert(job, train: bool) -> Trained:
    from nirl_mj.experiments.demos import ExpertConfig

    return Trained(ExpertConfig.named(job.expert, job.seed).build())


def _reference(job, train: bool) -> Trained:
    from nirl_mj.experts.policies import always_forward, rule_policy

    return Trained({"forward": always_forward, "rule": rule_policy}[job.method.kind])


def _plugin(job, train: bool) -> Trained:
    from nirl_mj.experiments.plugins import train_plugin

    policy, seen = train_plugin(job)
    return Trained(policy, frozenset(seen))


KINDS: dict[str, Callable[[Any, bool], Trained]] = {
    "irl": _irl,
    "bc": _bc,
    "dagger": _dagger,
    "forward": _reference,
    "rule": _reference,
    "rl": _rl,
    "expert": _expert,
    "plugin": _plugin,
}
"""Every method kind (``definition.METHOD_KINDS``) and how it trains."""

PACKAGES: dict[str, tuple[str, ...]] = {"rl": ("gymnasium", "stable_baselines3")}
"""The optional extra's packages a kind needs (nirl-mj[gym]); the others need none, or (an installed
method) only if they drive the robot."""


def missing_packages(kind: str) -> list[str]:
    """The packages method kind ``kind`` needs that are not installed."""
    import importlib.util

    return [p for p in PACKAGES.get(kind, ()) if importlib.util.find_spec(p) is None]
