"""The main job (``nirl-mj run``): a built-in experiment of one run, and its report.

:func:`main_experiment` is an :class:`~nirl_mj.experiments.definition.Experiment`
like the files under ``tasks/``: one set of demonstrations (default: 30 by the
sensor-based expert), one run (seed ``seed``) of six methods, each tested on the
same held-out arenas. It runs through the shared protocol
(``nirl_mj.experiments.protocol``) and executors, so it resumes and
parallelises like ``compare``, with the same seeds (without retries: a failed cell is reported at
once). The methods:

- ``NIRL``: the learner (``variant``: a preset of ``nirl_mj.learn.config``);
- ``forward``, ``rule``, ``BC``: always forward, the rule on phi(s), behaviour cloning;
- ``control-progress``, ``control-constant``: the same loop with the learned reward
  replaced by the known progress reward (the inner loop's ceiling) and by a
  constant (what surviving alone earns).

OUT holds the protocol's files (``experiment.json``, ``demos.npz``,
``runs/METHOD/SEED/``, ``cells/``), every method's test episodes
(``tests/METHOD.npz``, the dataset format), ``results.json``, ``report.md`` with
PNG plots, and ``run.rrd`` (Rerun). ``report.md`` defines every term it uses and captions every figure;
its path column counts the successful tests only (:func:`success_path_length`, from the test
episodes: ``results.json`` keeps the stored metrics as they are). :func:`rewrite_report` writes the
report and its figures again from a finished job's files, running nothing.
"""

from __future__ import annotations

import json
import textwrap
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from nirl_mj.data.atomic import write_text
from nirl_mj.data.dataset import load_dataset, save_dataset
from nirl_mj.data.lock import writes
from nirl_mj.data.outcomes import sct
from nirl_mj.data.rundir import RUN_FILE, RunDir
from nirl_mj.data.trajectory import Trajectory, path_length
from nirl_mj.experiments.definition import Experiment, ExperimentError, MethodSpec, check_actions
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.executors import Cell
from nirl_mj.experiments.protocol import EXPERIMENT_FILE, Execution, RunJob, policy_of, prepare, run_seed
from nirl_mj.experiments.reads import VOCABULARY, method_reads, reads_text
from nirl_mj.inspect.figures import NIRL_PAPER, SCT_TEXT, SPL_TEXT, paths_plot, results_table, training_plots
from nirl_mj.inspect.recording import record_run
from nirl_mj.learn.bc import CloneSettings
from nirl_mj.learn.config import MATCHINGS
from nirl_mj.learn.inputs import NetworkInputs
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
    check_actions(methods, (task,), "nirl-mj run")
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
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(
            f"{out} is a file, not a directory: give the main job a directory of its own"
        )
    if resume and not (out.is_dir() and any(out.iterdir())):
        raise FileNotFoundError(f"nothing to resume in {out}: the main job had not started there; run the "
                                "same command without --resume")  # fmt: skip
    if out.exists() and any(out.iterdir()) and not resume:
        raise FileExistsError(
            f"{out} exists and is not empty; pass --resume to continue it, or choose another --out"
        )
    if (out / "nirl" / RUN_FILE).is_file() and not (out / EXPERIMENT_FILE).is_file():
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
    text = json.dumps({"task": task.name, "seed": experiment.seed, "results": results}, indent=1)
    if _finished(out, text):
        # A resume of a finished job: its report and recording (written last) already hold these
        # results; writing them again would take half a minute and change nothing.
        log(f"the main job in {out} had finished: its report and recording are kept as they are")
        return results
    paths = {ROWS[name]: load_dataset(out / "tests" / f"{name}.npz") for name in ROWS}
    write_text(out / "results.json", text)
    nirl = RunDir(jobs["NIRL", 0].run_dir)
    demo_trajectories = load_dataset(out / "demos.npz")
    write_report(out, nirl, experiment, results, paths, len(demo_trajectories))
    record_main_job(out, nirl, out / "run.rrd", overwrite=True)  # the job's own, made again from its files
    return results


def _finished(out: Path, results_text: str) -> bool:
    """Whether the main job in ``out`` was written to the end with these results: ``results.json``
    holds ``results_text`` and the report and the recording (written after it, in that order) exist."""
    stored = out / "results.json"
    return (
        stored.is_file()
        and stored.read_text() == results_text
        and (out / "report.md").is_file()
        and (out / "run.rrd").is_file()
    )


@writes("main job report")  # one writer of OUT
def rewrite_report(out: str | Path) -> Path:
    """Writes ``report.md`` and its figures again for the finished main job in ``out`` from what it
    stored (``experiment.json``, ``results.json``, the NIRL run, ``demos.npz``, ``tests/``), running
    nothing: a report written by an older nirl-mj, read with today's. Nothing else in ``out`` changes."""
    out = Path(out)
    saved = json.loads((out / EXPERIMENT_FILE).read_text())
    if saved.get("kind") != "main":
        raise ExperimentError(f"{out} holds no main job (experiment kind {saved.get('kind')!r})")
    task = specs.from_dict(saved["task"], f"{out / EXPERIMENT_FILE}: task")
    variant = next(m["variant"] for m in saved["methods"] if m["name"] == "NIRL")
    experiment = main_experiment(
        task, saved["seed"], variant, saved["demos"], saved["expert"], tests=saved["tests"]
    )
    results, paths = stored_results(out)
    nirl = RunDir(out / "runs" / "NIRL" / str(run_seed(experiment, 0)))
    return write_report(out, nirl, experiment, results, paths, len(load_dataset(out / "demos.npz")))


def stored_results(out: str | Path) -> tuple[dict, dict]:
    """A finished main job's stored results (``results.json``, by row) and test episodes
    (``tests/METHOD.npz``, by row)."""
    out = Path(out)
    results = json.loads((out / "results.json").read_text())["results"]
    return results, {ROWS[name]: load_dataset(out / "tests" / f"{name}.npz") for name in ROWS}


def report_table(out: str | Path) -> str:
    """The results table of the finished main job in ``out`` as its report gives it (the path of
    the successful tests and SCT from the test episodes; a reference's reads in bold)."""
    return results_table(report_rows(*stored_results(out)), reads_text)


def record_main_job(
    out: str | Path, nirl: RunDir, target: str | Path, focus: str | None = None, overwrite: bool = False
) -> Path:
    """Writes the recording of the main job in ``out`` to ``target``: its demonstrations, the training
    scalars and reward of its NIRL run ``nirl``, the first test episodes of every method tested so
    far (``tests/``: all of them once the job has finished) and the reward map in the first test
    arena (the one ``eval/nirl/000`` drove in). ``focus``: the episode the layout opens on
    (:func:`nirl_mj.inspect.blueprint.default_blueprint`). ``overwrite`` False: an existing ``target``
    is refused."""
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
        reward_of=ROWS["NIRL"],
        selected=nirl.read_record().get("selected_iteration"),
        overwrite=overwrite,
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


def success_path_length(trajectories: Sequence[Trajectory]) -> float | None:
    """The mean path driven (metres) over the episodes that reached the target; None when none did.
    A mean over every episode would make a policy that crashes early look efficient."""
    lengths = [path_length(t) for t in trajectories if t.success]
    return float(np.mean(lengths)) if lengths else None


def report_rows(results: dict, paths: dict) -> dict:
    """The report's rows: each stored result with ``success_path_length`` from its test episodes
    (``paths``, by row name), and ``sct`` computed from them where the result was stored before SCT.
    The stored files (``results.json``, ``cells/``) are not changed."""
    rows = {}
    for name, result in results.items():
        row, episodes = dict(result), paths.get(name)
        if episodes:
            row["success_path_length"] = success_path_length(episodes)
            row.setdefault("sct", sct(list(episodes)))
        rows[name] = row
    return rows


_BEST = "the iteration whose network predicts the demonstrated actions best in {}"
SELECTION_TEXT = {
    "demo_balanced": _BEST.format("balanced accuracy"),
    "demo_accuracy": _BEST.format("accuracy"),
    "last": "the last iteration",
    "validation": "the iteration with the highest success on validation arenas (a rule that reads the "
    "task's success: docs/ALGORITHM.md)",
}
"""How the report says each selection rule (``LoopConfig.selection``)."""

PATH_POLICIES = ("NIRL", "rule on phi(s)", "always forward")
"""The rows whose paths ``paths.png`` draws, in drawing order (the last on top)."""
PATH_ARENAS = 3
"""How many test arenas ``paths.png`` shows (the first ones)."""


def _and(names: Sequence[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return " and ".join([", ".join(names[:-1]), names[-1]] if len(names) > 1 else list(names))


def _inputs_text(inputs: NetworkInputs) -> str:
    """What a network's input code (``learn.inputs.NetworkInputs``) feeds it, in words."""
    if inputs.bearing:
        scaled = "the danger levels D divided by 7, " if inputs.scaled else ""
        return f"phi(s) with {scaled}the target's sector V replaced by its bearing as (cos, sin)"
    return "phi(s) with D divided by 7 and V by 9" if inputs.scaled else "phi(s) as it is"


def _bc_text(nirl_config: dict, variant: str) -> str:
    """What behaviour cloning of ``variant`` (``CloneSettings.of``, as ``experiments.kinds`` trains it)
    does, next to NIRL's network (``nirl_config``)."""
    bc = CloneSettings.of(variant)
    nirl_inputs = NetworkInputs(
        bool(nirl_config.get("input_scaling")), bool(nirl_config.get("input_bearing"))
    )
    same = nirl_config.get("hidden_units") == bc.hidden_units and nirl_inputs == bc.inputs
    whose = "NIRL's network here" if same else "the default NIRL's network"
    stop = (
        f"for the number of epochs (1 to {bc.epochs}) whose network predicts held-out demonstrations (every "
        f"{bc.held_out}th one, not fitted) best in balanced accuracy"
        if bc.held_out
        else f"for {bc.epochs} epochs"
    )
    weights = ", each action's pairs weighing alike (class-balanced)" if bc.balanced else ""
    return (
        f"*behaviour cloning* fits a network of the same form and inputs as {whose} "
        f"({_inputs_text(bc.inputs)}; {bc.hidden_units} hidden units) to the demonstrated actions: the "
        f"cross-entropy cost of eq. 15 on every output (1 for the demonstrated action, 0 for the "
        f"others){weights}, by minibatch gradient steps, {stop}. It learns no reward and drives no "
        "episode of its own."
    )


def _terms(experiment: Experiment, record: dict, rows: dict) -> str:
    """The report's definitions, each term once."""
    task, config = experiment.task, record["config"]
    budget, period = task.step_budget, task.control.decision_period
    straight = float(np.hypot(*(np.asarray(task.arena.target) - np.asarray(task.arena.start))))
    reads = [w for w in VOCABULARY if any(w in r.get("reads", ()) for r in rows.values())]
    targets = (f"{config['n_step']}-step Q-learning" if config.get("bootstrap") == "q" else "SARSA") + (
        f" targets (eq. 14) of the iteration's rewards, discount gamma = {config['gamma']:g}"
    )
    shown_cost = (
        "its value before the iteration's last full-batch gradient step"
        if config.get("replay_episodes") == 0
        else "its mean over the iteration's minibatch gradient steps"
    )
    rule = SELECTION_TEXT.get(record["selection"]["rule"], record["selection"]["rule"])
    if record["selection"]["rule"].startswith("demo_"):  # runs before 6c30c7d kept the first of equals
        latest = record["selection"].get("ties") == "latest"
        rule += f" (the {'latest' if latest else 'earliest'} on a tie)"
    matching = config.get("matching", "occupancy")
    alternatives = MATCHINGS.get(matching, matching)
    loss = f"{config['margin_loss']:g} " + (
        "where the learner's greedy action differs from the expert's, else 0"
        if matching == "paper"
        else "for an action other than the expert's, 0 for it"
    )
    return f"""**Terms** (units: metres, seconds; a decision is one action, held {period:g} s):

- *success*, *collision*, *timeout*: the fraction of the test episodes that reached the target (the
  robot's centre within {task.arena.target_radius:g} m of it), hit an obstacle or a wall, or used up the step
  budget ({budget} decisions, {budget * period:g} s) first.
- *path of successful tests (m)*: the mean length of the path driven, in metres, over the test
  episodes that reached the target only ("-": none did); the straight line from the start to the
  target is {straight:.1f} m long. Episodes that crashed or timed out are left out, so that a policy that
  crashes early does not look efficient.
- {SPL_TEXT}.
- {SCT_TEXT}; here a decision lasts {period:g} s and v = {task.control.speed:g} m/s.
- *tests*: the number of test episodes, one per held-out arena.
- *reads*: what a method reads, in training or in choosing its policy (`nirl_mj/experiments/reads.py`;
  a **reference** reads a task signal that a learner from demonstrations does not):
{chr(10).join(f"  - {w}: {VOCABULARY[w]}" for w in reads)}
- *iteration*: one pass of the NIRL paper's Algorithm 1, numbered from 0: {config["trajectories_per_episode"]}
  training episodes driven by the current network with Boltzmann exploration (eq. 8), the reward step and
  the network step. Figures 1-4 have iterations on their x axis.
- *margin t*: the result of the reward step, the max-margin step (Algorithm 1, lines 5-7; eq.
  12-13). The reward is r_theta(s, a) = theta^T f(s, a), f the state-action features, ||theta||_2 <= 1;
  the step minimises over theta the max-margin objective J(theta): the value of the best alternative
  to the expert (alternatives: {alternatives}) plus the margin loss l ({loss}), minus the expert's value,
  averaged over the demonstrated states. t = -min J(theta), in the reward's units: how far the best
  reward still puts the expert above every loss-augmented alternative; it falls towards 0 as the
  alternatives come to act as the expert does.
- *network cost J(Omega)*: the cost the network step minimises (eq. 15), Omega the network's weights:
  the cross-entropy between the network's value Q(s_t, a_t) of each taken action and its target
  (its {targets}), mean per pair (natural logarithms), plus an L2 penalty on the weights
  (lambda_2 = {config["net_l2"]:g}); Figure 2 shows {shown_cost}.
- *||dW1||_1*, *||dW2||_1*: the change in one iteration of the hidden and the output layer's weights,
  sum of absolute differences (the NIRL paper's ||W_new - W||_1).
- *demonstration accuracy*: the fraction of the demonstrated state-action pairs whose action the
  network's greedy policy takes; *balanced accuracy*: the mean over the actions of that fraction among
  each action's pairs (accuracy alone rewards always taking the most demonstrated action).
- *training success*: the fraction of the iteration's training episodes (exploring policy, simulated
  with the {config.get("train_drive", task.robot.drive)} drive) that reached the target.
- *selected policy*: the network that was tested, that of {rule}: here iteration
  {record["selected_iteration"]}, marked by a dashed vertical line in Figures 1-4."""


def _reflow(text: str, width: int = 100) -> str:
    """Markdown ``text`` with its paragraphs and list items re-wrapped at ``width`` (tables, images
    and headings as they are): the report reads as well in a terminal as rendered."""
    blocks = []
    for block in text.split("\n\n"):
        lines = block.split("\n")
        if lines[0].startswith(("|", "![", "#")):
            blocks.append(block)
            continue
        items: list[list[str]] = []
        for line in lines:
            if line.lstrip().startswith("- ") or not items:
                items.append([line])
            else:
                items[-1].append(line.strip())
        wrapped = []
        for item in items:
            indent = " " * (len(item[0]) - len(item[0].lstrip()))
            more = indent + ("  " if item[0].lstrip().startswith("- ") else "")
            joined = " ".join([item[0].strip(), *item[1:]])
            wrapped.append(
                textwrap.fill(joined, width, initial_indent=indent, subsequent_indent=more,
                              break_long_words=False, break_on_hyphens=False)
            )  # fmt: skip
        blocks.append("\n".join(wrapped))
    return "\n\n".join(blocks)


def write_report(
    out: Path, nirl: RunDir, experiment: Experiment, results: dict, paths: dict, n_demos: int
) -> Path:
    """``report.md`` with the results table, the terms it uses, and the figures with their captions.

    ``paths`` (row name -> that method's test episodes) give the path of the successful tests and,
    for results stored before SCT, SCT; ``results.json`` and the cells are left as they are."""
    task, variant, expert = experiment.task, experiment.methods[0].variant, experiment.expert
    record = nirl.read_record()
    selected = record["selected_iteration"]
    metrics = nirl.read_metrics()
    training_plots(metrics, out, selected=selected)
    validated = any(row.get("validation_success") is not None for row in metrics)
    validation = ", and the greedy policy's success on validation arenas" if validated else ""
    drawn = [name for name in PATH_POLICIES if paths.get(name)]
    paths_plot(out / "paths.png", {name: paths[name] for name in drawn}, PATH_ARENAS)
    shown = min([PATH_ARENAS, *(len(paths[name]) for name in drawn)])
    rows = report_rows(results, paths)
    config = record["config"]
    matching = config.get("matching", "occupancy")
    guide = _guide_note(task)
    tests = next(iter(results.values()))["tests"]
    iterations = record["iterations"]
    mark = f"the dashed vertical line marks the selected policy (iteration {selected})"
    arena = f"{task.arena.size[0]:g} m x {task.arena.size[1]:g} m"
    (x0, y0), (x1, y1) = task.arena.start, task.arena.target
    bc_text = _bc_text(config, next(m.variant for m in experiment.methods if m.name == "BC"))
    text = f"""# nirl-mj run: {task.name}

A simulated Festo Robotino (three omniwheels, nine range sensors) learns to drive to a target among
obstacles from demonstrations, by Neural Inverse Reinforcement Learning (NIRL) as in *the NIRL paper*:
{NIRL_PAPER}. Its
equations (eq. 8, 12-15), Algorithm 1 and figures (Fig. 4a, 4b, 5, 7) are quoted by their numbers in
that paper. Every policy acts on phi(s), the paper's 16 state features: the danger level D (0-7) of
seven range sensors, the sensor sector V (1-9) that holds the target's bearing, whether the target is
within sensing range and in sight I, and whether each of the seven sensors sees a wall U; and
chooses one of six actions (forward, turn 30 or 60 degrees left or right while driving, backward).

**Set-up.** {n_demos} demonstrations by the {expert} expert; NIRL ({variant} variant; the margin's
alternatives: {MATCHINGS.get(matching, matching)}), {iterations} iterations (numbered 0 to {iterations - 1});
selected policy: iteration {selected}; seed {record["seed"]}. Evaluation: greedy policies on {tests}
held-out arenas of `{task.name}` ({arena}, {task.arena.static_obstacles} static obstacles, start
({x0:g}, {y0:g}), target ({x1:g}, {y1:g}),
{task.control.speed:g} m/s, {task.robot.drive} drive), none of which was seen in demonstrations, training
or validation.{guide}

{results_table(rows, reads_text)}

The methods: *NIRL* learns a reward from the demonstrations and a network's policy on it; *always
forward* (action "forward" whatever the state) is what a collapsed learner becomes; the *rule on phi(s)*,
written by hand (turn towards V along the safest way, back off when boxed in), shows what the 16
features can carry; {bc_text} The controls run the same NIRL loop with its learned per-step
reward replaced by the task's progress towards the target (a reference: it reads the task's reward)
and by a constant, both keeping the learned value of an episode's end: the constant control shows what
the learned per-step reward adds to that end value. NIRL reads the demonstrations, phi(s) and that its
own episodes ended, behaviour cloning the demonstrations and phi(s); neither reads the task's reward,
outcome or success.

{_terms(experiment, record, rows)}

![margin t per iteration](margin.png)

*Figure 1. The margin t of the reward step (y, reward units) in each iteration (x) of the NIRL run:
the NIRL paper's Fig. 4a; {mark}.*

![network cost J(Omega) per iteration](cost.png)

*Figure 2. The network cost J(Omega) (y, mean cross-entropy per pair plus the L2 penalty, natural
logarithms) in each iteration (x): the NIRL paper's Fig. 4b; {mark}.*

![change of the weights per iteration](weights.png)

*Figure 3. The change of the hidden layer's weights ||dW1||_1 and of the output layer's ||dW2||_1 (y,
sum of absolute differences) in each iteration (x): the NIRL paper's Fig. 7; {mark}.*

![learning curves](training.png)

*Figure 4. Learning curves (y, fractions from 0 to 1) per iteration (x): training success and the
demonstration accuracy and balanced accuracy of the network's greedy policy{validation}; {mark}. A
network that always drives forward scores the demonstrations' share of "forward" in accuracy and
1/K in balanced accuracy, K the number of actions demonstrated.*

![paths in {shown} test arenas](paths.png)

*Figure 5. Paths of {_and(drawn)} in the first {shown} test arenas, seen from above (x and y
in metres, the whole {arena} arena; grey: obstacles, darker grey: walls; open circle: start, star:
target). Each policy has its own colour and line; a path's end marker says how it ended (circle:
reached the target, X: collided, square: timed out); each legend gives every path's outcome and length
in metres. The NIRL paper's Fig. 5.*

Files: `results.json`, `demos.npz`, `{nirl.path.relative_to(out)}/` (the NIRL run: run.json, metrics.jsonl,
checkpoint.npz, policy.npz, reward.json), `runs/` (every trained method), `tests/` (every method's test
episodes, the dataset format), `run.rrd` (open with `rerun run.rrd`).
"""
    write_text(out / "report.md", _reflow(text))
    return out / "report.md"
