"""A trained NIRL run's last iterate, tested before and after more value-fitting rounds on its last
replay window: whether its values had converged where its tests end.

The run's checkpoint holds the last iteration's network, theta and replay window (the last
``replay_episodes`` iterations' pairs). This rebuilds the learner from it, tests the last iterate's
greedy policy on the run's held-out test arenas (as ``nirl-mj eval --which last``, nothing written),
then fits the replay window ``--rounds`` more times, eq. 14's targets computed again from the network
before each (the step's own fit, ``IrlLoop.fit_replay``; theta unchanged, no new rollout), and tests again
on the same arenas. A diagnostic: it changes no run.

    python docs/scripts/refit_last.py RUN DEMOS.npz [--rounds 5] [--tests 100] [--seed 0]
"""

from __future__ import annotations

import argparse
import sys

from nirl_mj.data.rundir import RunDir, RunError
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.subjects import run_subject
from nirl_mj.experiments.training import load_demonstrations, saved_settings
from nirl_mj.learn.loop import IrlLoop, greedy_policy
from nirl_mj.sim.task import make_env


def last_iterate(run: str, demos: str) -> IrlLoop:
    """The learner of ``run`` as its checkpoint left it (network, theta, replay window, draws)."""
    _, config, _, seed = saved_settings(run)
    # one fit per round here, whatever fit_rounds the run trained with (the step's own fit does that many)
    learner = IrlLoop(config.replace(fit_rounds=1), load_demonstrations(demos), seed)
    learner.load_state(RunDir(run).read_checkpoint())
    return learner


def refit(learner: IrlLoop, rounds: int) -> None:
    """``rounds`` more fits of the replay window, each on targets from the network as it then is."""
    for _ in range(rounds):
        learner.fit_replay()  # the loop's own step 4, without the rollouts and reward step around it


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="a NIRL run directory (nirl-mj train, or a compare's runs/NIRL/SEED)")
    parser.add_argument("demos", help="the demonstrations it was trained on (a compare's demos/runNNN.npz)")
    parser.add_argument("--rounds", type=int, default=5, help="further fitting rounds (default 5)")
    parser.add_argument("--tests", type=int, default=100, help="test arenas (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the test arenas (as for eval)")
    args = parser.parse_args()
    if args.rounds < 1 or args.tests < 1:
        sys.exit(f"error: --rounds {args.rounds}, --tests {args.tests}: expected at least 1 each")
    try:
        subject = run_subject(args.run, "last", None)
        learner = last_iterate(args.run, args.demos)
    except (RunError, FileNotFoundError, KeyError, ValueError) as e:
        sys.exit(f"error: {e}")
    env = make_env(subject.task)
    seeds = subject.test_seeds(args.seed, args.tests)
    for label, rounds in (("last iterate", 0), (f"after {args.rounds} more rounds", args.rounds)):
        refit(learner, rounds)
        metrics, _ = evaluate(env, greedy_policy(learner.net, learner.inputs), seeds, "nirl")
        print(
            f"{args.run} {label}: success {metrics['success_rate']:.0%}, collision "
            f"{metrics['collision_rate']:.0%}, timeout {metrics['timeout_rate']:.0%} over {args.tests} arenas"
        )


if __name__ == "__main__":
    main()
