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
    from nirl_mj.learn.predictability import predictability

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
    from nirl_mj.data.trajectory import path_length

    return (
        f"seed {trajectory.arena_seed:10d}  {trajectory.outcome:13s} steps {len(trajectory):4d}  "
        f"path {path_length(trajectory):6.1f} m"
    )


def _cmd_rollout(args: argparse.Namespace) -> int:
    from nirl_mj.data.outcomes import summarise
    from nirl_mj.experiments.seeds import episode_seed
    from nirl_mj.experts.policies import PolicyAgent
    from nirl_mj.sim.episode import run_episode
    from nirl_mj.sim.spec import apply_overrides, load_task
    from nirl_mj.sim.task import make_env

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
        agent = PolicyAgent.named(args.policy)
        for i in range(args.episodes):
            trajectory = run_episode(env, agent, episode_seed(args.seed, i))
            trajectories.append(trajectory)
            bar.update()
            bar.write(f"episode {i:3d}  {_episode_line(trajectory)}", file=sys.stdout)
    summary = summarise(trajectories)
    _print_summary(summary)
    if args.json:
        print(json.dumps({**summary, "task": spec.name, "policy": args.policy, "seed": args.seed}))
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from nirl_mj.experiments.demos import default_workers
    from nirl_mj.experiments.main_job import main_job
    from nirl_mj.inspect.figures import results_table
    from nirl_mj.sim.spec import apply_overrides, load_task

    spec = apply_overrides(load_task(args.task), args.set)
    if args.rerun:
        _check_output(Path(args.rerun), args.overwrite)
    from nirl_mj.learn.loop import NirlConfig

    iterations = args.episodes or NirlConfig.named(args.variant).episodes
    bar = tqdm(total=3 * iterations, unit="iteration", file=sys.stderr, disable=args.quiet,
               desc="NIRL and 2 controls")  # fmt: skip

    def progress(m: dict) -> None:
        bar.update()
        if m["margin"] == m["margin"]:  # a NIRL row (the controls learn no reward: margin NaN)
            bar.set_postfix(margin=f"{m['margin']:.3f}", acc=f"{m['demo_accuracy']:.2f}",
                            succ=f"{m['success_rate']:.1f}")  # fmt: skip

    def log(text: str) -> None:
        bar.write(text, file=sys.stderr)

    try:
        results = main_job(
            args.out, spec, seed=args.seed, variant=args.variant, demos=args.demos, expert=args.expert,
            episodes=args.episodes, tests=args.tests, workers=args.workers or default_workers(),
            resume=args.resume, log=log,
            on_metrics=progress,
        )  # fmt: skip
    finally:
        bar.close()
    print(results_table(results))
    print(f"report: {Path(args.out) / 'report.md'}")
    if args.rerun:
        from nirl_mj.inspect.recording import copy_recording

        print(f"wrote {copy_recording(Path(args.out) / 'run.rrd', args.rerun)}")
    if args.json:
        print(json.dumps({name: r["success_rate"] for name, r in results.items()}))
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


def _open_recording(path: str | None, overwrite: bool):
    """A :class:`nirl_mj.inspect.recording.Recording` at ``path`` (checked first), or None without one."""
    if not path:
        return None
    _check_output(Path(path), overwrite)
    from nirl_mj.inspect.recording import Recording

    return Recording(path)


def _cmd_demos(args: argparse.Namespace) -> int:
    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.data.outcomes import summarise
    from nirl_mj.experiments.demos import ExpertConfig, collect, default_workers
    from nirl_mj.sim.spec import apply_overrides, load_task

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
        from nirl_mj.inspect.recording import record_demonstrations

        record_demonstrations(args.rerun, trajectories)
        print(f"wrote {args.rerun}")
    if args.json:
        print(json.dumps({**summary, "predictability": pred, "expert": args.expert, "out": str(out)}))
    return 0


def _cmd_inspect(args: argparse.Namespace) -> int:
    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.data.outcomes import summarise
    from nirl_mj.learn.pretreat import map_pretreat

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
    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.experiments.seeds import episode_seed
    from nirl_mj.experts.teleop import __doc__ as keys_doc
    from nirl_mj.experts.teleop import teleoperate
    from nirl_mj.sim.task import make_env

    out = Path(args.out)
    _check_output(out, args.overwrite)
    from nirl_mj.sim.spec import apply_overrides, load_task

    env = make_env(apply_overrides(load_task(args.task), args.set))
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


def _cmd_train(args: argparse.Namespace) -> int:
    from nirl_mj.experiments.training import read_run, train
    from nirl_mj.learn.loop import NirlConfig
    from nirl_mj.sim.spec import SpecError, apply_overrides, from_dict, load_task

    if args.resume:
        changed = [flag for flag, given in (("--config", args.config), ("--set", args.set),
                                            ("--episodes", args.episodes)) if given]  # fmt: skip
        if changed:
            raise SpecError(
                f"--resume continues with the run's saved settings; {', '.join(changed)} cannot change them "
                "(train a new run with another --out instead)"
            )
        saved = read_run(args.out)  # continue with exactly the saved task and configuration
        spec = from_dict(saved["task"], f"{args.out}/run.json")
        config = NirlConfig(**saved["config"])
        demos, seed = args.demos or saved["demos"], saved["seed"]
    else:
        if not args.demos:
            raise FileNotFoundError("--demos is required (record some with `nirl-mj demos`)")
        spec = apply_overrides(load_task(args.task), args.set)
        changes = {"episodes": args.episodes} if args.episodes else {}
        config = NirlConfig.named(args.variant, **changes, **_config_overrides(args.config))
        demos, seed = args.demos, args.seed
    done = _iterations_done(args.out) if args.resume else 0
    recording = _open_recording(args.rerun, args.overwrite)
    with tqdm(
        total=config.episodes, initial=done, unit="episode", file=sys.stderr, disable=args.quiet
    ) as bar:

        def progress(m) -> None:
            bar.update()
            bar.set_postfix(margin=f"{m.margin:.3f}", cost=f"{m.cost:.3f}", acc=f"{m.demo_accuracy:.2f}",
                            succ=f"{m.success_rate:.1f}", val="-" if m.validation_success is None
                            else f"{m.validation_success:.2f}")  # fmt: skip
            if recording:
                recording.training([vars(m)])  # per iteration, from the metrics already computed

        try:
            record = train(args.out, spec, demos, config, seed, args.resume, progress)
        except BaseException:
            if recording:
                recording.abort()
            raise
    if recording:
        from nirl_mj.inspect.recording import finish_training

        print(f"wrote {finish_training(recording, args.out, demos)}")
    print(
        f"trained {record['iterations']} iterations ({config.variant} variant); selected policy: iteration "
        f"{record['selected_iteration']}; run in {args.out}"
    )
    return 0


def _config_overrides(assignments: list[str]) -> dict:
    """``KEY=VALUE`` pairs for NirlConfig (VALUE in TOML syntax), checked against its fields."""
    import dataclasses
    import tomllib

    from nirl_mj.learn.loop import NirlConfig
    from nirl_mj.sim.spec import SpecError

    fields = {f.name: f.type for f in dataclasses.fields(NirlConfig)}
    out = {}
    for text in assignments:
        key, sep, value = text.partition("=")
        key = key.strip()
        if not sep or key not in fields:
            raise SpecError(f"--config {text!r}: expected KEY=VALUE with KEY one of: {', '.join(fields)}")
        try:
            out[key] = tomllib.loads(f"v = {value.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            out[key] = value.strip()
    return out


def _iterations_done(run_dir: str) -> int:
    path = Path(run_dir) / "metrics.jsonl"
    return len(path.read_text().splitlines()) if path.exists() else 0


def _cmd_eval(args: argparse.Namespace) -> int:
    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.experiments.evaluation import evaluate
    from nirl_mj.experiments.seeds import held_out_seeds, seen_seeds
    from nirl_mj.experiments.training import load_policy
    from nirl_mj.sim.spec import apply_overrides, from_dict, load_task
    from nirl_mj.sim.task import make_env

    if args.run:
        policy, run = load_policy(args.run, args.which)
        spec = load_task(args.task) if args.task else from_dict(run["task"], f"{args.run}/run.json")
        seen = seen_seeds(run)
        name = "nirl"
    else:
        demos = load_dataset(args.demos) if args.demos else []
        policy, spec, name = _reference_policy(args, demos), load_task(args.task or "navigate"), args.policy
        seen = {t.arena_seed for t in demos}
    spec = apply_overrides(spec, args.set)
    if args.rerun:
        _check_output(Path(args.rerun), args.overwrite)
    seeds = held_out_seeds(args.seed, args.tests, seen)
    env = make_env(spec)
    with tqdm(total=args.tests, unit="test", file=sys.stderr, disable=args.quiet) as bar:
        metrics, trajectories = evaluate(env, policy, seeds, name, on_episode=lambda t: bar.update())
    result = {
        **metrics,
        "task": spec.name,
        "seed": args.seed,
        "policy": args.which if args.run else args.policy,
    }
    if args.run:
        key = f"{spec.name}|seed={args.seed}|tests={args.tests}|{args.which}"
        _merge_json(Path(args.run) / "eval.json", key, result)
    print(
        f"{args.tests} held-out tests of {spec.name}: success {metrics['success_rate']:.0%}  collision "
        f"{metrics['collision_rate']:.0%}  timeout {metrics['timeout_rate']:.0%}  path "
        f"{metrics['mean_path_length']:.1f} m  SPL {metrics['spl']:.2f}"
    )
    if args.rerun:
        from nirl_mj.inspect.recording import record_evaluation

        reward = Path(args.run) / "reward.json" if args.run else None
        reward = reward if reward and reward.is_file() else None
        record_evaluation(args.rerun, name, trajectories, reward, (spec, seeds[0]) if reward else None)
        print(f"wrote {args.rerun}")
    if args.json:
        print(json.dumps(result))
    return 0


def _reference_policy(args: argparse.Namespace, demos: list):
    """A reference policy for ``eval --policy``: forward, rule, or behaviour cloning of --demos."""
    from nirl_mj.experts.policies import POLICIES

    if args.policy != "bc":
        return POLICIES[args.policy]
    if not demos:
        raise FileNotFoundError("eval --policy bc needs --demos (the demonstrations to clone)")
    from nirl_mj.learn.bc import behaviour_cloning

    return behaviour_cloning(demos, seed=args.train_seed)


def _merge_json(path: Path, key: str, value: dict) -> None:
    """Adds ``key`` to the JSON object in ``path`` (atomically), keeping the other entries."""
    from nirl_mj.data.atomic import write_text

    data = json.loads(path.read_text()) if path.exists() else {}
    data[key] = value
    write_text(path, json.dumps(data, indent=1))


def _cmd_render(args: argparse.Namespace) -> int:
    from nirl_mj.inspect import video as render

    outputs = [Path(p) for p in (args.out, args.montage, args.paths) if p]
    if not outputs:
        raise render.RenderError(
            "nothing to write: give --out FILE.mp4, --montage FILE.png and/or --paths FILE.png"
        )
    for path in outputs:
        _check_output(path, args.overwrite)
    render.check_frame(args.camera, args.width, args.height)
    render.check_backend()
    from nirl_mj.sim.task import make_env

    policy, spec, seeds, what = _render_subject(args)
    env = make_env(spec)
    print(f"{what} on {spec.name}, arena seed {seeds[0]}, camera {args.camera}", file=sys.stderr)
    if args.out:
        video = render.record_video(env, policy, seeds[0], args.out, args.camera, args.width, args.height,
                                    args.fps, args.overlay, args.overwrite)  # fmt: skip
        t = video.trajectory
        print(f"wrote {video.path}: {video.frames} frames, {video.duration:.1f} s simulated at "
              f"{args.fps:g} fps, {t.outcome} after {len(t)} decisions")  # fmt: skip
    if args.montage:
        out = render.snapshot_strip(env, policy, seeds[0], args.montage, args.snapshots, args.camera,
                                    args.width, args.height, overwrite=args.overwrite)  # fmt: skip
        print(f"wrote {out}")
    if args.paths:
        out = render.paths_montage(env, policy, seeds, args.paths, args.camera, args.width, args.height,
                                   overwrite=args.overwrite)  # fmt: skip
        print(f"wrote {out}")
    return 0


def _render_subject(args: argparse.Namespace) -> tuple:
    """(policy, task spec, arena seeds, description) for ``render``: a run's greedy policy on its
    held-out test arenas (as ``eval`` numbers them), or a reference policy on test-domain arenas."""
    from nirl_mj.experiments.seeds import domain_seeds, held_out_seeds
    from nirl_mj.sim.spec import apply_overrides, from_dict, load_task

    if args.episode < 0:
        from nirl_mj.inspect.video import RenderError

        raise RenderError(f"--episode {args.episode}: expected a test arena index >= 0")
    count = args.episode + max(1, args.arenas if args.paths else 1)
    if args.run:
        from nirl_mj.experiments.seeds import seen_seeds
        from nirl_mj.experiments.training import load_policy

        policy, run = load_policy(args.run, args.which)
        spec = load_task(args.task) if args.task else from_dict(run["task"], f"{args.run}/run.json")
        seen = seen_seeds(run)
        seeds, what = held_out_seeds(args.seed, count, seen), f"{args.run} ({args.which} policy)"
    else:
        from nirl_mj.experts.policies import POLICIES

        policy, spec = POLICIES[args.policy], load_task(args.task or "navigate")
        seeds, what = domain_seeds("test", args.seed, count), f"policy {args.policy}"
    return policy, apply_overrides(spec, args.set), seeds[args.episode :], what


def _cmd_compare(args: argparse.Namespace) -> int:
    from nirl_mj.experiments.compare import json_line, markdown_table, run_compare

    summary = _run_experiment(args, "compare", run_compare)
    print(markdown_table(summary))
    return _experiment_end(args, summary, json_line)


def _cmd_sweep(args: argparse.Namespace) -> int:
    from nirl_mj.experiments.definition import load_experiment
    from nirl_mj.experiments.sweep import json_line, markdown_table, run_sweep

    summary = _run_experiment(args, "sweep", run_sweep)
    print(markdown_table(summary, load_experiment(args.task, args.quick)))
    return _experiment_end(args, summary, json_line)


def _run_experiment(args: argparse.Namespace, kind: str, run) -> dict:
    """Loads the experiment spec, then runs (or resumes) it with a progress bar over its cells."""
    from nirl_mj.experiments.definition import ExperimentError, load_experiment
    from nirl_mj.experiments.protocol import Execution

    experiment = load_experiment(args.task, args.quick)
    if experiment.kind != kind:
        raise ExperimentError(f"{args.task} is a {experiment.kind} experiment: run it with `nirl-mj "
                              f"{experiment.kind}`")  # fmt: skip
    if args.retries < 0:
        raise ExperimentError(f"--retries {args.retries}: must be >= 0")
    if args.address and args.executor != "ray":
        raise ExperimentError("--address is the address of a Ray cluster: give --executor ray with it")
    out = Path(args.out or f"runs/{experiment.name}{'-quick' if args.quick else ''}")
    execution = Execution(args.executor, args.workers, args.address, args.retries, args.report)
    bars: list[tqdm] = []  # made once the number of cells is known

    def log(text: str) -> None:
        tqdm.write(text, file=sys.stderr)

    def start(total: int, done: int) -> None:
        log(f"{total} cells, {done} already finished in {out}; executor {args.executor}")
        bars.append(tqdm(total=total, initial=done, unit="cell", file=sys.stderr, disable=args.quiet,
                         desc=experiment.name))  # fmt: skip

    def done(cell_id: str, result, failure) -> None:
        bars[0].update()
        bars[0].set_postfix_str(cell_id if failure is None else f"{cell_id} FAILED")

    try:
        return run(experiment, out, execution, log, start, done)
    except KeyboardInterrupt:
        print(f"interrupted: finished cells are kept in {out}/cells; run the same command to resume",
              file=sys.stderr)  # fmt: skip
        raise SystemExit(130) from None
    finally:
        for bar in bars:
            bar.close()


def _experiment_end(args: argparse.Namespace, summary: dict, json_line) -> int:
    """Prints the files and failures; 1 if any cell failed (its results are missing), else 0."""
    print("wrote " + ", ".join(summary["files"]))
    for failure in summary["failures"]:
        attempts = failure["attempts"]
        print(f"FAILED {failure['id']} ({attempts} attempt(s)): {failure['error']}", file=sys.stderr)
    if args.json:
        print(json_line(summary))
    return 1 if summary["failures"] else 0


def _cmd_task(args: argparse.Namespace) -> int:
    from nirl_mj.sim.spec import load_task

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


def _add_rerun_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """--rerun FILE.rrd, and --overwrite for it where the command has none yet."""
    parser.add_argument(
        "--rerun", default=None, metavar="FILE.rrd", help=f"also write a Rerun recording: {what}"
    )
    if "--overwrite" not in parser._option_string_actions:  # argparse refuses a second --overwrite
        parser.add_argument("--overwrite", action="store_true", help="replace an existing --rerun file")


def _add_task_arguments(parser: argparse.ArgumentParser, default: str | None = "navigate") -> None:
    """--task and --set, the same on every command that builds an environment."""
    helps = "task name under tasks/ or a .toml path" + ("" if default else " (default: the run's own)")
    parser.add_argument("--task", default=default, help=helps)
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override a task value, e.g. control.speed=3 (repeatable)")  # fmt: skip


def _add_experiment_arguments(parser: argparse.ArgumentParser, default: str, func) -> None:
    """The options of ``compare`` and ``sweep`` (docs/EXPERIMENTS.md)."""
    from nirl_mj.experiments.executors import EXECUTORS

    parser.add_argument("--task", default=default, metavar="SPEC",
                        help=f"experiment file or its name under tasks/ (default: {default})")  # fmt: skip
    parser.add_argument("--quick", action="store_true", help="the spec's [quick] values: a smoke run")
    parser.add_argument("--out", default=None, help="output directory (default: runs/NAME[-quick]); "
                        "rerunning into it resumes the same experiment, another one is refused")  # fmt: skip
    parser.add_argument("--executor", choices=EXECUTORS, default="local",
                        help="where cells run: this process, local processes (default), or Ray")  # fmt: skip
    parser.add_argument("--workers", type=_positive_int, default=None,
                        help="local processes or local Ray CPUs (default: all cores)")  # fmt: skip
    parser.add_argument("--address", default=None, help="with --executor ray: an existing cluster's address")
    parser.add_argument("--retries", type=int, default=2, metavar="N",
                        help="further attempts of a failing cell (default: 2)")  # fmt: skip
    parser.add_argument("--report", action="store_true",
                        help="run nothing: write the tables from the cells finished so far (a partial "
                        "report of a long or interrupted experiment; safe while it runs)")  # fmt: skip
    parser.add_argument("--json", action="store_true", help="print the summary as JSON on the last line")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=func)


def build_parser() -> argparse.ArgumentParser:
    from nirl_mj.experts import EXPERT_KINDS
    from nirl_mj.experts.policies import POLICIES

    parser = argparse.ArgumentParser(prog="nirl-mj", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    main = sub.add_parser(
        "run",
        help="the main job: demonstrations, NIRL, held-out evaluation next to the references, report",
    )
    _add_task_arguments(main)
    main.add_argument("--out", default="runs/main", help="run directory (default: runs/main)")
    main.add_argument(
        "--resume", action="store_true", help="continue a run in --out, skipping finished stages"
    )
    main.add_argument("--seed", type=int, default=0)
    main.add_argument("--variant", choices=["default", "paper"], default="default")
    main.add_argument("--demos", type=_positive_int, default=30, help="demonstrations to record")
    main.add_argument("--expert", choices=["sensor", "planner", "rule"], default="sensor")
    main.add_argument(
        "--episodes", type=_positive_int, default=None, help="NIRL iterations (default: the variant's)"
    )
    main.add_argument("--tests", type=_positive_int, default=100, help="held-out test arenas")
    main.add_argument(
        "--workers",
        type=_positive_int,
        default=None,
        help="processes for demonstrations, training and evaluation (default: all cores)",
    )
    main.add_argument("--json", action="store_true", help="print success rates as JSON on the last line")
    main.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_rerun_argument(main, "a copy of RUN_DIR/run.rrd (always written)")
    main.set_defaults(func=_cmd_run)

    run = sub.add_parser(
        "rollout",
        help="roll out a reference policy on fresh arenas and print each episode's outcome",
    )
    _add_task_arguments(run)
    run.add_argument("--episodes", type=_positive_int, default=10)
    run.add_argument("--seed", type=int, default=0)
    run.add_argument("--policy", choices=sorted(POLICIES), default="rule")
    run.add_argument("--json", action="store_true", help="print a JSON summary as the last line")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.set_defaults(func=_cmd_rollout)

    demos = sub.add_parser("demos", help="record expert demonstrations to a dataset file")
    _add_task_arguments(demos)
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
    _add_task_arguments(teleop)
    teleop.add_argument("--episodes", type=_positive_int, default=30)
    teleop.add_argument("--seed", type=int, default=0)
    teleop.add_argument("--out", required=True, help="dataset path (.npz)")
    teleop.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    teleop.set_defaults(func=_cmd_teleop)

    train = sub.add_parser("train", help="train NIRL on demonstrations (resumable)")
    _add_task_arguments(train)
    train.add_argument("--demos", help="dataset from `nirl-mj demos` (.npz)")
    train.add_argument("--out", required=True, help="run directory")
    train.add_argument("--variant", choices=["default", "paper"], default="default")
    train.add_argument(
        "--episodes", type=_positive_int, default=None, help="NIRL iterations (default: the variant's)"
    )
    train.add_argument("--seed", type=int, default=0)
    train.add_argument(
        "--resume", action="store_true", help="continue the run in --out from its last checkpoint"
    )
    train.add_argument("--config", action="append", default=[], metavar="KEY=VALUE",
                       help="override a learner setting, e.g. reward_source=progress")  # fmt: skip
    train.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_rerun_argument(train, "training scalars per iteration, demonstrations with r_theta, reward map")
    train.set_defaults(func=_cmd_train)

    evaluate = sub.add_parser("eval", help="evaluate a trained run's greedy policy on held-out arenas")
    who = evaluate.add_mutually_exclusive_group(required=True)
    who.add_argument("--run", help="run directory")
    who.add_argument(
        "--policy", choices=["forward", "rule", "bc"], help="a reference policy instead of a run"
    )
    evaluate.add_argument(
        "--demos", help="with --policy: demonstrations (cloned by bc; their arenas are held out)"
    )
    evaluate.add_argument("--train-seed", type=int, default=0, help="with --policy bc: its training seed")
    _add_task_arguments(evaluate, default=None)
    evaluate.add_argument("--tests", type=_positive_int, default=100)
    evaluate.add_argument("--seed", type=int, default=0, help="seed of the test arenas")
    evaluate.add_argument(
        "--which",
        default="selected",
        metavar="selected|last|N",
        help="the selected policy, the last one, or the one of iteration N",
    )
    evaluate.add_argument("--json", action="store_true", help="print the result as JSON on the last line")
    evaluate.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_rerun_argument(evaluate, "every test episode (with r_theta and the reward map for --run)")
    evaluate.set_defaults(func=_cmd_eval)

    rendering = sub.add_parser(
        "render", help="render an episode of a run's (or a reference) policy offscreen: MP4, PNG montages"
    )
    who = rendering.add_mutually_exclusive_group(required=True)
    who.add_argument("--run", help="run directory: its greedy policy on its held-out test arenas")
    who.add_argument("--policy", choices=sorted(POLICIES), help="a reference policy instead of a run")
    _add_task_arguments(rendering, default=None)
    rendering.add_argument("--seed", type=int, default=0, help="seed of the test arenas (as for eval)")
    rendering.add_argument("--episode", type=int, default=0, help="which test arena (0 = eval's first)")
    rendering.add_argument("--which", default="selected", help="selected, last or an iteration number")
    rendering.add_argument("--out", help="MP4 video of the episode")
    rendering.add_argument("--montage", metavar="FILE.png", help="strip of snapshots of the episode (Fig. 8)")
    rendering.add_argument("--snapshots", type=_positive_int, default=5, help="frames in --montage")
    rendering.add_argument("--paths", metavar="FILE.png", help="whole paths in several test arenas (Fig. 5)")
    rendering.add_argument("--arenas", type=_positive_int, default=4, help="arenas in --paths")
    rendering.add_argument(
        "--camera", default="top", help="top (whole arena, default), follow (12 m above the robot) or chase"
    )
    rendering.add_argument("--width", type=_positive_int, default=640, help="pixels (even, <= 1280)")
    rendering.add_argument("--height", type=_positive_int, default=480, help="pixels (even, <= 960)")
    rendering.add_argument("--fps", type=float, default=10.0,
                           help="video frames per second of simulated time; plays at real time")  # fmt: skip
    rendering.add_argument("--overlay", action=argparse.BooleanOptionalAction, default=True,
                           help="draw time, step, action and danger levels onto the video")  # fmt: skip
    rendering.add_argument("--overwrite", action="store_true", help="replace existing output files")
    rendering.set_defaults(func=_cmd_render)

    compare = sub.add_parser(
        "compare", help="the paper's Table I protocol: every method, R runs of T tests, next to the paper"
    )
    _add_experiment_arguments(compare, "tasks/table1.toml", _cmd_compare)
    sweep = sub.add_parser("sweep", help="Fig. 6: success against obstacles and speed (CSV and line plot)")
    _add_experiment_arguments(sweep, "tasks/fig6.toml", _cmd_sweep)

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
    from nirl_mj.data.dataset import DatasetError
    from nirl_mj.experiments.training import RunError
    from nirl_mj.sim.layout import ArenaGenerationError
    from nirl_mj.sim.spec import SpecError

    try:
        return args.func(args)
    except (SpecError, ArenaGenerationError, DatasetError, RunError, OSError, RuntimeError) as exc:
        # OSError covers FileExistsError: a run or file that would be overwritten.
        print(f"nirl-mj {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"nirl-mj {args.command}: interrupted; nothing was written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
