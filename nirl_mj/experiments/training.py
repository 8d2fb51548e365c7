"""Training runs on disk: a run directory, a checkpoint every iteration, exact resume.

RUN_DIR holds ``run.json`` (task, variant, configuration, seed, demonstrations,
the arena seeds used), ``metrics.jsonl`` (one line per iteration),
``checkpoint.npz`` (the whole learner state, written atomically after every
iteration), and at the end ``policy.npz`` (the selected and the last network)
and ``reward.json`` (theta of the selected iteration, by component name). An
interrupted run (Ctrl-C, a crash, a killed machine) continues from its last
checkpoint with ``resume=True`` and ends with exactly the weights an
uninterrupted run would have.
"""

from __future__ import annotations

import json
import os
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from nirl_mj.data.atomic import write_npz, write_text
from nirl_mj.data.dataset import load_dataset
from nirl_mj.experiments.seeds import domain_seeds
from nirl_mj.learn import network
from nirl_mj.learn.loop import Metrics, Nirl, NirlConfig, greedy_policy
from nirl_mj.learn.reward import RewardModel
from nirl_mj.sim import spec as specs

RUN_FILE, METRICS_FILE, CHECKPOINT_FILE = "run.json", "metrics.jsonl", "checkpoint.npz"
POLICY_FILE, REWARD_FILE = "policy.npz", "reward.json"


class RunError(ValueError):
    """A run directory is missing, foreign, corrupted or would be overwritten."""


def read_run(run_dir: str | os.PathLike) -> dict:
    """The run's ``run.json``, with a clear error if RUN_DIR is not a run."""
    path = Path(run_dir) / RUN_FILE
    if not path.is_file():
        raise RunError(
            f"{run_dir} is not a nirl-mj run directory (no {RUN_FILE}); train one with `nirl-mj train`"
        )
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise RunError(f"{path} is corrupted: {exc}") from None


def load_checkpoint(run_dir: str | os.PathLike) -> dict[str, np.ndarray]:
    path = Path(run_dir) / CHECKPOINT_FILE
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except FileNotFoundError:
        raise RunError(f"{run_dir} has no checkpoint to resume from ({CHECKPOINT_FILE})") from None
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
        raise RunError(f"{path} is corrupted ({exc}); start a new run in another directory") from None


def load_policy(
    run_dir: str | os.PathLike, which: str = "selected"
) -> tuple[Callable[[np.ndarray], int], dict]:
    """The trained greedy policy on phi(s) and the run's record.

    ``which``: "selected" or "last" (from policy.npz), or an iteration number
    (any kept policy, from the checkpoint: to study what another selection rule
    would have picked).
    """
    run = read_run(run_dir)
    net = network.QNetwork(seed=0)
    if str(which).isdigit():
        state, i = load_checkpoint(run_dir), int(which)
        kept = len(state["scores"])
        if i >= kept:
            raise RunError(
                f"{run_dir} kept {kept} policies (iterations 0-{kept - 1}); there is no iteration {i}"
            )
        network.set_weights(net, {k: state[f"kept_{k}"][i] for k in ("W1", "W2")})
        return greedy_policy(net, run["config"]["input_scaling"]), run
    if which not in ("selected", "last"):
        raise RunError(f"unknown policy {which!r}; accepted: selected, last or an iteration number")
    path = Path(run_dir) / POLICY_FILE
    if not path.is_file():
        raise RunError(
            f"{run_dir} has no {POLICY_FILE}: its training has not finished (resume it with --resume)"
        )
    with np.load(path, allow_pickle=False) as data:
        network.set_weights(
            net, {k.split("/", 1)[1]: data[k] for k in data.files if k.startswith(which + "/")}
        )
    return greedy_policy(net, run["config"]["input_scaling"]), run


def train(
    run_dir: str | os.PathLike,
    task: specs.TaskSpec,
    demos_path: str | os.PathLike,
    config: NirlConfig,
    seed: int = 0,
    resume: bool = False,
    on_metrics: Callable[[Metrics], None] | None = None,
) -> dict:
    """Trains (or resumes) NIRL in ``run_dir``; returns the run record."""
    from nirl_mj.sim.task import make_env

    run_dir = Path(run_dir)
    demos = load_dataset(demos_path)
    record = {
        "task": task.to_dict(),
        "config": config.to_dict(),
        "seed": seed,
        "demos": str(demos_path),
        "demo_seeds": [t.arena_seed for t in demos],
        "validation_seeds": validation_seeds(config, seed),
    }
    if resume:
        saved = read_run(run_dir)
        for key in ("task", "config", "seed"):
            if saved[key] != json.loads(json.dumps(record[key])):
                raise RunError(
                    f"{run_dir} was trained with another {key}; resume with the same options, "
                    "or train in a new --out"
                )
    elif run_dir.exists() and any(run_dir.iterdir()):
        raise RunError(
            f"{run_dir} exists and is not empty; pass --resume to continue it, or choose another --out"
        )
    run_dir.mkdir(parents=True, exist_ok=True)

    learner = Nirl(config, demos, seed)
    if resume:
        learner.load_state(load_checkpoint(run_dir))
        _truncate_metrics(run_dir / METRICS_FILE, learner.iteration)
    else:
        write_text(run_dir / RUN_FILE, json.dumps(record, indent=1))
        (run_dir / METRICS_FILE).write_text("")
    env = make_env(specs.replace(task, robot={"drive": config.train_drive}))
    first_round = record["validation_seeds"][: config.validation_arenas]

    def validate(net) -> float | None:
        if config.selection != "validation" or learner.iteration % config.validate_every:
            return None
        from nirl_mj.experiments.evaluation import evaluate

        policy = greedy_policy(net, config.input_scaling)
        return evaluate(env, policy, first_round)[0]["success_rate"]

    k = config.trajectories_per_episode
    while learner.iteration < config.episodes and not learner.stopped:
        seeds = domain_seeds("train", seed, k, start=learner.iteration * k)
        metrics = learner.step(env, seeds, validate)
        with open(run_dir / METRICS_FILE, "a") as f:
            f.write(json.dumps(metrics.__dict__) + "\n")
        write_npz(run_dir / CHECKPOINT_FILE, learner.state())
        if on_metrics:
            on_metrics(metrics)
    selection = select(learner, env, record["validation_seeds"][config.validation_arenas :])
    return finish(run_dir, learner, {**record, "selection": selection})


def ensure_trained(
    run_dir: str | os.PathLike,
    task: specs.TaskSpec,
    demos_path: str | os.PathLike,
    config: NirlConfig,
    seed: int = 0,
) -> dict:
    """Trains the run, resumes it from its checkpoint, or returns a finished one's record.

    Finished means the final record is written (:func:`finish` writes it last). A directory
    killed before its first checkpoint holds only the files :func:`train` starts with and is
    started afresh; one holding anything else is refused."""
    run_dir = Path(run_dir)
    if (run_dir / RUN_FILE).is_file() and (run_dir / POLICY_FILE).is_file():
        record = read_run(run_dir)
        if "train_seeds" in record:
            return record
    resume = (run_dir / CHECKPOINT_FILE).is_file()
    if not resume and run_dir.exists():
        extra = {p.name for p in run_dir.iterdir()} - {RUN_FILE, METRICS_FILE, REWARD_FILE}
        if extra:
            raise RunError(f"{run_dir} holds {sorted(extra)} but no checkpoint; choose another directory")
        shutil.rmtree(run_dir)  # holds only files a training writes, and no checkpoint to resume
    return train(run_dir, task, demos_path, config, seed, resume=resume)


def validation_seeds(config: NirlConfig, seed: int) -> list[int]:
    """Every validation arena a run may use: the first round's, then the second round's."""
    rounds = 2 if config.selection == "validation" and config.final_candidates > 1 else 1
    return domain_seeds("validation", seed, rounds * config.validation_arenas)


def select(learner: Nirl, env, second_round: list[int]) -> dict:
    """The kept policy to report, by the configured rule, with how it was chosen.

    "validation": the ``final_candidates`` best first-round policies are evaluated
    on the second round's arenas too, and the best over both rounds wins (earliest
    on ties): picking the maximum of many noisy 20-arena estimates favours lucky
    ones, a fresh estimate of the few best corrects that.
    """
    from nirl_mj.experiments.evaluation import evaluate

    c = learner.config
    first = learner.selected
    if not second_round or not learner.kept:
        return {"rule": c.selection, "iteration": first}
    order = sorted(range(len(learner.scores)), key=lambda i: (-learner.scores[i], i))
    candidates = sorted(order[: c.final_candidates])
    combined = {}
    for i in candidates:
        net = network.QNetwork(seed=0)
        network.set_weights(net, learner.kept[i])
        second = evaluate(env, greedy_policy(net, c.input_scaling), second_round)[0]["success_rate"]
        combined[i] = (learner.scores[i] + second) / 2
    chosen = max(candidates, key=lambda i: (combined[i], -i))
    return {
        "rule": f"{c.selection}, best {c.final_candidates} re-validated",
        "iteration": chosen,
        "first_round_best": first,
        "candidates": {str(i): {"first": learner.scores[i], "both": combined[i]} for i in candidates},
    }


def finish(run_dir: Path, learner: Nirl, record: dict) -> dict:
    """Writes the selected and last policy and the selected reward."""
    chosen = record["selection"]["iteration"]
    arrays = {f"selected/{k}": v for k, v in learner.kept[chosen].items()}
    arrays |= {f"last/{k}": v for k, v in learner.kept[-1].items()}
    write_npz(run_dir / POLICY_FILE, arrays)
    RewardModel(learner.thetas[chosen], learner.config.reward_features).save(run_dir / REWARD_FILE)
    n_train = learner.iteration * learner.config.trajectories_per_episode
    record = {
        **record,
        "iterations": learner.iteration,
        "selected_iteration": chosen,
        "train_seeds": domain_seeds("train", record["seed"], n_train),
    }
    write_text(run_dir / RUN_FILE, json.dumps(record, indent=1))
    return record


def _truncate_metrics(path: Path, iterations: int) -> None:
    """Keeps the first ``iterations`` lines: a crash may have written one past the checkpoint."""
    lines = path.read_text().splitlines(keepends=True) if path.exists() else []
    write_text(path, "".join(lines[:iterations]))
