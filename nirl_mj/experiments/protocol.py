"""The protocol every experiment shares: output directory, demonstrations, seeds, runs, one evaluation.

An experiment's output directory OUT holds ``experiment.json`` (the identity of
what it computes: :meth:`nirl_mj.experiments.definition.Experiment.identity`), ``demos.npz``
(one set of demonstrations for every run and method) or, with ``[demos] per_run``,
``demos/runNNN.npz`` (run r's, seeded ``seed + r``, shared by every method of run r),
``runs/METHOD/SEED/``
(training runs, ``nirl-mj train``'s layout, resumable from their checkpoints)
and ``cells/`` (finished cells, :class:`nirl_mj.experiments.executors.CellStore`).

Seeds. Run r of every method trains with seed ``experiment.seed + r`` on the same
demonstrations and is tested on the same arenas: ``held_out_seeds(seed + r,
tests, seen, test_domain)``, where ``seen`` holds the demonstrations' arenas and the training
and validation arenas every trainable method of run r may use. So the methods of
a run are compared on identical arenas (paired), the test arenas of a run are
disjoint from everything its learners saw (checked again against each run's
record), and a cell's result depends on nothing but its own arguments.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nirl_mj.data.atomic import leftover_temporaries
from nirl_mj.experiments.definition import Experiment, ExperimentError, MethodSpec
from nirl_mj.sim.spec import TaskSpec

EXPERIMENT_FILE = "experiment.json"


def one_writer(runner: Callable) -> Callable:
    """Decorates an experiment's runner ``(experiment, out, execution, ...)``: it runs holding the lock
    on OUT (``nirl_mj.data.lock``), so a second command writing the same OUT is refused with one line
    naming the first one's process. A ``--report`` takes the lock too; while another process holds
    it (the experiment is running), the report runs without writing anything: its summary carries
    no files and says why under ``not_written``, and the command prints the tables instead."""
    import dataclasses
    import functools

    @functools.wraps(runner)
    def locked(experiment: Experiment, out: str | Path, execution: Execution | None = None, *args, **kwargs):
        from nirl_mj.data.lock import DirectoryLock, LockedError

        if execution is not None and execution.report_only:
            try:
                lock = DirectoryLock(out, f"{experiment.kind}").acquire()
            except LockedError as busy:
                summary = runner(experiment, out, dataclasses.replace(execution, writes_tables=False), *args,
                                 **kwargs)  # fmt: skip
                summary["not_written"] = f"{busy}: this partial report is printed, not written"
                return summary
            try:
                return runner(experiment, out, execution, *args, **kwargs)
            finally:
                lock.release()
        with DirectoryLock(out, f"{experiment.kind}"):
            return runner(experiment, out, execution, *args, **kwargs)

    return locked


def open_output(out: str | Path, experiment: Experiment, record: bool = True) -> Path:
    """Creates OUT for ``experiment``, or re-opens it to resume the same experiment.

    Refuses a non-empty directory of another experiment (naming the keys that differ)
    or of anything else. Methods may be added (:func:`grows`), and learner changes spelled
    otherwise with the same resolved settings (a default's value pinned in ``[config]``) are the same
    experiment. Returns OUT as an absolute path: cells may run in another
    working directory (Ray workers do). ``record`` False (a report beside the running experiment)
    writes nothing: a grown experiment is recorded by the run that computes it."""
    out = Path(out).resolve()
    marker = out / EXPERIMENT_FILE
    identity = experiment.identity()
    if marker.is_file():
        differ, grown = recorded_differences(out, experiment)
        if differ and not grown:
            # a method changed (its settings, or its package's code once fixed): the other rows' cells
            # still hold, and the command that keeps them is the one to name
            flag = {"compare": "--reuse", "suite": "--restore"}.get(experiment.kind)
            keep = (f"; to compute the changed methods beside the cells of the others: --out NEW {flag} {out}"
                    if flag and any(d.startswith("methods (") for d in differ) else "")  # fmt: skip
            raise ExperimentError(
                f"{out} holds another experiment (it differs in: {', '.join(differ)}); choose another --out, "
                "or rerun it with the same spec and flags to resume it (methods may be added, if the "
                f"runs' test arenas stay the same; none may change or go){keep}"
            )
        # grown by new methods (the same learners spelled otherwise keep what they were)
        if differ and record:
            from nirl_mj.data.atomic import write_text

            write_text(marker, json.dumps(identity, indent=1))
        return out
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ExperimentError(f"{out} exists and holds no nirl-mj experiment; choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    from nirl_mj.data.atomic import write_text

    write_text(marker, json.dumps(identity, indent=1))
    return out


def recorded_differences(out: Path, experiment: Experiment) -> tuple[list[str], bool]:
    """The identity keys in which the experiment recorded in OUT differs from ``experiment``, and
    whether the differences only grow it (methods added, :func:`grows`): a run resumes OUT then."""
    marker = out / EXPERIMENT_FILE
    try:
        saved = json.loads(marker.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ExperimentError(f"{marker} is corrupted ({exc}); choose another --out") from None
    if not isinstance(saved, dict):
        raise ExperimentError(f"{marker} is corrupted (not a JSON object); choose another --out")
    identity = experiment.identity()
    was, now = unspelled_identity(saved), unspelled_identity(identity)
    if isinstance(saved.get("learners"), dict):
        # as they compute, read as their runs are: a setting's older spelling (epsilon -inf, now
        # None) or a setting added since, at the value it had then, changes no cell; one this version
        # cannot read is kept as written, a difference like any other
        was["learners"] = resolved_learners(saved, as_written=True)
    # every key either holds: one written only when set (test_domain, demos_per_run) differs when
    # it goes back to its default too ("runs", in identities of old, was never part of one)
    differ = sorted(k for k in set(identity) | (set(saved) - {"runs"}) if was.get(k) != now.get(k))
    grown = set(differ) <= {"methods", "learners"} and grows(saved, identity, experiment.runs)
    return [_described(k, was, now) for k in differ], bool(differ) and grown


def _described(key: str, was: dict, now: dict) -> str:
    """``key`` of an identity that differs, with the methods (or learners) whose entries differ and
    in which fields, for the refusal: ``"methods (KNN: source)"``."""
    if key not in ("methods", "learners"):
        return key

    def by_name(identity: dict) -> dict:
        entries = identity.get(key) or {}
        if isinstance(entries, dict):
            return entries
        return {m.get("name", "?"): m for m in entries if isinstance(m, dict)}

    before, after = by_name(was), by_name(now)
    parts = []
    for name in [*before, *(n for n in after if n not in before)]:
        if name not in after or name not in before:
            parts.append(f"{name} {'removed' if name not in after else 'added'}")
        elif before[name] != after[name]:
            a, b = before[name], after[name]
            fields = sorted(f for f in {*a, *b} if a.get(f) != b.get(f)) if isinstance(a, dict) else []
            source = " (its package's code changed)" if "source" in fields else ""
            parts.append(f"{name}: {', '.join(fields) or 'order'}{source}")
    return f"{key} ({'; '.join(parts)})" if parts else f"{key} (their order)"


def output_state(out: str | Path, experiment: Experiment) -> str:
    """What OUT holds for ``experiment`` (``--check``): nothing yet, this experiment (and how many
    finished cells), or something a run would refuse."""
    out = Path(out)
    if not out.exists():
        return "does not exist yet"
    if (out / EXPERIMENT_FILE).is_file():
        differ, grown = recorded_differences(out.resolve(), experiment)
        if differ and not grown:
            return f"holds another experiment (it differs in: {', '.join(differ)}): a run would refuse it"
        cells = len(list((out / "cells").glob("*.json"))) if (out / "cells").is_dir() else 0
        grew = " (grown by new methods)" if grown else ""
        return f"holds this experiment{grew}, {cells} finished cell(s): a run resumes them"
    if not out.is_dir() or any(out.iterdir()):
        return "exists and holds no nirl-mj experiment: a run would refuse it"
    return "an empty directory"


def unspelled_identity(identity: dict) -> dict:
    """``identity`` without the learner changes as the file spells them (the experiment's
    ``[config]`` and each learner's ``config``): its resolved ``learners`` hold what they change, so
    a value the default already has, pinned in ``[config]`` or dropped from it, changes no cell."""
    learners = identity.get("learners", {})

    def unspelled(method: Any) -> Any:
        trains = isinstance(method, dict) and method.get("name") in learners
        return {k: v for k, v in method.items() if k != "config"} if trains else method

    methods = [unspelled(m) for m in identity.get("methods", [])]
    return {**{k: v for k, v in identity.items() if k != "config"}, "methods": methods}


def resolved_learners(saved: dict, skip_retired: bool = False, as_written: bool = False) -> dict[str, dict]:
    """A saved identity's learners, each resolved as its run records are (a setting added since it
    was saved takes the value it had then: ``LearnerConfig.from_record``). A learner this version
    cannot read is an error; with ``skip_retired``, one that holds a retired setting at a value that
    did something (``learn/config.py`` RETIRED) is left out instead: it cannot be the computation of
    any learner of this version; with ``as_written``, any such learner is kept as written (a
    difference from every learner of this version)."""
    from nirl_mj.learn.config import LearnerConfig, holds_retired

    resolved = {}
    for name, flat in saved.get("learners", {}).items():
        try:
            resolved[name] = LearnerConfig.from_record(flat).to_dict()
        except (TypeError, ValueError, AttributeError) as exc:
            if as_written:
                resolved[name] = flat
            elif not (skip_retired and holds_retired(flat)):
                raise ExperimentError(
                    f"the saved experiment's learners cannot be read by this version: {exc}"
                ) from None
    return resolved


def grows(saved: dict, identity: dict, runs: int) -> bool:
    """Whether ``identity`` is the ``saved`` experiment with methods added and nothing else
    changed: every saved method (and learner) is still there unchanged, and the new learners visit
    no arena the saved ones did not (so every run's test arenas, and so every finished cell, stay
    what they were: :func:`run_test_seeds`)."""
    from nirl_mj.experiments.training import planned_seeds
    from nirl_mj.learn.config import LearnerConfig

    new_methods = unspelled_identity(identity)["methods"]
    if any(m not in new_methods for m in unspelled_identity(saved)["methods"]):
        return False
    try:
        old, new = resolved_learners(saved), identity["learners"]
    except ExperimentError:  # a saved learner this version cannot read: not this experiment grown
        return False
    if any(new.get(name) != flat for name, flat in old.items()):
        return False
    added = [LearnerConfig.from_dict(new[n]) for n in new if n not in old]
    kept = [LearnerConfig.from_dict(flat) for flat in old.values()]
    for run in range(runs):
        seed = identity["seed"] + run
        seen = set().union(*(planned_seeds(c, seed) for c in kept))
        if any(not planned_seeds(c, seed) <= seen for c in added):
            return False
    return True


def demos_path(out: Path, experiment: Experiment, run: int) -> Path:
    """Where run ``run``'s demonstrations are: OUT/demos.npz, or OUT/demos/runNNN.npz per run."""
    return out / "demos" / f"run{run:03d}.npz" if experiment.demos_per_run else out / "demos.npz"


def demos_seed(experiment: Experiment, run: int) -> int:
    """The seed of run ``run``'s demonstrations (their arenas and the expert's randomness)."""
    return experiment.seed + run if experiment.demos_per_run else experiment.seed


def ensure_demos(
    out: Path, experiment: Experiment, workers: int, log: Callable[[str], None], run: int = 0
) -> Path:
    """Run ``run``'s demonstrations (:func:`demos_path`): ``experiment.demos`` episodes by its
    expert on its training task, seeded :func:`demos_seed` (made once, then re-used)."""
    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.experiments.demos import ExpertConfig, collect

    path, seed = demos_path(out, experiment, run), demos_seed(experiment, run)
    if path.is_file():
        return path
    which = f" for run {run}" if experiment.demos_per_run else ""
    n = experiment.demos
    log(f"demonstrations{which}: {n} episode{'s' * (n != 1)} by the {experiment.expert} expert (seed {seed})")
    trajectories = collect(experiment.task, ExpertConfig.named(experiment.expert, seed),
                           experiment.demos, seed, workers)  # fmt: skip
    path.parent.mkdir(parents=True, exist_ok=True)
    save_dataset(path, trajectories)
    return path


def prepare(
    experiment: Experiment, out: str | Path, execution: Execution, log: Callable[[str], None]
) -> tuple[Path, dict[tuple[str, int], RunJob]]:
    """Creates or re-opens OUT (refusing another experiment), makes the demonstrations once,
    and returns OUT (absolute) with every (method, run) job."""
    from nirl_mj.experiments.executors import default_workers

    if execution.restore:
        raise ExperimentError("--restore takes a published suite's cells: suites only (a comparison's: "
                              "docs/scripts/restore_cells.py)")  # fmt: skip
    execution.check_output(out)
    out = open_output(out, experiment, record=execution.writes_tables)
    if not execution.report_only:  # a report may run beside the experiment: then nothing is left over
        for folder in (out, out / "cells", out / "demos"):
            for leftover in leftover_temporaries(folder):
                leftover.unlink(missing_ok=True)  # written by a process killed while writing
    workers = execution.workers or default_workers()
    demos = {}
    for run in range(experiment.runs):
        if execution.report_only:  # reports what is there: a run whose demonstrations are missing has no cell
            if demos_path(out, experiment, run).is_file():
                demos[run] = demos_path(out, experiment, run)
        else:
            demos[run] = ensure_demos(out, experiment, workers, log, run)
    return out, run_jobs(experiment, out, demos)


def run_seed(experiment: Experiment, run: int) -> int:
    """The training seed of run ``run`` (also the seed of its test arenas)."""
    return experiment.seed + run


def run_test_seeds(experiment: Experiment, run: int, demo_seeds: set[int]) -> list[int]:
    """The test arenas of run ``run``, shared by every method: none was seen by any learner of it."""
    from nirl_mj.experiments.seeds import held_out_seeds
    from nirl_mj.experiments.training import planned_seeds

    seed = run_seed(experiment, run)
    seen = set(demo_seeds)
    for method in experiment.methods:
        if method.trains:
            seen |= planned_seeds(method.learner_config(experiment.config), seed)
    return held_out_seeds(seed, experiment.tests, seen, experiment.test_domain)


@dataclass(frozen=True)
class RunJob:
    """Method ``method``'s run ``run``: what it trains on, where, and the arenas it is tested on.

    ``config``: the resolved learner config of the training run, flat (``LearnerConfig.to_dict``;
    trainable methods); ``run_dir`` an absolute path (``OUT/runs/METHOD/SEED``); ``test_seeds`` the
    run's test arenas. ``trained_by`` names the method whose training run this job reads (its
    ``run_dir`` and ``config``; :func:`training_owners`)."""

    method: MethodSpec
    run: int
    seed: int
    task: TaskSpec
    demos_path: str
    run_dir: str
    config: dict
    test_seeds: tuple[int, ...]
    expert: str = "sensor"  # the demonstrator, DAgger's interactive expert
    trained_by: str = ""  # another method's training run, read instead of training again ("": its own)
    shared_run: bool = False  # another job reads this job's run, or this job another's: wait for its lock

    @property
    def policy(self) -> str:
        """Which policy of the training run the job tests: another method's run lends its last iterate."""
        return "last" if self.trained_by else "selected"


def run_jobs(experiment: Experiment, out: Path, demos: dict[int, Path]) -> dict[tuple[str, int], RunJob]:
    """Every (method, run) of the runs in ``demos``, by (method name, run index); ``demos[r]`` holds
    run r's demonstrations (one path for every run unless they are drawn per run)."""
    from nirl_mj.data.dataset import load_dataset

    owners = training_owners(experiment)
    sharing = {*owners, *(owner.name for owner in owners.values())}
    jobs, seeds_of = {}, {}
    for run, path in demos.items():
        if path not in seeds_of:
            seeds_of[path] = {t.arena_seed for t in load_dataset(path)}
        seeds = tuple(run_test_seeds(experiment, run, seeds_of[path]))
        seed = run_seed(experiment, run)
        for method in experiment.methods:
            owner = owners.get(method.name, method)
            config = owner.learner_config(experiment.config).to_dict() if method.trains else {}
            run_dir = out / "runs" / owner.name / str(seed)
            jobs[method.name, run] = RunJob(method, run, seed, experiment.task, str(path), str(run_dir),
                                            config, seeds, experiment.expert,
                                            trained_by=owner.name if owner is not method else "",
                                            shared_run=method.name in sharing)  # fmt: skip
    # a job that reads another's training run starts after every other job, so that on a few workers
    # that run is finished when it starts (on many, it waits for the run's lock: the same result)
    return dict(sorted(jobs.items(), key=lambda item: bool(item[1].trained_by)))


SHARED_SELECTIONS = ("demo_accuracy", "demo_balanced", "last")
"""The selection rules that drive no episode and read no arena: runs that differ in these alone train
the same, bit for bit, and keep the same policies (the last among them)."""


def training_owners(experiment: Experiment) -> dict[str, MethodSpec]:
    """The methods whose training is another listed method's, by name. An IRL method that reports its
    last iterate (``selection = "last"``) and whose resolved learner settings differ from another
    listed method's in the selection alone, by a rule of :data:`SHARED_SELECTIONS`, reads that
    method's training run: the first such method that selects by a rule, else the first before it
    that reports its last iterate too (``NIRL-last`` reads ``NIRL``'s run: it would train the same)."""
    settings = {m.name: m.learner_config(experiment.config).to_dict() for m in experiment.methods if m.trains}
    rule = {name: config.pop("selection") for name, config in settings.items()}
    owners: dict[str, MethodSpec] = {}
    for i, method in enumerate(experiment.methods):
        if rule.get(method.name) != "last":
            continue
        mine = settings[method.name]
        same = [m for m in experiment.methods if m is not method and settings.get(m.name) == mine
                and rule[m.name] in SHARED_SELECTIONS]  # fmt: skip
        by_rule = [m for m in same if rule[m.name] != "last"]
        earlier = [m for m in same if m in experiment.methods[:i] and m.name not in owners]
        if by_rule or earlier:
            owners[method.name] = (by_rule or earlier)[0]
    return owners


def policy_of(job: RunJob, train: bool = True) -> Callable:
    """The job's greedy policy on phi(s) (for ``kind = "expert"``: the demonstrator, an Agent that
    reads the whole observation), training (or resuming) it first if it trains
    (``nirl_mj.experiments.kinds``, the same for every kind); refused if its training saw one of the
    run's test arenas. With ``train=False`` (a sweep's tests) an IRL run that has not finished is an
    error; the other kinds as ``nirl_mj.experiments.kinds`` says."""
    from nirl_mj.experiments.kinds import KINDS

    trained = KINDS[job.method.kind](job, train)
    overlap = trained.seen & set(job.test_seeds)
    if overlap:
        raise RuntimeError(f"{job.method.name} run {job.run} ({job.run_dir}): test arenas seen in training: "
                           f"{sorted(overlap)}")  # fmt: skip
    return trained.policy


def evaluate_policy(policy: Callable, task: TaskSpec, seeds: tuple[int, ...], name: str) -> dict:
    """Success, collision, timeout and physics-error rates, SPL, SCT, mean path length (m) and test
    count of ``policy`` (:func:`policy_of`) on the arenas ``seeds`` of ``task`` (greedy, one episode
    each)."""
    from nirl_mj.experiments.evaluation import evaluate
    from nirl_mj.sim.task import make_env

    metrics, _ = evaluate(make_env(task), policy, seeds, name)
    return metrics


@dataclass(frozen=True)
class Execution:
    """Where cells run (``nirl_mj.experiments.executors.Executor``): executor name, workers, Ray address,
    further attempts of a failing cell."""

    executor: str = "local"
    workers: int | None = None
    address: str | None = None
    retries: int = 2
    report_only: bool = False  # run nothing: report the cells already finished (a partial table)
    reuse: str | None = None  # compare: an earlier output directory whose same cells are taken
    only: tuple[str, ...] = ()  # compare, suite: run these methods' cells only, report the others as stored
    points: tuple[str, ...] = ()  # suite, training axis: run these values' cells only, as ``only``
    writes_tables: bool = True  # False for a --report while the experiment runs (``one_writer``)
    restore: str | None = None  # suite: a published suite whose cells are taken first (``suite_restore``)

    def __post_init__(self) -> None:
        if self.retries < 0:
            raise ExperimentError(f"--retries {self.retries}: must be >= 0")
        for flag, given in (("--reuse", self.reuse), ("--restore", self.restore)):
            if given and self.report_only:
                raise ExperimentError(f"{flag} takes cells into a run; --report runs nothing: give one")
        if self.address and self.executor != "ray":
            raise ExperimentError("--address is the address of a Ray cluster: give --executor ray with it")
        from nirl_mj.experiments.executors import unused_workers

        if (problem := unused_workers(self.executor, self.workers, self.address)) is not None:
            raise ExperimentError(problem)

    def start(self, out: Path, log: Callable[[str], None] | None = None) -> CellRunner:
        """A runner storing finished cells in OUT/cells; use it as a context manager. ``log``
        hears of every cell that is run again, and why."""
        from nirl_mj.experiments.executors import CellStore, Executor

        return CellRunner(
            Executor(self.executor, self.workers, self.address, self.retries),
            CellStore(out / "cells", check=cell_problem),
            self.report_only,
            log=log,
        )

    def check_methods(self, experiment: Experiment) -> None:
        """Refuses an ``--only`` name that is not a method of ``experiment``, and a method to be run
        without the optional packages its kind needs (``kinds.PACKAGES``)."""
        from nirl_mj.experiments.kinds import missing_packages

        unknown = sorted(set(self.only) - {m.name for m in experiment.methods})
        if unknown:
            raise ExperimentError(f"--only {', '.join(unknown)}: not a method of {experiment.name} "
                                  f"({', '.join(m.name for m in experiment.methods)})")  # fmt: skip
        if self.report_only:
            return
        run = [m for m in experiment.methods if not self.only or m.name in self.only]
        short = {m.name: missing_packages(m.kind) for m in run}
        names = [name for name, missing in short.items() if missing]
        if names:
            raise ExperimentError(f"{', '.join(names)}: need the optional extra nirl-mj[gym] (no module "
                                  f"{short[names[0]][0]!r}): pip install -e '.[gym]', or run the other "
                                  "methods with --only")  # fmt: skip

    def check_output(self, out: str | Path) -> None:
        """With ``report_only``, OUT must hold a started experiment: there is nothing to report else."""
        if not self.report_only:
            return
        if not (Path(out) / EXPERIMENT_FILE).is_file():
            raise ExperimentError(
                f"--report: {out} holds no started experiment; run it first (without --report)"
            )
        if not any((Path(out) / name).exists() for name in ("demos.npz", "demos", "points")):
            raise ExperimentError(
                f"--report: {out} is still collecting its demonstrations; no cell has finished"
            )


def cell_problem(result, cell_id: str | None = None) -> str | None:
    """Why a stored cell cannot be a finished cell of an experiment (it is then computed again): not a
    JSON object, no evaluation in it (but a sweep's training cell), metrics out of their ranges
    (``outcomes.metrics_problem``), or, given the cell's id, the result of another method or run
    (``METHOD-runNNN``, as compare, suite and sweep name their cells)."""
    from nirl_mj.data.outcomes import holds_metrics, metrics_problem

    if not isinstance(result, dict):
        return "not a JSON object"
    if "iterations" in result:  # a sweep's training cell: no evaluation in it
        return None
    if not holds_metrics(result):
        return "holds no evaluation"
    if cell_id is not None and isinstance(result.get("method"), str) and isinstance(result.get("run"), int):
        own = f"{result['method']}-run{result['run']:03d}"
        if not re.search(rf"(^|\.){re.escape(own)}($|-n)", cell_id):
            return f"the result of {own}, not of {cell_id}"
    return metrics_problem(result)


@dataclass
class CellRunner:
    """An executor and the experiment's cell store."""

    executor: Any
    store: Any
    report_only: bool = False
    unfinished: int = 0  # cells neither finished nor failed (report_only)
    log: Callable[[str], None] | None = None

    def run(self, cells: list, on_done: Callable | None = None):
        """Runs the cells not stored yet; returns the executor's report (with ``report_only``: the
        stored cells only, nothing run)."""
        if not self.report_only:
            on_retry = (lambda cell_id, why: self.log(f"cell {cell_id}: {why}")) if self.log else None
            return self.executor.run(cells, self.store, on_done, on_retry)
        from nirl_mj.experiments.executors import Report

        report = Report()
        report.results = {c.id: r for c in cells if (r := self.store.load(c.id)) is not None}
        report.reused = list(report.results)
        self.unfinished += len(cells) - len(report.results)
        return report

    def run_only(self, cells: list, only: tuple[str, ...], on_start: Callable | None = None,
                 on_done: Callable | None = None, also: Callable | None = None):  # fmt: skip
        """Runs the cells of the methods in ``only`` (every cell if it is empty; a cell's method is its
        first argument's, a ``RunJob``) for which ``also(cell)`` holds (if given); the others' stored
        cells join the report as a ``--report`` shows them. ``on_start(cells to run, finished)``."""
        mine = [c for c in cells if (not only or c.args[0].method.name in only) and (also is None or also(c))]
        if on_start:
            on_start(len(mine), self.finished(mine))
        report = self.run(mine, on_done)
        others = [c for c in cells if c not in mine]
        report.results |= {c.id: r for c in others if (r := self.store.load(c.id)) is not None}
        self.unfinished += sum(c.id not in report.results for c in others)
        return report

    def finished(self, cells: list) -> int:
        """How many of ``cells`` are already stored (for a progress bar's start)."""
        return sum(self.store.load(c.id) is not None for c in cells)

    def __enter__(self) -> CellRunner:
        return self

    def __exit__(self, *exc) -> None:
        self.executor.close()


def failure_rows(failures: dict) -> list[dict]:
    """Failed cells as JSON rows (id, last error line, attempts, traceback)."""
    return [{"id": f.id, "error": f.error, "attempts": f.attempts, "traceback": f.traceback}
            for f in failures.values()]  # fmt: skip


def failed_section(summary: dict) -> str:
    """The Markdown list of failed cells and the count of unfinished ones (empty if none)."""
    text = ""
    if summary.get("unfinished"):
        text += (f"\n**Partial report** (`--report`, or rows left to another `--only`): "
                 f"{summary['unfinished']} cells are not finished yet; each row counts its finished runs "
                 "only.\n")  # fmt: skip
    if summary["failures"]:
        rows = "".join(f"\n- `{f['id']}` failed after {f['attempts']} attempt(s): {f['error']}"
                       for f in summary["failures"])  # fmt: skip
        text += (
            f"\nFailed cells (rerun the same command to try them again; a method fixed since is another "
            f"computation: a new --out with --reuse, docs/EXTENDING.md section 4):{rows}\n"
        )
    return text
