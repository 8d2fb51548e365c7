"""The main job (``nirl-mj run``): a built-in experiment of one run, and its report.

:func:`main_experiment` is an :class:`~nirl_mj.experiments.definition.Experiment`
like the files under ``tasks/``: one set of demonstrations (default: 30 by the
sensor-based expert), one run (seed ``seed``) of six methods, each tested on the
same held-out arenas. It runs through the shared protocol
(``nirl_mj.experiments.protocol``) and executors, so it resumes, retries and
parallelises like ``compare``, with the same seeds. The methods:

- ``NIRL``: the learner (``variant``: a preset of ``nirl_mj.learn.config``);
- ``forward``, ``rule``, ``BC``: always forward, the rule on phi(s), behaviour cloning;
- ``control-progress``, ``control-constant``: the same loop with the learned reward
  replaced by the known progress reward (the inner loop's ceiling) and by a
  constant (what surviving alone earns).

OUT holds the protocol's files (``experiment.json``, ``demos.npz``,
``runs/METHOD/SEED/``, ``cells/``), every method's test episodes
(``tests/METHOD.npz``, the dataset format), ``results.json``, ``report.md`` with
PNG plots, and ``run.rrd`` (Rerun).
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from nirl_mj.data.atomic import write_text
from nirl_mj.data.dataset import load_dataset, save_dataset
from nirl_mj.data.lock import writes
from nirl_mj.data.rundir import RunDir
from nirl_mj.experiments.definition import Experiment, ExperimentError, MethodSpec
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.executors import Cell
from nirl_mj.experiments.protocol import Execution, RunJob, policy_of, prepare
from nirl_mj.experiments.reads import method_reads
from nirl_mj.inspect.figures import paths_plot, results_table, training_plots
from nirl_mj.inspect.recording import record_run
from nirl_mj.learn.config import MATCHINGS
from nirl_mj.learn.reward import RewardModel
from nirl_mj.sim import spec as specs
from nirl_mj.sim.task import make_env

ROWS = {
    "NIRL": "NIRL",
    "forward": "always forward",
    "rule": "rule on phi(s)",
    "BC": "behaviour cloning",
    "control-progress": "control: progress reward",
    "control-constant": "control: constant reward",
}
"""Method name (cells, run directories) -> its row in the results and the report, in report order."""


START_ORDER = ("control-constant", "NIRL", "control-progress")
"""The cells that start first, longest first: every training and test episode of the constant-reward
control runs to the step budget (measured 291 s against about 125 s for NIRL and the progress
control on 2 cores), so it starts at once and the others share the second worker meanwhile. The
order changes no result: the cells are independent."""


def main_experiment(
    task: specs.TaskSpec,
    seed: int = 0,
    variant: str = "default",
    demos: int = 30,
    expert: str = "sensor",
    episodes: int | None = None,
    tests: int = 100,
) -> Experiment:
    """The main job as an experiment; ``episodes`` (learner iterations) None keeps the variant's."""

    def learner(name: str, **config) -> MethodSpec:
        return MethodSpec(name, "irl", variant, "nirl", config)

    methods = (  # the trainings first: they take longest
        learner("NIRL"),
        learner("control-progress", reward_source="progress"),
        learner("control-constant", reward_source="constant"),
        MethodSpec("forward", "forward"),
        MethodSpec("rule", "rule"),
        MethodSpec("BC", "bc"),
    )
    return Experiment(
        kind="main", name="main", source="nirl-mj run", description=f"the main job on {task.name}",
        task=task, test_task=task, seed=seed, runs=1, tests=tests, methods=methods, expert=expert,
        demos=demos, config={"episodes": episodes} if episodes else {}, paper={}, strip=None,
        obstacles=(), speeds=(), quick=False,
    )  # fmt: skip


def main_cell(job: RunJob, test_task: specs.TaskSpec, paths_file: str) -> dict:
    """Trains (if it trains) and tests one method; keeps its test episodes in ``paths_file``."""
    metrics, trajectories = evaluate(
        make_env(test_task), policy_of(job), job.test_seeds, ROWS[job.method.name]
    )
    Path(paths_file).parent.mkdir(parents=True, exist_ok=True)
    save_dataset(paths_file, trajectories, overwrite=True)  # a retried cell writes its episodes again
    return metrics


@writes("main job")  # one writer of OUT
def main_job(
    out: str | Path,
    experiment: Experiment,
    workers: int = 1,
    resume: bool = False,
    log: Callable[[str], None] = print,
    on_metrics: Callable[[dict], None] | None = None,
) -> dict:
    """Runs (or resumes) the main job ``experiment`` (:func:`main_experiment`) in ``out``; returns the
    evaluation results by row name.

    ``on_metrics`` receives every training run's metrics rows (dicts) as iterations finish."""
    out = Path(out)
    if out.exists() and any(out.iterdir()) and not resume:
        raise FileExistsError(
            f"{out} exists and is not empty; pass --resume to continue it, or choose another --out"
        )
    if (out / "nirl" / "run.json").is_file() and not (out / "experiment.json").is_file():
        raise ExperimentError(
            f"{out} is a main job of an older nirl-mj (its NIRL run is in nirl/; now runs/NIRL/SEED): it "
            "cannot be resumed; run the main job in a new --out (the old run still evaluates: "
            f"nirl-mj eval --run {out}/nirl)"
        )
    task = experiment.task
    execution = Execution("serial" if workers == 1 else "local", workers, retries=0)
    out, jobs = prepare(experiment, out, execution, log)
    cells = [
        Cell(name, main_cell, (job, experiment.test_task, str(out / "tests" / f"{name}.npz")))
        for (name, _), job in jobs.items()
    ]
    cells.sort(key=lambda cell: START_ORDER.index(cell.id) if cell.id in START_ORDER else len(START_ORDER))
    trained = [RunDir(job.run_dir) for job in jobs.values() if job.method.trains]
    log(f"training and testing {len(cells)} methods ({execution.executor}, {workers} worker(s))")
    with follow_metrics(trained, on_metrics), execution.start(out, log) as runner:
        report = runner.run(cells)
    if report.failures:
        failed = "; ".join(f"{f.id}: {f.error}" for f in report.failures.values())
        raise RuntimeError(f"the main job failed ({failed}); rerun with --resume to retry")
    methods = {m.name: m for m in experiment.methods}
    results = {ROWS[name]: {**report.results[name], "reads": method_reads(methods[name], experiment.config)}
               for name in ROWS}  # fmt: skip
    paths = {ROWS[name]: load_dataset(out / "tests" / f"{name}.npz") for name in ROWS}
    write_text(
        out / "results.json",
        json.dumps({"task": task.name, "seed": experiment.seed, "results": results}, indent=1),
    )
    nirl = RunDir(jobs["NIRL", 0].run_dir)
    demo_trajectories = load_dataset(out / "demos.npz")
    write_report(out, nirl, experiment, results, paths, len(demo_trajectories))
    record_main_job(out, nirl, out / "run.rrd")
    return results


def record_main_job(out: str | Path, nirl: RunDir, target: str | Path, focus: str | None = None) -> Path:
    """Writes the recording of the main job in ``out`` to ``target``: its demonstrations, the training
    scalars and reward of its NIRL run ``nirl``, the first test episodes of every method tested so
    far (``tests/``: all of them once the job has finished) and the reward map in the first test
    arena (the one ``eval/nirl/000`` drove in). ``focus``: the episode the layout opens on
    (:func:`nirl_mj.inspect.blueprint.default_blueprint`)."""
    out = Path(out)
    files = {ROWS[name]: out / "tests" / f"{name}.npz" for name in ROWS}
    paths = {row: load_dataset(file) for row, file in files.items() if file.is_file()}
    first_test = paths[ROWS["NIRL"]][0]
    return record_run(
        target,
        load_dataset(out / "demos.npz"),
        nirl.read_metrics(),
        paths,
        reward=RewardModel.from_dict(nirl.read_reward()),
        map_arena=(specs.from_dict(first_test.task, "test episode task"), first_test.arena_seed),
        focus=focus,
    )


@contextmanager
def follow_metrics(runs: list[RunDir], on_metrics: Callable[[dict], None] | None) -> Iterator[None]:
    """Passes the runs' new metrics rows to ``on_metrics`` from a thread while the caller works
    (the rows are written by whichever process trains)."""
    if on_metrics is None:
        yield
        return
    seen = dict.fromkeys(runs, 0)

    def poll() -> None:
        for run in runs:
            rows = run.read_metrics()
            for row in rows[seen[run] :]:
                on_metrics(row)
            seen[run] = len(rows)

    stop = threading.Event()

    def loop() -> None:
        while not stop.wait(0.5):
            poll()

    thread = threading.Thread(target=loop, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
        poll()


def _guide_note(task: specs.TaskSpec) -> str:
    """A sentence for the report when phi's sector V is not the paper's (``sensing.guide``)."""
    if task.sensing.guide == "target":
        return ""
    return (
        "\nphi's sector V reads the robot's memory: the target's sector, or while stuck its memory's escape "
        'waypoint (`sensing.guide = "memory"`, a departure from the paper; docs/TASKS.md).'
    )


def write_report(
    out: Path, nirl: RunDir, experiment: Experiment, results: dict, paths: dict, n_demos: int
) -> Path:
    """``report.md`` with the results table and the figures."""
    task, variant, expert = experiment.task, experiment.methods[0].variant, experiment.expert
    training_plots(nirl.read_metrics(), out)
    paths_plot(out / "paths.png", {k: paths[k] for k in ("NIRL", "rule on phi(s)", "always forward")})
    record = nirl.read_record()
    matching = record["config"].get("matching", "occupancy")
    guide = _guide_note(task)
    text = f"""# nirl-mj run: {task.name}

{n_demos} demonstrations by the {expert} expert; NIRL ({variant} variant, the margin's alternatives:
{MATCHINGS.get(matching, matching)}), {record["iterations"]} iterations,
selected policy: iteration {record["selected_iteration"]} (rule: {record["selection"]["rule"]}); seed
{record["seed"]}. Evaluation: greedy policies on {next(iter(results.values()))["tests"]} held-out arenas of
`{task.name}` ({task.robot.drive} drive), none of which was seen in demonstrations, training or
validation.{guide}

{results_table(results)}

The references: *always forward* is what a collapsed learner becomes; the *rule on phi(s)* shows what the
16 features can carry; *behaviour cloning* trains a network of NIRL's inputs and width on the
demonstrations (class-balanced loss, stopped early on held-out demonstrations); the controls run
the same NIRL loop with its learned per-step reward replaced by the task's progress reward (a reference:
it reads the task's reward) and by a constant, both keeping the learned value of an episode's end: the
constant control shows what the learned per-step reward adds to that end value. The last column says what
each method reads (`nirl_mj/experiments/reads.py`): NIRL reads the demonstrations, phi(s) and that its
own episodes ended, behaviour cloning the demonstrations and phi(s); neither reads the task's reward,
outcome or success.

![margin](margin.png) ![cost](cost.png)

![weights](weights.png) ![training](training.png)

![paths](paths.png)

Files: `results.json`, `demos.npz`, `{nirl.path.relative_to(out)}/` (the NIRL run: run.json, metrics.jsonl,
checkpoint.npz, policy.npz, reward.json), `runs/` (every trained method), `tests/` (every method's test
episodes, the dataset format), `run.rrd` (open with `rerun run.rrd`).
"""
    write_text(out / "report.md", text)
    return out / "report.md"
