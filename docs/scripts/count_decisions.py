"""How many environment decisions one training run of an IRL method of a compare experiment spends.

The Stable-Baselines3 rows (PPO-reward, GAIL, AIRL) train for a fixed number of decisions
(``method.NAME.steps``); NIRL and the other IRL rows train for a number of iterations, each driving
``trajectories_per_episode`` rollouts, and drive validation episodes to pick their policy. To give
the two kinds the same budget, this script retrains run R of METHOD exactly as the experiment does
(same demonstrations, configuration and seed, in a temporary directory) and counts the decisions of
every episode it drives: the training rollouts, and the validation and selection episodes.

    python docs/scripts/count_decisions.py OUT [RUN ...] [--method NIRL] [--task tasks/table1.toml]
    (OUT: the experiment's --out, for its demonstrations; default run 0)

The count hooks ``run_episode`` where the ``cpu`` backend's rollouts call it
(``nirl_mj.sim.rollouts``), and counts an episode as validation while training's ``evaluate`` runs
(validation and selection); nothing else changes, so the run trains as in the experiment (it is not
kept). Where OUT holds the run, the retrained run's policy selection must equal the stored one's,
or the script stops: the count is of the same run.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import nirl_mj.experiments.training as training
import nirl_mj.sim.rollouts as rollouts
from nirl_mj.experiments.definition import load_experiment
from nirl_mj.experiments.protocol import demos_path, run_jobs
from nirl_mj.learn.config import LearnerConfig


def counting(counts: dict[str, int]) -> None:
    """Replaces the rollouts' ``run_episode`` by one that adds each episode's decisions to
    ``counts["training"]``, or ``counts["validation"]`` while training's ``evaluate`` runs."""
    original, evaluate, phase = rollouts.run_episode, training.evaluate, ["training"]

    def run_episode(env, agent, seed, on_step=None):
        trajectory = original(env, agent, seed, on_step)
        counts[phase[0]] += len(trajectory.actions)
        counts[phase[0] + " episodes"] += 1
        return trajectory

    def validating(*args, **kwargs):
        phase[0] = "validation"
        try:
            return evaluate(*args, **kwargs)
        finally:
            phase[0] = "training"

    rollouts.run_episode, training.evaluate = run_episode, validating


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out", type=Path, help="the compare experiment's --out (its demonstrations)")
    parser.add_argument("runs", type=int, nargs="*", default=[0])
    parser.add_argument("--method", default="NIRL")
    parser.add_argument("--task", default="tasks/table1.toml")
    args = parser.parse_args()
    experiment = load_experiment(args.task)
    jobs = run_jobs(experiment, args.out, {r: demos_path(args.out, experiment, r) for r in args.runs})
    counts: dict[str, int] = {}
    counting(counts)
    for run in args.runs:
        job = jobs[(args.method, run)]
        if job.method.kind != "irl":
            kind = job.method.kind
            raise SystemExit(f"{args.method} is not an IRL method (kind {kind!r}): nothing to count")
        counts.update(
            dict.fromkeys(["training", "training episodes", "validation", "validation episodes"], 0)
        )
        with tempfile.TemporaryDirectory() as tmp:
            config = LearnerConfig.from_dict(job.config)
            record = training.train(Path(tmp) / "run", job.task, job.demos_path, config, seed=job.seed)
        stored = Path(job.run_dir) / "run.json"
        if stored.is_file() and json.loads(stored.read_text())["selection"] != record["selection"]:
            raise SystemExit(f"run {run} retrained differently from {stored}: not the experiment's run")
        total = counts["training"] + counts["validation"]
        print(f"{args.method} run {run}: {total} decisions: {counts['training']} in "
              f"{counts['training episodes']} training rollouts, {counts['validation']} in "
              f"{counts['validation episodes']} validation and selection episodes")  # fmt: skip


if __name__ == "__main__":
    main()
