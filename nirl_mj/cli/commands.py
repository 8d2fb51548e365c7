"""The ``nirl-mj`` commands: each takes the parsed arguments, calls the library and prints."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import shutil
import sys
import time
from pathlib import Path

from tqdm import tqdm

from nirl_mj.data.assignments import parse_assignment
from nirl_mj.data.dataset import load_dataset, save_dataset
from nirl_mj.data.features import ACTION_NAMES
from nirl_mj.data.lock import DirectoryLock
from nirl_mj.data.outcomes import summarise
from nirl_mj.data.rundir import (
    EVAL_FILE,
    RUN_FILE,
    RunDir,
    RunError,
)
from nirl_mj.experiments import compare, suite, sweep
from nirl_mj.experiments.definition import ExperimentError, check_seed_range, load_experiment
from nirl_mj.experiments.demos import ExpertConfig, collect, kept_episodes_folder
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.executors import default_workers
from nirl_mj.experiments.main_job import main_experiment, main_job, report_table
from nirl_mj.experiments.protocol import Execution
from nirl_mj.experiments.seeds import episode_seed
from nirl_mj.experiments.subjects import Subject, reference_subject, run_subject
from nirl_mj.experiments.training import saved_settings, train
from nirl_mj.experts import make_expert
from nirl_mj.inspect import video
from nirl_mj.inspect.recording import Recording, copy_recording, finish_training, record_demonstrations
from nirl_mj.inspect.text import episode_line, evaluation_line, phi_text, predictability_line, summary_lines
from nirl_mj.learn.config import PRETREATMENTS, LearnerConfig, checked_changes
from nirl_mj.learn.predictability import predictability
from nirl_mj.learn.pretreat import map_pretreat, relabelled_states
from nirl_mj.sim import spec as specs
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.rollouts import Backend, make_rollouts
from nirl_mj.sim.spec import SpecError, apply_overrides, load_task
from nirl_mj.sim.task import make_env


class _LazyBar:
    """A tqdm progress bar drawn at its first use (update, postfix or write), so that an input error
    found before any work starts prints its one line under no empty bar."""

    def __init__(self, **kw) -> None:
        self._kw, self._bar, self._made = kw, None, time.time()

    def __getattr__(self, name: str):
        if self._bar is None:
            self._bar = tqdm(**self._kw)
            # timed from when the work began, not from its first step's end (a rate of 1/0)
            self._bar.start_t = self._bar.last_print_t = self._made
        return getattr(self._bar, name)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()

    def __enter__(self) -> _LazyBar:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _episodes(n: int) -> str:
    return f"{n} episode{'s' * (n != 1)}"


def _bar(args: argparse.Namespace, total: int, unit: str, **kw) -> _LazyBar:
    return _LazyBar(total=total, unit=unit, file=sys.stderr, disable=getattr(args, "quiet", False), **kw)


def _summary(trajectories: list, summary: dict) -> dict | None:
    """Prints a dataset's summary and, with two or more episodes of discrete actions, its
    predictability from phi(s) (a classifier of the six actions)."""
    print(summary_lines(summary))
    discrete = summary.get("action_kind", "discrete") == "discrete"
    try:
        pred = predictability(trajectories) if len(trajectories) >= 2 and discrete else None
    except ValueError as exc:  # a half of the episodes without a decision: a valid dataset all the same
        print(f"predictability: not measured ({exc})")
        pred = None
    if pred:
        print(predictability_line(pred))
    return pred


def _check_output(
    path: str | Path, overwrite: bool, flag: str = "--out", creates: str | Path | None = None
) -> Path:
    """Fails before any work if ``path`` (given as ``flag``) cannot be written or would overwrite
    results; ``creates``, a directory the command itself makes (its ``--out``), may hold it."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"{flag} {path} is a directory; give a file path")
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; pass --overwrite to replace it, or choose another {flag}")
    parent = path.parent if str(path.parent) else Path(".")
    if creates is not None and parent.resolve() == Path(creates).resolve() and not parent.exists():
        return path
    if not parent.is_dir():
        raise FileNotFoundError(f"cannot write {path}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise PermissionError(f"cannot write {path}: directory {parent} is not writable")
    return path


def _check_rerun(
    args: argparse.Namespace, *kept: str | Path, creates: str | Path | None = None
) -> Path | None:
    """``--rerun``'s file checked before any work (None without it): a name ending in ``.rrd`` (what
    Rerun's viewer opens; never a dataset, a run's policy or its eval.json) that is none of ``kept``,
    the files the command itself writes, and :func:`_check_output`'s checks (``creates``: the
    directory the command makes, which may hold it)."""
    if not getattr(args, "rerun", None):
        return None
    path = Path(args.rerun)
    if path.suffix.lower() != ".rrd":
        raise ValueError(f"--rerun {path}: a Rerun recording's name ends in .rrd (for example "
                         f"{path.with_suffix('.rrd').name}): no other file is taken for it")  # fmt: skip
    if any(path.resolve() == Path(k).resolve() for k in kept):
        raise ValueError(
            f"--rerun {path} is also a file this command writes: give the recording another name"
        )
    return _check_output(path, args.overwrite, "--rerun", creates)


def _task(args: argparse.Namespace):
    return apply_overrides(load_task(args.task or "navigate"), args.set)


def _no_rerun_of_continuous(args: argparse.Namespace, spec) -> None:
    """Refuses ``--rerun`` on a task with continuous actions before any work: the Rerun recording
    names each decision's action among the six discrete ones."""
    if getattr(args, "rerun", None) and spec.control.actions == "continuous":
        raise ValueError(f"--rerun: task {spec.name} has continuous actions, and the Rerun recording shows "
                         "the six discrete actions only: leave out --rerun")  # fmt: skip


def cmd_run(args: argparse.Namespace) -> int:
    spec = _task(args)
    _check_rerun(args, Path(args.out) / "run.rrd", creates=args.out)
    iterations = args.episodes or LearnerConfig.preset(args.variant).loop.episodes
    bar = _bar(args, 3 * iterations, "iteration", desc="NIRL and 2 controls")

    def progress(m: dict) -> None:
        bar.update()
        if m["margin"] is not None:  # a NIRL row (the controls learn no reward: no margin, null)
            bar.set_postfix(margin=f"{m['margin']:.3f}", acc=f"{m['demo_accuracy']:.2f}",
                            succ=f"{m['success_rate']:.1f}")  # fmt: skip

    try:
        experiment = main_experiment(spec, args.seed, args.variant, args.demos, args.expert, args.episodes,
                                     args.tests)  # fmt: skip
        results = main_job(
            args.out,
            experiment,
            workers=args.workers or default_workers(),
            resume=args.resume,
            log=lambda text: bar.write(text, file=sys.stderr),
            on_metrics=progress,
        )
    finally:
        bar.close()
    print(report_table(args.out))
    print(f"report: {Path(args.out) / 'report.md'}")
    if args.rerun:
        print(f"wrote {copy_recording(Path(args.out) / 'run.rrd', args.rerun, args.overwrite)}")
    if args.json:
        print(json.dumps({name: r["success_rate"] for name, r in results.items()}))
    return 0


def cmd_rollout(args: argparse.Namespace) -> int:
    env = make_env(_task(args))
    spec, agent, trajectories = env.task.spec, make_expert(args.policy), []
    print(f"task {spec.name}: {spec.arena.static_obstacles} static + {spec.arena.moving_obstacles} moving "
          f"obstacles, {spec.control.speed} m/s, {spec.robot.drive} drive; policy {args.policy}; "
          f"{_episodes(args.episodes)}, seed {args.seed}", file=sys.stderr)  # fmt: skip
    with _bar(args, args.episodes, "episode") as bar:
        for i in range(args.episodes):
            trajectories.append(run_episode(env, agent, episode_seed(args.seed, i)))
            bar.update()
            bar.write(f"episode {i:3d}  {episode_line(trajectories[-1])}", file=sys.stdout)
    summary = summarise(trajectories)
    print(summary_lines(summary))
    if args.json:
        print(json.dumps({**summary, "task": spec.name, "policy": args.policy, "seed": args.seed}))
    return 0


def cmd_demos(args: argparse.Namespace) -> int:
    _check_output(args.out, args.overwrite)  # a bad --out is refused before the lock beside it is made
    with DirectoryLock(args.out, "demos"):  # one writer of the dataset file
        return _demos(args)


def _demos(args: argparse.Namespace) -> int:
    out = _check_output(args.out, args.overwrite)
    _check_rerun(args, out)
    spec = _task(args)
    _no_rerun_of_continuous(args, spec)
    # flag: (ExpertConfig's field, the value given; None: not given, the field's default)
    noise = {"--base": ("base", args.base), "--slip": ("slip", args.slip),
             "--random-action": ("random", args.random_action)}  # fmt: skip
    if args.expert != "noisy" and (named := [flag for flag, (_, v) in noise.items() if v is not None]):
        raise ValueError(f"{', '.join(named)}: only for --expert noisy; with --expert {args.expert} leave "
                         "them out")  # fmt: skip
    expert = ExpertConfig(args.expert, seed=args.seed, **{f: v for f, v in noise.values() if v is not None})
    workers = args.workers or default_workers()
    print(f"demonstrations: {_episodes(args.episodes)} of {spec.name} by the {args.expert} expert, "
          f"seed {args.seed}, {workers} worker(s)", file=sys.stderr)  # fmt: skip
    with _bar(args, args.episodes, "episode") as bar:

        def progress(trajectory) -> None:
            bar.update()
            bar.set_postfix_str(trajectory.outcome)

        # finished episodes are kept beside OUT until it is written: the same command resumes them
        kept = kept_episodes_folder(out)
        trajectories = collect(spec, expert, args.episodes, args.seed, workers, progress, keep=kept,
                               log=lambda text: bar.write(text, file=sys.stderr))  # fmt: skip
    save_dataset(out, trajectories, overwrite=args.overwrite)
    shutil.rmtree(kept, ignore_errors=True)
    summary = summarise(trajectories)
    pred = _summary(trajectories, summary)
    print(f"wrote {out}")
    if args.rerun:
        record_demonstrations(args.rerun, trajectories, overwrite=args.overwrite)
        print(f"wrote {args.rerun}")
    if args.json:
        print(json.dumps({**summary, "predictability": pred, "expert": args.expert, "out": str(out)}))
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    import minari  # noqa: F401  (the optional extra: missing, it fails here, before any work)

    from nirl_mj.gym.minari_export import export_minari

    trajectories = load_dataset(args.path)
    with _bar(args, len(trajectories), "episode", desc="replaying") as bar:
        dataset = export_minari(trajectories, args.id, args.overwrite, on_episode=lambda i: bar.update())
    print(f"wrote Minari dataset {args.id}: {dataset.total_episodes} episodes, {dataset.total_steps} steps "
          f"(minari.load_dataset({args.id!r}))")  # fmt: skip
    return 0


def cmd_inspect(args: argparse.Namespace) -> int:
    from nirl_mj.experiments.training import load_demonstrations

    trajectories = load_demonstrations(args.path, discrete=False)  # a file, or minari:ID as train reads
    summary = summarise(trajectories)
    print(f"{args.path}: valid nirl-mj dataset")
    print(f"demonstrators {summary['demonstrators']}  speeds {summary['speeds']}  tasks {summary['tasks']}")
    empty = sum(len(t) == 0 for t in trajectories)
    if empty:
        usable = "no learner can train on it" if empty == len(trajectories) else "they add nothing to learn"
        print(f"warning: {empty} of {len(trajectories)} trajectories end before their first decision; "
              f"{usable}")  # fmt: skip
    pred = _summary(trajectories, summary)
    changed = {}
    if summary.get("action_kind", "discrete") == "discrete":  # MAP relabels among the six actions
        for setting, prior in ((k, v) for k, v in PRETREATMENTS.items() if v is not None):
            relabelled, report = map_pretreat(trajectories, prior)
            changed[setting] = report.pairs_changed
            shares = "  ".join(f"{a} {f:.1%}" for a, f in summarise(relabelled)["action_fractions"].items())
            print(
                f'MAP pretreatment (eq. 10, {prior} prior, pretreatment = "{setting}") would relabel '
                f"{report.pairs_changed} of {report.pairs_total} pairs ({report.ambiguous_states} states "
                f"seen with several actions); actions after it: {shares}"
            )
            for r in relabelled_states(trajectories, relabelled):
                was = ", ".join(f"{ACTION_NAMES[a]} {n}" for a, n in enumerate(r.recorded) if n)
                print(f"  {phi_text(r.phi)}: {r.recorded.sum()} pairs ({was}) -> {ACTION_NAMES[r.action]}")
    if args.json:
        print(json.dumps({**summary, "predictability": pred, "map_pairs_changed": changed.get("map"),
                          "map_majority_pairs_changed": changed.get("map-majority")}))  # fmt: skip
    return 0


def cmd_teleop(args: argparse.Namespace) -> int:
    from nirl_mj.experts import teleop  # opens MuJoCo's viewer: only when asked

    teleop.require_display()  # before the key table is printed
    out = _check_output(args.out, args.overwrite)  # a bad --out is refused before the lock beside it
    with DirectoryLock(out, "teleop"):  # one writer of the dataset file
        return _teleop(args, teleop, out)


def _teleop(args: argparse.Namespace, teleop, out: Path) -> int:
    env = make_env(_task(args))
    print(teleop.__doc__.split("\n\n", 2)[2], file=sys.stderr)
    trajectories = []

    def keep(trajectory) -> None:
        trajectories.append(trajectory)
        print(f"episode {len(trajectories)}: {episode_line(trajectory)}")

    try:
        teleop.teleoperate(env, args.episodes, lambda i: episode_seed(args.seed, i), keep)
    except KeyboardInterrupt:
        print("interrupted: saving the finished episodes", file=sys.stderr)
    if not trajectories:
        print("no episode kept; nothing written", file=sys.stderr)
        return 1
    save_dataset(out, trajectories, overwrite=args.overwrite)
    print(f"wrote {len(trajectories)} human demonstrations to {out}")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    settings = {"--config": args.config, "--set": args.set, "--episodes": args.episodes, "--task": args.task,
                "--variant": args.variant, "--seed": args.seed}  # fmt: skip
    if args.resume:
        changed = [flag for flag, given in settings.items() if given not in (None, [])]
        if changed:
            raise SpecError(f"--resume continues with the run's saved settings; {', '.join(changed)} cannot "
                            "change them (train a new run with another --out instead)")  # fmt: skip
        spec, config, saved_demos, seed = saved_settings(args.out)
        demos = args.demos or saved_demos
        backend = _backend(args, RunDir(args.out).read_record().get("backend"))
    else:
        if not args.demos:
            raise FileNotFoundError("--demos is required (record some with `nirl-mj demos`)")
        changes = _config_overrides(args.config)
        if args.episodes:
            if "episodes" in changes:
                raise SpecError("--episodes and --config episodes=... both set the iterations: give one")
            changes["episodes"] = args.episodes
        config = LearnerConfig.preset(args.variant or "default", **changes)
        spec, demos, seed = _task(args), args.demos, args.seed or 0
        backend = _backend(args, worlds=config.loop.trajectories_per_episode)
    done = RunDir(args.out).iterations_done() if args.resume else 0
    rerun = _check_rerun(args, creates=args.out)
    # opened at the first iteration's end: its file may go into the run directory train makes
    recording: Recording | None = None
    with _bar(args, config.loop.episodes, "episode", initial=done) as bar:

        def progress(m) -> None:
            nonlocal recording
            bar.update(m.episode + 1 - bar.n)  # a resume redoes an iteration written past its checkpoint
            bar.set_postfix(margin=f"{m.margin:.3f}", cost=f"{m.cost:.3f}", acc=f"{m.demo_accuracy:.2f}",
                            succ=f"{m.success_rate:.1f}", val="-" if m.validation_success is None
                            else f"{m.validation_success:.2f}")  # fmt: skip
            if rerun is not None:
                if recording is None:
                    recording = Recording(rerun, overwrite=args.overwrite)
                recording.training([vars(m)])  # per iteration, from the metrics already computed

        try:
            record = train(args.out, spec, demos, config, seed, args.resume, progress, backend)
        except BaseException:
            if recording is not None:
                recording.abort()
            raise
    if rerun is not None:
        if recording is None:  # a resumed run with no iteration left
            recording = Recording(rerun, overwrite=args.overwrite)
        print(f"wrote {finish_training(recording, args.out, demos)}")
    print(f"trained {record['iterations']} iterations ({config.loop.variant} variant); selected policy: "
          f"iteration {record['selected_iteration']}; run in {args.out}")  # fmt: skip
    return 0


def cmd_rl(args: argparse.Namespace) -> int:
    import gymnasium  # noqa: F401  (the optional extra: missing, it fails here, before any work)
    import stable_baselines3  # noqa: F401

    from nirl_mj.experiments.rl import ADVERSARIAL, DEFAULT_STEPS, train_rl

    out = RunDir(args.out)
    if args.resume:
        if not out.is_run:
            raise RunError(f"nothing to resume in {args.out}: no run of nirl-mj rl there; train one "
                           "without --resume")  # fmt: skip
        saved = out.read_record()
        if saved.get("kind") != "rl":
            raise RunError(f"{args.out} holds a run of `nirl-mj train`, not of `nirl-mj rl`: resume it with "
                           f"`nirl-mj train --out {args.out} --resume`")  # fmt: skip
        if args.task or args.set:
            raise SpecError("--resume continues with the run's task; --task and --set cannot change it")
        spec = specs.from_dict(saved["task"], f"{out.file(RUN_FILE)}: task")
        # what is not given is the run's own (a different one is refused by train_rl, by name)
        args.algo, args.demos = args.algo or saved["algo"], args.demos or saved.get("demos")
        args.seed = saved["seed"] if args.seed is None else args.seed
        args.steps = args.steps or saved["steps"]
    else:
        spec = _task(args)
        args.algo, args.seed, args.steps = args.algo or "ppo", args.seed or 0, args.steps or DEFAULT_STEPS
    if (args.algo in ADVERSARIAL) != bool(args.demos):
        raise SpecError(f"--demos goes with --algo gail or airl (the demonstrations they imitate); got "
                        f"--algo {args.algo}{' with' if args.demos else ' without'} --demos")  # fmt: skip
    done = out.read_record().get("steps_done", 0) if args.resume else 0
    with _bar(args, args.steps, "decision", initial=min(done, args.steps)) as bar:

        def progress(n: int, stats: dict) -> None:
            bar.update(n)
            # a resume replays the run from its seed to its last checkpoint first (experiments.rl._replays)
            shown = {"replaying": stats["replaying"]} if "replaying" in stats else {}
            shown.update(episodes=stats["episodes"], succ=f"{stats['success']:.2f}")
            bar.set_postfix(shown, refresh=False)

        record = train_rl(out.path, spec, args.algo, args.steps, args.seed, args.resume, on_steps=progress,
                          demos=args.demos, selection=args.selection, envs=args.envs,
                          train_drive=args.train_drive, overwrite=args.overwrite)  # fmt: skip
    arenas = len(record["train_seeds"])
    print(f"trained {args.algo} for {record['steps_done']} decisions ({arenas} training arenas) on "
          f"{spec.name}; run in {args.out} (test it with nirl-mj eval --run {args.out})")  # fmt: skip
    return 0


def _config_overrides(assignments: list[str]) -> dict:
    """``KEY=VALUE`` learner settings (VALUE in TOML syntax; a bare word is a string), type-checked."""
    out = {}
    for text in assignments:
        parsed = parse_assignment(text)
        if parsed is None:
            raise SpecError(f"--config {text!r}: expected KEY=VALUE, e.g. reward_source=progress")
        out[parsed[0]] = parsed[1]
    if "variant" in out:
        raise SpecError("--config variant=...: the learner preset is chosen with --variant")
    try:
        return checked_changes(out, "--config", exclude=("variant",))
    except ValueError as exc:
        raise SpecError(str(exc)) from None


def _subject(args: argparse.Namespace) -> Subject:
    """A run's policy (``--run``) or a reference policy (``--policy``), for ``eval`` and ``render``."""
    demos, train_seed = getattr(args, "demos", None), getattr(args, "train_seed", None)
    if args.policy and args.which is not None:
        raise SpecError(
            f"--which chooses among a run's policies; --policy {args.policy} is one: leave out --which"
        )
    args.which = args.which or "selected"
    if train_seed is not None and args.policy != "bc":
        raise SpecError(f"--train-seed is the training seed of --policy bc; it has no use with "
                        f"{f'--policy {args.policy}' if args.policy else '--run'}: leave it out")  # fmt: skip
    if args.run:
        if demos:
            raise SpecError("--demos goes with --policy (a run's demonstrations are its own): leave it out")
        return run_subject(args.run, args.which, args.task)
    return reference_subject(args.policy, args.task, demos, train_seed or 0)


def cmd_eval(args: argparse.Namespace) -> int:
    if args.rerun:  # before the subject: `--policy bc` trains one
        _check_rerun(args)
        if not args.run:  # a run's task is its record's, known once the subject is
            _no_rerun_of_continuous(args, _task(args))
    subject = _subject(args)
    spec = apply_overrides(subject.task, args.set)
    if args.run:
        _no_rerun_of_continuous(args, spec)
    backend = _backend(args)
    warp = backend.name != "cpu"
    # --set changes the task but not its name: the key names the values it changed, so that an
    # evaluation under other settings never takes the plain one's place
    changed = _changed_values(subject.task, spec)
    key = (f"{spec.name}|seed={args.seed}|tests={args.tests}|{args.which}" + ("|backend=warp" if warp else "")
           + "".join(f"|set {value}" for value in changed))  # fmt: skip
    if subject.run:
        # a corrupt eval.json, or an evaluation already there, fails now, not after the evaluation
        if key in subject.run.read_evaluations() and not args.overwrite:
            raise RunError(f"{subject.run.file(EVAL_FILE)} already holds the evaluation {key!r}: give "
                           "--overwrite to replace it, or another --seed or --tests")  # fmt: skip
        if not os.access(subject.run.path, os.W_OK):
            raise RunError(f"{subject.run.path} is not writable: eval stores its result in eval.json there")
        with DirectoryLock(subject.run.file(EVAL_FILE), "eval", wait=True):
            pass  # a file system without locks fails now too
    seeds = subject.test_seeds(args.seed, args.tests)
    rollouts = make_rollouts(backend, spec) if warp else None
    with _bar(args, args.tests, "test") as bar:
        env = None if warp else make_env(spec)
        metrics, trajectories = evaluate(env, subject.policy, seeds, subject.name,
                                         on_episode=lambda t: bar.update(), rollouts=rollouts)  # fmt: skip
    result = {
        **metrics,
        "task": spec.name,
        "seed": args.seed,
        "policy": args.which if args.run else args.policy,
        **({"backend": backend.to_dict()} if warp else {}),
        **({"set": changed} if changed else {}),
    }
    if subject.run:
        subject.run.add_evaluation(key, result)
    print(evaluation_line(spec.name, metrics))
    if args.rerun:
        from nirl_mj.inspect.recording import record_evaluation

        reward = subject.reward()
        map_arena = (spec, seeds[0]) if reward else None
        record_evaluation(args.rerun, subject.name, trajectories, reward, map_arena, args.overwrite)
        print(f"wrote {args.rerun}")
    if args.json:
        print(json.dumps(result))
    return 0


def _changed_values(base: specs.TaskSpec, spec: specs.TaskSpec) -> list[str]:
    """``SECTION.KEY=VALUE`` (VALUE as JSON) for every task value in which ``spec`` differs from
    ``base``, sorted: the same for any order or spelling of the overrides that made it."""
    before, after = base.to_dict(), spec.to_dict()
    changed = []
    for section in sorted(k for k, v in {**before, **after}.items() if isinstance(v, dict)):
        was, now = before.get(section, {}), after.get(section, {})
        # to_dict leaves out some values at their defaults: a key on one side only changed too
        changed += [f"{section}.{key}={json.dumps(now.get(key))}" for key in sorted({*was, *now})
                    if was.get(key) != now.get(key)]  # fmt: skip
    return changed


def _backend(args: argparse.Namespace, saved: dict | None = None, worlds: int | None = None) -> Backend:
    """The backend that --backend, --worlds and --device name (a resumed training: the run's ``saved``
    one unless they say otherwise); ``worlds``, when given, replaces the default count of worlds
    (a training drives no more episodes at once than its iteration's trajectories)."""
    saved = saved or {}
    name = args.backend or saved.get("name", "cpu")
    if name == "cpu" and (args.worlds or args.device):
        raise SpecError("--worlds and --device go with --backend warp (the cpu backend runs one world)")
    default = Backend()
    return Backend(name, args.worlds or saved.get("worlds", worlds or default.worlds),
                   args.device or saved.get("device", default.device))  # fmt: skip


def cmd_render(args: argparse.Namespace) -> int:
    defaults = (("--arenas", args.arenas, "paths", video.PATHS_ARENAS),
                ("--snapshots", args.snapshots, "montage", video.MONTAGE_SNAPSHOTS))  # fmt: skip
    for flag, value, owner, default in defaults:
        if value is not None and not getattr(args, owner):
            raise video.RenderError(f"{flag} sets --{owner}'s figure; without --{owner} it has no use: "
                                    "leave it out")  # fmt: skip
        setattr(args, flag[2:], default if value is None else value)
    if args.montage:  # refused before anything is printed or computed, not after the header line
        video.check_snapshots(args.snapshots)
    outputs = [Path(p) for p in (args.out, args.montage, args.paths) if p]
    if not outputs:
        raise video.RenderError(
            "nothing to write: give --out FILE.mp4, --montage FILE.png and/or --paths FILE.png"
        )
    if len({p.resolve() for p in outputs}) < len(outputs):
        raise video.RenderError("--out, --montage and --paths name the same file; give each its own")
    written = {"--out": (args.out, ".mp4"), "--montage": (args.montage, ".png"),
               "--paths": (args.paths, ".png")}  # fmt: skip
    for flag, (path, suffix) in written.items():
        if path and Path(path).suffix.lower() != suffix:  # what is written: an MP4 video, PNG images
            raise video.RenderError(f"{flag} {path}: {flag} writes {suffix} (for example "
                                    f"{Path(path).with_suffix(suffix).name})")  # fmt: skip
    for flag, (path, _) in written.items():
        if path:
            _check_output(path, args.overwrite, flag)
    with contextlib.ExitStack() as held:
        for path in outputs:  # one writer of each file
            held.enter_context(DirectoryLock(path, "render"))
        return _render(args)


def _render(args: argparse.Namespace) -> int:
    video.check_frame(args.camera, args.width, args.height)
    video.check_backend()
    if args.episode < 0:
        raise video.RenderError(f"--episode {args.episode}: expected a test arena index >= 0")
    subject = _subject(args)
    spec = apply_overrides(subject.task, args.set)
    if spec.control.actions == "continuous" and subject.name.startswith("rl-"):
        raise video.RenderError(f"task {spec.name} has continuous actions: render shows a policy of the "
                                "six discrete actions (a reference policy, a NIRL run), not a continuous RL "
                                "run")  # fmt: skip
    seeds = subject.test_seeds(args.seed, args.episode + max(1, args.arenas if args.paths else 1))[
        args.episode :
    ]
    if args.out:  # the frame rate's bound is the task's command period: checked before the header line
        video.check_fps(args.fps, spec.control.command_period)
    what = f"{args.run} ({args.which} policy)" if args.run else f"policy {args.policy}"
    env, frame = make_env(spec), (args.camera, args.width, args.height)
    print(f"{what} on {spec.name}, arena seed {seeds[0]}, camera {args.camera}", file=sys.stderr)
    if args.out:
        clip = video.record_video(env, subject.policy, seeds[0], args.out, *frame, args.fps, args.overlay,
                                  args.overwrite)  # fmt: skip
        t = clip.trajectory
        print(
            f"wrote {clip.path}: {clip.frames} frames, {clip.duration:.1f} s simulated at {args.fps:g} fps, "
            f"{t.outcome} after {len(t)} decisions"
        )
    if args.montage:
        strip = video.snapshot_strip(env, subject.policy, seeds[0], args.montage, args.snapshots, *frame,
                                     overwrite=args.overwrite)  # fmt: skip
        print(f"wrote {strip}")
    if args.paths:
        print(
            "wrote "
            + str(
                video.paths_montage(
                    env,
                    subject.policy,
                    seeds,
                    args.paths,
                    *frame,
                    overwrite=args.overwrite,
                    first_index=args.episode,
                )  # fmt: skip
            )
        )
    return 0


_EXPERIMENTS = {  # command -> (run, Markdown table, --json line)
    "compare": (compare.run_compare, lambda summary, _: compare.markdown_table(summary), compare.json_line),
    "sweep": (sweep.run_sweep, sweep.markdown_table, sweep.json_line),
    "suite": (suite.run_suite, suite.markdown_table, suite.json_line),
}


def cmd_experiment(args: argparse.Namespace) -> int:
    """``compare``, ``sweep`` and ``suite``: run (or resume) the experiment, a progress bar over its cells."""
    run, table, json_line = _EXPERIMENTS[args.command]
    experiment = load_experiment(args.task, args.quick, args.command)
    if args.runs is not None:
        experiment = dataclasses.replace(experiment, runs=args.runs)
        check_seed_range(experiment, "--runs with the file's seed")
    out = Path(args.out or f"runs/{experiment.name}{'-quick' if args.quick else ''}")
    only, points = (tuple(n.strip() for n in (getattr(args, key, None) or "").split(",") if n.strip())
                    for key in ("only", "points"))  # fmt: skip
    execution = Execution(args.executor, args.workers, args.address, args.retries, args.report,
                          getattr(args, "reuse", None), only, points,
                          restore=getattr(args, "restore", None))  # fmt: skip
    if args.check:
        _check_flags(args, experiment, execution)
        print(_plan_text(experiment, out))
        return 0
    bars: list[_LazyBar] = []  # made once the number of cells is known

    def log(text: str) -> None:
        tqdm.write(text, file=sys.stderr)

    def start(total: int, done: int) -> None:
        log(f"{total} cells, {done} already finished in {out}; executor {args.executor}")
        bars.append(_bar(args, total, "cell", initial=done, desc=experiment.name))
        bars[0].refresh()  # drawn now, 0/N with its clock: the first cell may take long

    def done(cell_id: str, result, failure) -> None:
        bars[0].update()
        bars[0].set_postfix_str(cell_id if failure is None else f"{cell_id} FAILED")

    try:
        summary = run(experiment, out, execution, log, start, done)
    except KeyboardInterrupt:
        print(f"interrupted: finished cells are kept in {out}/cells; run the same command to resume",
              file=sys.stderr)  # fmt: skip
        raise SystemExit(130) from None
    finally:
        for bar in bars:
            bar.close()
    print(table(summary, experiment))
    print(summary["not_written"] if "not_written" in summary else "wrote " + ", ".join(summary["files"]))
    for failure in summary["failures"]:
        print(
            f"FAILED {failure['id']} ({failure['attempts']} attempt(s)): {failure['error']}", file=sys.stderr
        )
    if args.json:
        print(json_line(summary))
    return 1 if summary["failures"] else 0


def _check_flags(args: argparse.Namespace, experiment, execution: Execution) -> None:
    """``--check``: what a run refuses before it starts, of the flags given with the file."""
    execution.check_methods(experiment)  # --only names, the optional packages of the methods run
    if args.command == "suite":
        suite.at_points(experiment, execution)
    for flag in ("reuse", "restore"):
        where = getattr(args, flag, None)
        if where and not Path(where).is_dir():
            raise ExperimentError(f"--{flag} {where}: no such directory")


def _plan_text(experiment, out: Path) -> str:
    """``--check``: what a valid experiment file would run, and what its output directory holds."""
    from nirl_mj.experiments.protocol import output_state
    from nirl_mj.experiments.reads import is_reference, method_reads

    e = experiment
    demos = f"{e.demos} by the {e.expert} expert, {'a set per run' if e.demos_per_run else 'one set'}"
    for axis in (a for a in e.axes if a.trains):  # demonstrations or demonstrator
        demos += f" ({axis.name}: the axis's values)"
    lines = [f"{e.source}: a valid {e.kind} experiment{' (--quick)' if e.quick else ''}"
             + (f": {e.description}" if e.description else ""),
             f"runs {e.runs} (seeds {e.seed}..{e.seed + e.runs - 1}), {e.tests} test arenas each from the "
             f"{e.test_domain!r} domain; demonstrations: {demos}",
             f"task {e.task.name}, tests on {e.test_task.name}", _set_line(e)]  # fmt: skip
    for a in e.axes:
        own = a.test_task is not None and a.test_task != e.test_task
        # an axis's own test task keeps its arenas: [set]'s arena values do not reach its tests
        tests_on = f" (tests on {a.test_task.name}, its own arena: not set's arena.*)" if own else ""
        lines.append(f"axis {a.name}{tests_on}: {', '.join(map(str, a.values))}")
    if e.kind == "sweep":
        lines.append(f"cells: {len(e.obstacles)} obstacle counts x {len(e.speeds)} speeds")
    lines.append(f"methods ({len(e.methods)}):")
    for m in e.methods:
        reads = method_reads(m, e.config)
        lines.append(f"  {m.name} ({m.kind}{', a reference' if is_reference(reads) else ''}): reads "
                     f"{', '.join(reads) or 'nothing'}")  # fmt: skip
    lines.append(f"output: {out} ({output_state(out, e)})")
    return "\n".join(lines)


def _set_line(experiment) -> str:
    """``--check``: the experiment file's ``[set]`` (with --quick, its ``[quick]`` table's merged in), the
    values it changes in the task and the test task, as ``SECTION.KEY=VALUE`` (VALUE as JSON), sorted
    (an axis with a test task of its own keeps that task's arena; a sweep's cells and a test axis set
    the value they vary, as the plan's other lines say)."""
    table = experiment.overrides
    values = [f"{section}.{key}={json.dumps(value)}"
              for section in sorted(table) for key, value in sorted(table[section].items())]  # fmt: skip
    return "set: " + (", ".join(values) or "none")


def cmd_leaderboard(args: argparse.Namespace) -> int:
    """Merges output directories of compare and suite into one ranked table (docs/EXTENDING.md)."""
    from nirl_mj.experiments.leaderboard import write_leaderboard

    table, files = write_leaderboard(args.dirs, args.out, args.overwrite)  # holding OUT's lock
    print(table)
    print("wrote " + ", ".join(str(f) for f in files))
    return 0


def cmd_task(args: argparse.Namespace) -> int:
    spec = _task(args)
    print(json.dumps({**spec.to_dict(), "step_budget": spec.step_budget}, indent=2))
    return 0
