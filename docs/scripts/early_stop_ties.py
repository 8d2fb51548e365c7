"""Where early stopping had tied scores: trains runs of a compare experiment's BC or DAgger row again
(as ``nirl-mj compare`` does, from OUT's demonstrations) and prints, per run, its success on the
run's test arenas and every fit (DAgger: one per round) whose best held-out score was reached at
more than one epoch: the first such epoch (the rule before commit 6c30c7d) and the latest (today's,
``nirl_mj.learn.selection``). Writes nothing; about 1 (BC) to 3 (DAgger) core-minutes per run.

    python docs/scripts/early_stop_ties.py TASK OUT METHOD RUN [RUN ...]
    (e.g. tasks/table1.toml runs/table1_fair DAgger 0 2)
"""

from __future__ import annotations

import argparse
from pathlib import Path

from nirl_mj.experiments import protocol
from nirl_mj.experiments.definition import ExperimentError, load_experiment
from nirl_mj.learn import bc


def tied_fits(scores_of_fits: list[list[float]]) -> list[tuple[int, int, int]]:
    """(fit index, first best epoch, latest best epoch), epochs counted from 1, of each fit whose
    best score was reached more than once."""
    tied = []
    for i, scores in enumerate(scores_of_fits):
        best = max(scores)
        epochs = [e + 1 for e, s in enumerate(scores) if s == best]
        if len(epochs) > 1:
            tied.append((i, epochs[0], epochs[-1]))
    return tied


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task", type=Path)
    parser.add_argument("out", type=Path, help="the experiment's output directory (its demonstrations)")
    parser.add_argument("method", help="a method of kind bc or dagger")
    parser.add_argument("runs", type=int, nargs="+")
    args = parser.parse_args()
    try:
        experiment = load_experiment(args.task, kind="compare")
    except ExperimentError as exc:
        parser.exit(2, f"early_stop_ties: {exc}\n")
    kinds = {m.name: m.kind for m in experiment.methods}
    if kinds.get(args.method) not in ("bc", "dagger"):
        parser.exit(2, f"early_stop_ties: {args.method!r} is not a BC or DAgger method of {experiment.name} "
                       f"(its methods: {', '.join(kinds)})\n")  # fmt: skip
    fits: list[list[float]] = []
    early_stopped = bc.early_stopped

    def recorded(*a, **k):
        net, epochs, scores = early_stopped(*a, **k)
        fits.append(list(scores))
        return net, epochs, scores

    bc.early_stopped = recorded  # DAgger's rounds call it through the module too
    for run in args.runs:
        fits.clear()
        demos = protocol.demos_path(args.out, experiment, run)
        if not demos.exists():
            parser.exit(2, f"early_stop_ties: {demos} missing: run nirl-mj compare into {args.out} first\n")
        job = protocol.run_jobs(experiment, args.out, {run: demos})[args.method, run]
        metrics = protocol.evaluate_policy(protocol.policy_of(job), experiment.test_task, job.test_seeds,
                                           args.method)  # fmt: skip
        tied = ", ".join(f"fit {i}: epochs {a} and {b}" for i, a, b in tied_fits(fits)) or "none"
        print(f"{args.method} run {run}: success {100 * metrics['success_rate']:.0f} %, {len(fits)} fits, "
              f"tied best scores: {tied}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
