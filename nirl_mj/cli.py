"""The ``nirl-mj`` command: parse arguments, call the library, print. Nothing imports this."""

from __future__ import annotations

import argparse
import json
import sys

from tqdm import tqdm


def _cmd_run(args: argparse.Namespace) -> int:
    from nirl_mj.policies import POLICIES
    from nirl_mj.rollout import run_episodes, summarise
    from nirl_mj.task import make_env

    env = make_env(args.task, seed=args.seed)
    spec = env.task.spec
    print(
        f"task {spec.name}: {spec.arena.static_obstacles} static + {spec.arena.moving_obstacles} moving "
        f"obstacles, {spec.control.speed} m/s, {spec.robot.drive} drive; policy {args.policy}; "
        f"{args.episodes} episodes, seed {args.seed}",
        file=sys.stderr,
    )
    results = []
    bar = tqdm(total=args.episodes, unit="episode", file=sys.stderr, disable=args.quiet)
    for result in run_episodes(env, POLICIES[args.policy], args.seed, args.episodes):
        results.append(result)
        bar.update()
        bar.write(
            f"episode {result.episode:3d}  seed {result.seed:10d}  {result.outcome:13s} "
            f"steps {result.steps:4d}  path {result.path_length:6.1f} m  "
            f"to target {result.final_distance:6.1f} m",
            file=sys.stdout,
        )
    bar.close()
    summary = summarise(results)
    print(
        f"success {summary['success_rate']:.0%}  collision {summary['collision_rate']:.0%}  "
        f"timeout {summary['timeout_rate']:.0%}  diverged {summary['physics_error_rate']:.0%}  "
        f"mean steps {summary['mean_steps']:.1f}"
    )
    if args.json:
        print(json.dumps({**summary, "task": spec.name, "policy": args.policy, "seed": args.seed}))
    return 0


def _cmd_task(args: argparse.Namespace) -> int:
    from nirl_mj.spec import load_task

    spec = load_task(args.task)
    print(json.dumps({**spec.to_dict(), "step_budget": spec.step_budget}, indent=2))
    return 0


def build_parser() -> argparse.ArgumentParser:
    from nirl_mj.policies import POLICIES

    parser = argparse.ArgumentParser(prog="nirl-mj", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    run = sub.add_parser(
        "run",
        help="the main job: roll out a policy on a task and print each episode's outcome",
        description="Rolls out a reference policy on fresh seeded arenas and prints each episode's "
        "outcome and a summary. (NIRL training joins this job when the learner lands.)",
    )
    run.add_argument("--task", default="navigate", help="task name under tasks/ or a .toml path")
    run.add_argument("--episodes", type=_positive_int, default=10)
    run.add_argument("--seed", type=int, default=0)
    run.add_argument("--policy", choices=sorted(POLICIES), default="rule")
    run.add_argument("--json", action="store_true", help="print a JSON summary as the last line")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=_cmd_run)

    task = sub.add_parser("task", help="validate a task file and print the resolved spec as JSON")
    task.add_argument("task", help="task name under tasks/ or a .toml path")
    task.set_defaults(func=_cmd_task)
    return parser


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {text}")
    return value


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``nirl-mj`` console script; returns the exit status."""
    args = build_parser().parse_args(argv)
    from nirl_mj.layout import ArenaGenerationError
    from nirl_mj.spec import SpecError

    try:
        return args.func(args)
    except (SpecError, ArenaGenerationError, FileNotFoundError) as exc:
        print(f"nirl-mj {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"nirl-mj {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
