"""The main job: demonstrations -> NIRL -> held-out evaluation next to the references -> report.

Stages write into RUN_DIR, each atomically, and ``resume=True`` skips the
finished ones (training resumes from its checkpoint). The three trainings and
the six evaluations are independent jobs, run on ``workers`` processes; each
seeds itself, so the numbers do not depend on ``workers``:

- ``demos.npz``: the demonstrations (default: 30 by the sensor-based expert);
- ``nirl/``: the NIRL training run (``nirl-mj train``'s layout);
- ``control_progress/``, ``control_constant/``: the same loop with the learned
  reward replaced by the known progress reward (the inner loop's ceiling) and
  by a constant (what surviving alone earns);
- ``results.json``: held-out success of NIRL and of every reference (always
  forward, the rule on phi(s), behaviour cloning, the two controls, the
  demonstrator's own policy where it is one on phi);
- ``report.md`` with PNG plots, and ``run.rrd`` (Rerun).
"""

from __future__ import annotations

import json
import multiprocessing
import threading
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

from nirl_mj.data.atomic import write_text
from nirl_mj.data.dataset import load_dataset, save_dataset
from nirl_mj.experiments.demos import ExpertConfig, collect
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.seeds import domain_seeds, held_out_seeds
from nirl_mj.experiments.training import ensure_trained, load_policy, read_run, validation_seeds
from nirl_mj.experts.policies import always_forward, rule_policy
from nirl_mj.inspect.figures import paths_plot, read_metrics, results_table, training_plots
from nirl_mj.learn.bc import behaviour_cloning
from nirl_mj.learn.loop import NirlConfig
from nirl_mj.sim import spec as specs


def main_job(
    out: str | Path,
    task: specs.TaskSpec,
    seed: int = 0,
    variant: str = "default",
    demos: int = 30,
    expert: str = "sensor",
    episodes: int | None = None,
    tests: int = 100,
    workers: int = 1,
    resume: bool = False,
    log: Callable[[str], None] = print,
    on_metrics: Callable | None = None,
) -> dict:
    """Runs (or resumes) the whole pipeline in ``out``; returns the evaluation results."""
    out = Path(out)
    if out.exists() and any(out.iterdir()) and not resume:
        raise FileExistsError(
            f"{out} exists and is not empty; pass --resume to continue it, or choose another --out"
        )
    out.mkdir(parents=True, exist_ok=True)

    demos_path = out / "demos.npz"
    if demos_path.exists():
        log(f"demonstrations: re-using {demos_path}")
        demo_trajectories = load_dataset(demos_path)
    else:
        log(f"demonstrations: {demos} episodes by the {expert} expert")
        demo_trajectories = collect(task, ExpertConfig(expert, seed=seed), demos, seed, workers)
        save_dataset(demos_path, demo_trajectories)

    config = NirlConfig.named(variant, **({"episodes": episodes} if episodes else {}))
    runs = {
        "NIRL": ("nirl", config),
        "control: SARSA on progress": ("control_progress", replace(config, reward_source="progress")),
        "control: constant reward": ("control_constant", replace(config, reward_source="constant")),
    }
    # The test arenas: test-domain seeds none of which was seen in the demonstrations,
    # the training rollouts or the validation (the planned seeds of every run).
    k = config.trajectories_per_episode
    seen = {t.arena_seed for t in demo_trajectories}
    seen |= set(validation_seeds(config, seed))
    seen |= set(domain_seeds("train", seed, config.episodes * k))
    test_seeds = held_out_seeds(seed, tests, seen)
    jobs = [
        _Job(name, task, test_seeds, seed, out / folder, demos_path, cfg)
        for name, (folder, cfg) in runs.items()
    ]
    jobs += [_Job(name, task, test_seeds, seed) for name in ("always forward", "rule on phi(s)")]
    jobs += [_Job("behaviour cloning", task, test_seeds, seed, demos_path=demos_path)]
    results, paths = {}, {}
    for job, (metrics, trajectories) in _run_jobs(jobs, workers, log, on_metrics):
        results[job.name], paths[job.name] = metrics, trajectories
    order = ["NIRL", "always forward", "rule on phi(s)", "behaviour cloning", *list(runs)[1:]]
    results, paths = {n: results[n] for n in order}, {n: paths[n] for n in order}
    write_text(
        out / "results.json", json.dumps({"task": task.name, "seed": seed, "results": results}, indent=1)
    )
    write_report(out, task, variant, results, paths, len(demo_trajectories), expert)
    from nirl_mj.inspect.recording import record_run

    record_run(out / "run.rrd", demo_trajectories, read_metrics(out / "nirl"), paths,
               reward=out / "nirl" / "reward.json", map_arena=(task, test_seeds[0]))  # fmt: skip
    return results


@dataclass(frozen=True)
class _Job:
    """One row of the results: train (if ``config``) or build the policy, then evaluate it."""

    name: str
    task: specs.TaskSpec
    test_seeds: list[int]
    seed: int
    run_dir: Path | None = None
    demos_path: Path | None = None
    config: NirlConfig | None = None

    def policy(self) -> Callable:
        if self.config is not None:
            ensure_trained(self.run_dir, self.task, self.demos_path, self.config, self.seed)
            return load_policy(self.run_dir)[0]
        if self.name == "behaviour cloning":
            return behaviour_cloning(load_dataset(self.demos_path), seed=self.seed)
        return {"always forward": always_forward, "rule on phi(s)": rule_policy}[self.name]

    def __call__(self) -> tuple[dict, list]:
        import torch

        from nirl_mj.sim.task import make_env

        torch.set_num_threads(1)
        return evaluate(make_env(self.task), self.policy(), self.test_seeds, self.name)


def _run_job(job: _Job) -> tuple[dict, list]:
    return job()


def _run_jobs(jobs: list[_Job], workers: int, log: Callable[[str], None], on_metrics: Callable | None):
    """Yields (job, its result) as jobs finish; with ``workers`` > 1 in spawned processes.

    Every job seeds itself, so the results do not depend on ``workers``. Training
    progress reaches ``on_metrics`` (one metrics row, a dict, per finished
    iteration of any run) from the runs' metrics.jsonl files."""
    progress = _MetricsFollower([j.run_dir for j in jobs if j.run_dir is not None], on_metrics)
    if workers <= 1:
        for job in jobs:
            log(f"{'training and evaluating' if job.config else 'evaluating'} {job.name}")
            with progress.following():
                yield job, job()
        return
    context = multiprocessing.get_context("spawn")  # no inherited MuJoCo or GL state
    with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=context) as pool:
        pending = {pool.submit(_run_job, job): job for job in jobs}
        log(f"training and evaluating {len(jobs)} policies in {min(workers, len(jobs))} processes")
        while pending:
            done, _ = wait(pending, timeout=1.0, return_when=FIRST_COMPLETED)
            progress.poll()
            for future in done:
                job = pending.pop(future)
                log(f"finished {job.name}")
                yield job, future.result()
        progress.poll()


class _MetricsFollower:
    """Passes new lines of the runs' metrics.jsonl files to ``on_metrics``."""

    def __init__(self, run_dirs: list[Path], on_metrics: Callable | None) -> None:
        self.files = [d / "metrics.jsonl" for d in run_dirs]
        self.seen = dict.fromkeys(self.files, 0)
        self.on_metrics = on_metrics

    def poll(self) -> None:
        if self.on_metrics is None:
            return
        for path in self.files:
            lines = path.read_text().splitlines() if path.exists() else []
            for line in lines[self.seen[path] :]:
                try:
                    self.on_metrics(json.loads(line))
                except json.JSONDecodeError:  # a line being written: read it next time
                    break
                self.seen[path] += 1

    @contextmanager
    def following(self):
        """Polls in a thread while the caller works (the in-process path)."""
        stop = threading.Event()

        def loop() -> None:
            while not stop.wait(0.5):
                self.poll()

        thread = threading.Thread(target=loop, daemon=True)
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join()
            self.poll()


def write_report(
    out: Path, task: specs.TaskSpec, variant: str, results: dict, paths: dict, n_demos: int, expert: str
) -> Path:
    """``report.md`` with the results table and the figures."""
    training_plots(out / "nirl", out)
    paths_plot(out / "paths.png", {k: paths[k] for k in ("NIRL", "rule on phi(s)", "always forward")})
    record = read_run(out / "nirl")
    text = f"""# nirl-mj run: {task.name}

{n_demos} demonstrations by the {expert} expert; NIRL ({variant} variant), {record["iterations"]} iterations,
selected policy: iteration {record["selected_iteration"]} (rule: {record["selection"]["rule"]}); seed
{record["seed"]}. Evaluation: greedy policies on {next(iter(results.values()))["tests"]} held-out arenas of
`{task.name}` ({task.robot.drive} drive), none of which was seen in demonstrations, training or validation.

{results_table(results)}

The references: *always forward* is what a collapsed learner becomes; the *rule on phi(s)* shows what the
16 features can carry; *behaviour cloning* trains the same network on the demonstrations; the controls run
the same NIRL loop with the learned reward replaced by the known progress reward (the inner loop's ceiling)
and by a constant (surviving alone is rewarded: this shows what the learned reward itself adds).

![margin](margin.png) ![cost](cost.png)

![weights](weights.png) ![training](training.png)

![paths](paths.png)

Files: `results.json`, `demos.npz`, `nirl/` (metrics.jsonl, checkpoint, policy.npz, reward.json),
`run.rrd` (open with `rerun run.rrd`).
"""
    write_text(out / "report.md", text)
    return out / "report.md"
