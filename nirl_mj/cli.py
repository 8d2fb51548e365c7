"""The ``nirl-mj`` command: parse arguments, call the library, print. Nothing imports this."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from tqdm import tqdm

_OUTCOME_NAMES = ("success", "collision", "timeout", "physics_error")


def _print_summary(summary: dict) -> None:
    print(
        f"episodes {summary['episodes']}  success {summary['success_rate']:.0%}  "
        f"collision {summary['collision_rate']:.0%}  timeout {summary['timeout_rate']:.0%}  "
        f"diverged {summary['physics_error_rate']:.0%}  steps mean {summary['mean_steps']:.1f} "
        f"(min {summary['min_steps']}, max {summary['max_steps']})"
    )
    actions = "  ".join(f"{name} {frac:.1%}" for name, frac in summary["action_fractions"].items())
    print(f"actions ({summary['pairs']} pairs): {actions}")


def _print_predictability(trajectories: list) -> dict | None:
    from nirl_mj.predictability import predictability

    if len(trajectories) < 2:
        return None
    p = predictability(trajectories)
    print(
        f"predictability from phi(s) (class-weighted logistic regression, first half -> second half): "
        f"balanced accuracy {p['balanced_accuracy']:.2f}, accuracy {p['accuracy']:.2f} "
        f"(majority action alone: {p['majority_share']:.2f})"
    )
    return p


def _episode_line(trajectory) -> str:
    from nirl_mj.rollout import path_length

    return (
        f"seed {trajectory.arena_seed:10d}  {trajectory.outcome:13s} steps {len(trajectory):4d}  "
        f"path {path_length(trajectory):6.1f} m"
    )


def _cmd_run(args: argparse.Namespace) -> int:
    from nirl_mj.rollout import PolicyAgent, run_episodes
    from nirl_mj.spec import apply_overrides, load_task
    from nirl_mj.task import make_env
    from nirl_mj.trajectory import summarise

    env = make_env(apply_overrides(load_task(args.task), args.set))
    spec = env.task.spec
    print(
        f"task {spec.name}: {spec.arena.static_obstacles} static + {spec.arena.moving_obstacles} moving "
        f"obstacles, {spec.control.speed} m/s, {spec.robot.drive} drive; policy {args.policy}; "
        f"{args.episodes} episodes, seed {args.seed}",
        file=sys.stderr,
    )
    trajectories = []
    with tqdm(total=args.episodes, unit="episode", file=sys.stderr, disable=args.quiet) as bar:
        for i, trajectory in enumerate(
            run_episodes(env, PolicyAgent.named(args.policy), args.seed, args.episodes)
        ):
            trajectories.append(trajectory)
            bar.update()
            bar.write(f"episode {i:3d}  {_episode_line(trajectory)}", file=sys.stdout)
    summary = summarise(trajectories)
    _print_summary(summary)
    if args.json:
        print(json.dumps({**summary, "task": spec.name, "policy": args.policy, "seed": args.seed}))
    return 0


def _check_output(path: Path, overwrite: bool) -> None:
    """Fails before any work if ``path`` cannot be written or would overwrite results."""
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; pass --overwrite to replace it, or choose another --out")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise FileNotFoundError(f"cannot write {path}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise PermissionError(f"cannot write {path}: directory {parent} is not writable")


def _cmd_demos(args: argparse.Namespace) -> int:
    from nirl_mj.demos import ExpertConfig, collect, default_workers
    from nirl_mj.spec import apply_overrides, load_task
    from nirl_mj.trajectory import save_dataset, summarise

    out = Path(args.out)
    _check_output(out, args.overwrite)
    if args.rerun:
        _check_output(Path(args.rerun), args.overwrite)
    spec = apply_overrides(load_task(args.task), args.set)
    expert = ExpertConfig(args.expert, args.base, args.slip, args.random_action, args.seed)
    workers = args.workers or default_workers()
    print(
        f"demonstrations: {args.episodes} episodes of {spec.name} by the {args.expert} expert, "
        f"seed {args.seed}, {workers} worker(s)",
        file=sys.stderr,
    )
    with tqdm(total=args.episodes, unit="episode", file=sys.stderr, disable=args.quiet) as bar:

        def progress(trajectory) -> None:
            bar.update()
            bar.set_postfix_str(trajectory.outcome)

        trajectories = collect(spec, expert, args.episodes, args.seed, workers, progress)
    save_dataset(out, trajectories, overwrite=args.overwrite)
    summary = summarise(trajectories)
    _print_summary(summary)
    pred = _print_predictability(trajectories)
    print(f"wrote {out}")
    if args.rerun:
        from nirl_mj.record import record_demonstrations

        record_demonstrations(args.rerun, trajectories)
        print(f"wrote {args.rerun}")
    if args.json:
        print(json.dumps({**summary, "predictability": pred, "expert": args.expert, "out": str(out)}))
    return 0


def _cmd_inspect(args: argparse.Namespace) -> int:
    from nirl_mj.pretreat import map_pretreat
    from nirl_mj.trajectory import load_dataset, summarise

    trajectories = load_dataset(args.path)
    summary = summarise(trajectories)
    print(f"{args.path}: valid nirl-mj dataset")
    print(f"demonstrators {summary['demonstrators']}  speeds {summary['speeds']}  tasks {summary['tasks']}")
    _print_summary(summary)
    pred = _print_predictability(trajectories)
    _, report = map_pretreat(trajectories)
    print(
        f"MAP pretreatment (eq. 10, uniform prior) would relabel {report.pairs_changed} of "
        f"{report.pairs_total} pairs ({report.ambiguous_states} states seen with several actions)"
    )
    if args.json:
        print(json.dumps({**summary, "predictability": pred, "map_pairs_changed": report.pairs_changed}))
    return 0


def _cmd_teleop(args: argparse.Namespace) -> int:
    from nirl_mj.experts.teleop import __doc__ as keys_doc
    from nirl_mj.experts.teleop import teleoperate
    from nirl_mj.rollout import episode_seed
    from nirl_mj.task import make_env
    from nirl_mj.trajectory import save_dataset

    out = Path(args.out)
    _check_output(out, args.overwrite)
    env = make_env(args.task)
    print(keys_doc.split("\n\n", 2)[2], file=sys.stderr)
    trajectories = []

    def keep(trajectory) -> None:
        trajectories.append(trajectory)
        print(f"episode {len(trajectories)}: {_episode_line(trajectory)}")

    try:
        teleoperate(env, args.episodes, lambda i: episode_seed(args.seed, i), keep)
    except KeyboardInterrupt:
        print("interrupted: saving the finished episodes", file=sys.stderr)
    if not trajectories:
        print("no episode kept; nothing written", file=sys.stderr)
        return 1
    save_dataset(out, trajectories, overwrite=args.overwrite)
    print(f"wrote {len(trajectories)} human demonstrations to {out}")
    return 0


def _cmd_task(args: argparse.Namespace) -> int:
    from nirl_mj.spec import load_task

    spec = load_task(args.task)
    print(json.dumps({**spec.to_dict(), "step_budget": spec.step_budget}, indent=2))
    return 0


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text}")
    return value


def _probability(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a probability in [0, 1], got {text!r}") from None
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"expected a probability in [0, 1], got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    from nirl_mj.experts import EXPERT_KINDS
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
    run.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a task value, e.g. control.speed=3 (repeatable)")  # fmt: skip
    run.add_argument("--episodes", type=_positive_int, default=10)
    run.add_argument("--seed", type=int, default=0)
    run.add_argument("--policy", choices=sorted(POLICIES), default="rule")
    run.add_argument("--json", action="store_true", help="print a JSON summary as the last line")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=_cmd_run)

    demos = sub.add_parser("demos", help="record expert demonstrations to a dataset file")
    demos.add_argument("--task", default="navigate", help="task name under tasks/ or a .toml path")
    demos.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a task value, e.g. control.speed=3 (repeatable)")  # fmt: skip
    demos.add_argument("--episodes", type=_positive_int, default=30)
    demos.add_argument("--expert", choices=EXPERT_KINDS, default="sensor")
    demos.add_argument("--base", choices=[k for k in EXPERT_KINDS if k != "noisy"], default="sensor",
                       help="the expert a noisy expert perturbs")  # fmt: skip
    demos.add_argument("--slip", type=_probability, default=0.1, help="noisy: probability an action slips")
    demos.add_argument(
        "--random-action", type=_probability, default=0.05, help="noisy: probability of a random action"
    )
    demos.add_argument("--seed", type=int, default=0)
    demos.add_argument("--out", required=True, help="dataset path (.npz)")
    demos.add_argument("--overwrite", action="store_true", help="replace an existing --out / --rerun file")
    demos.add_argument("--workers", type=_positive_int, default=None, help="processes (default: all cores)")
    demos.add_argument(
        "--rerun", default=None, help="also write a Rerun recording (.rrd) of the demonstrations"
    )
    demos.add_argument("--json", action="store_true", help="print a JSON summary as the last line")
    demos.add_argument("--quiet", action="store_true", help="no progress bar")
    demos.set_defaults(func=_cmd_demos)

    teleop = sub.add_parser(
        "teleop", help="drive the robot from the keyboard in MuJoCo's viewer and record the episodes"
    )
    teleop.add_argument("--task", default="navigate", help="task name under tasks/ or a .toml path")
    teleop.add_argument("--episodes", type=_positive_int, default=30)
    teleop.add_argument("--seed", type=int, default=0)
    teleop.add_argument("--out", required=True, help="dataset path (.npz)")
    teleop.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    teleop.set_defaults(func=_cmd_teleop)

    inspect = sub.add_parser("inspect", help="validate a dataset file and print its summary")
    inspect.add_argument("path")
    inspect.add_argument("--json", action="store_true", help="print a JSON summary as the last line")
    inspect.set_defaults(func=_cmd_inspect)

    task = sub.add_parser("task", help="validate a task file and print the resolved spec as JSON")
    task.add_argument("task", help="task name under tasks/ or a .toml path")
    task.set_defaults(func=_cmd_task)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``nirl-mj`` console script; returns the exit status."""
    args = build_parser().parse_args(argv)
    from nirl_mj.layout import ArenaGenerationError
    from nirl_mj.spec import SpecError
    from nirl_mj.trajectory import DatasetError

    try:
        return args.func(args)
    except (SpecError, ArenaGenerationError, DatasetError, OSError, RuntimeError) as exc:
        print(f"nirl-mj {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"nirl-mj {args.command}: interrupted; nothing was written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
