"""The main job: demonstrations -> NIRL -> held-out evaluation next to the references -> report.

Stages write into RUN_DIR, each atomically, and ``resume=True`` skips the
finished ones (training resumes from its checkpoint):

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
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from nirl_mj import spec as specs
from nirl_mj.atomic import write_text
from nirl_mj.demos import ExpertConfig, collect
from nirl_mj.evaluate import evaluate, held_out_seeds
from nirl_mj.learn.bc import behaviour_cloning
from nirl_mj.learn.nirl import NirlConfig
from nirl_mj.learn.train import load_policy, read_run, train
from nirl_mj.policies import always_forward, rule_policy
from nirl_mj.report import paths_plot, read_metrics, results_table, training_plots
from nirl_mj.trajectory import load_dataset, save_dataset


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
    for name, (folder, cfg) in runs.items():
        run_dir = out / folder
        finished = (run_dir / "policy.npz").exists()
        if not finished:
            log(f"training {name} ({cfg.episodes} iterations)")
            train(run_dir, task, demos_path, cfg, seed, resume=(run_dir / "checkpoint.npz").exists(),
                  on_metrics=on_metrics if folder == "nirl" else None)  # fmt: skip

    seen = {t.arena_seed for t in demo_trajectories}
    for folder, _ in runs.values():
        record = read_run(out / folder)
        seen |= set(record.get("validation_seeds", [])) | set(record.get("train_seeds", []))
    test_seeds = held_out_seeds(seed, tests, seen)
    policies = {
        "NIRL": load_policy(out / "nirl")[0],
        "always forward": always_forward,
        "rule on phi(s)": rule_policy,
        "behaviour cloning": behaviour_cloning(demo_trajectories, seed=seed),
        "control: SARSA on progress": load_policy(out / "control_progress")[0],
        "control: constant reward": load_policy(out / "control_constant")[0],
    }
    from nirl_mj.task import make_env

    env = make_env(task)
    results, paths = {}, {}
    for name, policy in policies.items():
        log(f"evaluating {name} on {tests} held-out arenas")
        results[name], paths[name] = evaluate(env, policy, test_seeds, name)
    write_text(
        out / "results.json", json.dumps({"task": task.name, "seed": seed, "results": results}, indent=1)
    )
    write_report(out, task, variant, results, paths, len(demo_trajectories), expert)
    from nirl_mj.record import record_run

    record_run(out / "run.rrd", demo_trajectories, read_metrics(out / "nirl"), paths)
    return results


def write_report(
    out: Path, task: specs.TaskSpec, variant: str, results: dict, paths: dict, n_demos: int, expert: str
) -> Path:
    """``report.md`` with the results table and the figures."""
    training_plots(out / "nirl", out)
    paths_plot(out / "paths.png", {k: paths[k] for k in ("NIRL", "rule on phi(s)", "always forward")})
    record = read_run(out / "nirl")
    text = f"""# nirl-mj run: {task.name}

{n_demos} demonstrations by the {expert} expert; NIRL ({variant} variant), {record["iterations"]} iterations,
selected policy: iteration {record["selected_iteration"]} (rule: {record["config"]["selection"]}); seed
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
