"""Training runs: the shared IRL loop on the simulation, a checkpoint every iteration, exact resume.

The loop itself (``nirl_mj.learn.loop``) does not simulate; here it gets its
rollouts from the episode loop in the training arenas (``seeds.domain_seeds("train")``),
its validation from held-out validation arenas, and its files from a
:class:`~nirl_mj.data.rundir.RunDir`. An interrupted run (Ctrl-C, a crash, a killed
machine) continues from its last checkpoint with ``resume=True`` and ends with
exactly the weights an uninterrupted run would have.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from nirl_mj.data.atomic import leftover_temporaries
from nirl_mj.data.dataset import dataset_digest, load_dataset
from nirl_mj.data.lock import DirectoryLock
from nirl_mj.data.rundir import (
    CHECKPOINT_FILE,
    METRICS_FILE,
    REWARD_FILE,
    RUN_FILE,
    RunDir,
    RunError,
    check_weights,
)
from nirl_mj.data.trajectory import TERMINAL_OUTCOMES, Trajectory, require_discrete
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.reads import learner_reads
from nirl_mj.experiments.seeds import domain_seeds
from nirl_mj.learn import network
from nirl_mj.learn.config import LearnerConfig
from nirl_mj.learn.inputs import NetworkInputs
from nirl_mj.learn.loop import IrlLoop, Metrics, greedy_policy
from nirl_mj.learn.reward import RewardModel
from nirl_mj.learn.selection import latest_best
from nirl_mj.sim import spec as specs
from nirl_mj.sim.rollouts import CPU, Backend, Rollouts, make_rollouts

Policy = Callable[[np.ndarray], int]


MINARI = "minari:"
"""``--demos minari:ID``: a local Minari dataset (``nirl_mj.gym.minari_export``) instead of a file."""


def load_demonstrations(source: str | os.PathLike, discrete: bool = True) -> list[Trajectory]:
    """The trajectories of a dataset file (docs/DATASET.md), or of the local Minari dataset ID for
    ``minari:ID`` (written by ``nirl-mj export``; needs the optional extra ``nirl-mj[gym]``). With
    ``discrete`` (a learner of the six discrete actions) continuous actions are a clear error."""
    if str(source).startswith(MINARI):
        from nirl_mj.gym.minari_export import load_minari

        trajectories = load_minari(str(source)[len(MINARI) :])
    else:
        trajectories = load_dataset(source)
    if discrete:
        require_discrete(trajectories, str(source))
    return trajectories


def run_config(record: dict[str, Any]) -> LearnerConfig:
    """The learner config of a run record."""
    try:
        return LearnerConfig.from_record(record["config"])
    except (KeyError, TypeError, ValueError) as exc:
        raise RunError(f"the run record's learner config is not readable ({exc})") from None


def saved_settings(run_dir: str | os.PathLike) -> tuple[specs.TaskSpec, LearnerConfig, str, int]:
    """What a resume continues with: the run's task, learner config, demonstrations path and seed."""
    run = RunDir(run_dir)
    started = run.names() - {p.name for p in leftover_temporaries(run.path)}
    if not run.is_run and not started:
        raise RunError(f"nothing to resume in {run}: the training had not started (no {RUN_FILE}); run the "
                       "same command without --resume")  # fmt: skip
    record = run.read_record()
    return (
        specs.from_dict(record["task"], f"{run.file(RUN_FILE)}: task"),
        run_config(record),
        record["demos"],
        record["seed"],
    )


def load_policy(run_dir: str | os.PathLike, which: str = "selected") -> tuple[Policy, dict]:
    """The trained greedy policy on phi(s) and the run's record.

    ``which``: "selected" or "last" (from the policy file), or an iteration number
    (any kept policy, from the checkpoint: to study what another selection rule
    would have picked).
    """
    run = RunDir(run_dir)
    record = run.read_record()
    if str(which).isdigit():
        state, i = run.read_checkpoint(), int(which)
        kept = len(state["scores"])
        if i >= kept:
            raise RunError(f"{run} kept {kept} policies (iterations 0-{kept - 1}); there is no iteration {i}")
        weights = {k: state[f"kept_{k}"][i] for k in ("W1", "W2") if f"kept_{k}" in state}
        check_weights(
            weights, f"{run.file(CHECKPOINT_FILE)}'s policy of iteration {i}", "train the run again"
        )
    else:
        weights = run.read_policy(which)
    return _greedy(weights, run_config(record)), record


def _greedy(weights: dict[str, np.ndarray], config: LearnerConfig) -> Policy:
    inputs = NetworkInputs.of(config.loop)
    net = network.QNetwork(inputs.size, config.loop.hidden_units, seed=0)
    network.set_weights(net, weights)
    return greedy_policy(net, inputs)


def train(
    run_dir: str | os.PathLike,
    task: specs.TaskSpec,
    demos_path: str | os.PathLike,
    config: LearnerConfig,
    seed: int = 0,
    resume: bool = False,
    on_metrics: Callable[[Metrics], None] | None = None,
    backend: Backend = CPU,
) -> dict:
    """Trains (or resumes) the configured method in ``run_dir``; returns the run record. One writer at
    a time (``nirl_mj.data.lock``); a resume checks the whole checkpoint and its agreement with the
    record and the metrics before it changes anything. ``backend`` runs the rollouts, validation
    and selection episodes (:mod:`nirl_mj.sim.rollouts`; a run not on the ``cpu`` backend records it,
    and a resume must use the same)."""
    if task.control.actions != "discrete":  # refused before the run directory is made
        raise ValueError(f"task {task.name} has continuous actions, but NIRL and the IRL baselines learn a "
                         'policy over the six discrete actions: accepted: a task with [control] actions = '
                         '"discrete"')  # fmt: skip
    with DirectoryLock(run_dir, "training"):
        return _train(run_dir, task, demos_path, config, seed, resume, on_metrics, backend)


def _train(
    run_dir: str | os.PathLike,
    task: specs.TaskSpec,
    demos_path: str | os.PathLike,
    config: LearnerConfig,
    seed: int,
    resume: bool,
    on_metrics: Callable[[Metrics], None] | None = None,
    backend: Backend = CPU,
) -> dict:
    """:func:`train` holding the run's lock."""
    run = RunDir(run_dir)
    if run.path.is_dir():
        run.remove_leftovers()  # a killed process's temporary files (we hold the lock: no writer runs)
    demos = load_demonstrations(demos_path)
    minari = str(demos_path).startswith(MINARI)
    record = {
        "task": task.to_dict(),
        "config": config.to_dict(),
        "seed": seed,
        # a resume may run from another directory
        "demos": str(demos_path) if minari else str(Path(demos_path).resolve()),
        "demos_sha256": dataset_digest(demos),  # the demonstrations by content: a resume must use the same
        "demo_seeds": [t.arena_seed for t in demos],
        "validation_seeds": validation_seeds(config, seed),
        "reads": learner_reads(config),  # the information budget (nirl_mj.experiments.reads)
    }
    if backend.name != "cpu":
        record["backend"] = backend.to_dict()
    if resume:
        saved = run.read_record()
        # a record written before a setting existed holds its default: compare resolved configs
        saved = {**saved, "config": run_config(saved).to_dict()}
        for key in ("task", "config", "seed"):
            if saved.get(key) != json.loads(json.dumps(record[key])):
                raise RunError(
                    f"{run} was trained with another {key}; resume with the same options, "
                    "or train in a new --out"
                )
        if saved.get("demos_sha256", record["demos_sha256"]) != record["demos_sha256"]:
            raise RunError(
                f"{demos_path} holds other demonstrations than {run} was trained on (content sha256 "
                f"{record['demos_sha256'][:12]}..., the run's {saved['demos_sha256'][:12]}...); resume "
                f"with the run's own dataset ({saved['demos']}), or train in a new --out"
            )
        if saved.get("backend") != record.get("backend"):
            cpu = {"name": "cpu"}
            raise RunError(f"{run} was trained on the backend {saved.get('backend', cpu)}, this resume asks "
                           f"for {record.get('backend', cpu)}: resume with the run's --backend, --worlds and "
                           "--device (or none of them)")  # fmt: skip
        run.remove_leftovers()  # temporary files of a process killed while writing
        # Killed before its first checkpoint: nothing to continue, so it starts over (same settings);
        # at most one metrics row (the first iteration's, appended before its checkpoint) is there.
        resume = run.has_checkpoint
        if not resume and (run.iterations_done() > 1 or saved.get("train_seeds")):
            raise RunError(f"{run} has iterations recorded but no {CHECKPOINT_FILE} (deleted or lost): it "
                           "cannot be continued, and starting over would replace them; train it again in "
                           "another --out")  # fmt: skip
    elif not run.is_empty():
        if not run.is_run:  # a resume would find no record to continue either
            raise RunError(f"{run} exists and holds no run of nirl-mj train (no {RUN_FILE}): nothing there "
                           "can be continued; choose another --out")  # fmt: skip
        raise RunError(
            f"{run} exists and is not empty; pass --resume to continue it, or choose another --out"
        )

    learner = IrlLoop(config, demos, seed)
    if resume:
        state = run.read_checkpoint()
        try:
            learner.load_state(state)
        except (ValueError, KeyError, TypeError, IndexError) as exc:
            raise RunError(f"{run.file(CHECKPOINT_FILE)} cannot be resumed: {exc}; the run is left as it "
                           "is: train it again in another --out") from None  # fmt: skip
        rows = run.iterations_done()
        if rows < learner.iteration:
            raise RunError(
                f"{run.file(METRICS_FILE)} holds {rows} rows but the checkpoint is at iteration "
                f"{learner.iteration}; the run is left as it is: train it again in another --out"
            )
        run.keep_metrics(learner.iteration)  # a crash may have written one row past the checkpoint
    else:
        run.write_record(record)
        run.start_metrics()
    try:
        return _iterate(run, learner, config, task, seed, record, on_metrics, backend)
    except Exception:
        # failed before its first iteration (an arena that cannot be built...): leave no half-started
        # run that would block the same --out (an interrupted one stays, for --resume)
        if not run.has_checkpoint:
            for name in (RUN_FILE, METRICS_FILE):
                run.file(name).unlink(missing_ok=True)
        raise


def _iterate(
    run: RunDir,
    learner: IrlLoop,
    config: LearnerConfig,
    task: specs.TaskSpec,
    seed: int,
    record: dict,
    on_metrics: Callable[[Metrics], None] | None,
    backend: Backend = CPU,
) -> dict:
    """The iterations left, the selection and the final files."""
    loop = config.loop
    rollouts = make_rollouts(backend, specs.replace(task, robot={"drive": loop.train_drive}))
    first_round = record["validation_seeds"][: loop.validation_arenas]

    def validate(net: network.QNetwork) -> float | None:
        if loop.selection != "validation" or learner.iteration % loop.validate_every:
            return None
        policy = greedy_policy(net, NetworkInputs.of(loop))
        return evaluate(None, policy, first_round, rollouts=rollouts)[0]["success_rate"]

    k = loop.trajectories_per_episode
    while learner.iteration < loop.episodes and not learner.stopped:
        seeds = domain_seeds("train", seed, k, start=learner.iteration * k)
        metrics = learner.step(rollouts, seeds, validate)
        run.append_metrics(metrics.__dict__)
        run.write_checkpoint(learner.state())
        if on_metrics:
            on_metrics(metrics)
    selection = select(learner, rollouts, record["validation_seeds"])
    return finish(run, learner, {**record, "selection": selection})


def ensure_trained(
    run_dir: str | os.PathLike,
    task: specs.TaskSpec,
    demos_path: str | os.PathLike,
    config: LearnerConfig,
    seed: int = 0,
    wait: bool = False,
) -> dict:
    """Trains the run, resumes it from its checkpoint, or returns a finished one's record.

    Finished means the final record is written (:func:`finish` writes it last). A directory
    killed before its first checkpoint holds only the files :func:`train` starts with and is
    started afresh; one holding anything else is refused. Everything under the run's lock, which
    another process holding it refuses, or with ``wait`` is waited for."""
    with DirectoryLock(run_dir, "training", wait=wait):
        return _ensure_trained(RunDir(run_dir), task, demos_path, config, seed)


def _ensure_trained(run: RunDir, task, demos_path, config: LearnerConfig, seed: int) -> dict:
    if run.is_finished:
        return run.read_record()
    run.remove_leftovers()
    resume = run.has_checkpoint
    if not resume and run.path.exists():
        extra = run.names() - {RUN_FILE, METRICS_FILE, REWARD_FILE}
        if extra:
            raise RunError(f"{run} holds {sorted(extra)} but no {CHECKPOINT_FILE}; choose another directory")
        shutil.rmtree(run.path)  # holds only files a training writes, and no checkpoint to resume
    return _train(run.path, task, demos_path, config, seed, resume)


def validation_seeds(config: LearnerConfig, seed: int) -> list[int]:
    """Every validation arena a run may use: the first round's, then the second round's; with
    ``end_check_arenas``, at least that many (the end check drives the first of them)."""
    loop = config.loop
    rounds = 2 if loop.selection == "validation" and loop.final_candidates > 1 else 1
    return domain_seeds("validation", seed, max(rounds * loop.validation_arenas, loop.end_check_arenas))


def planned_seeds(config: LearnerConfig, seed: int) -> set[int]:
    """Every training and validation arena a run of ``config`` and ``seed`` may visit."""
    loop = config.loop
    train = domain_seeds("train", seed, loop.episodes * loop.trajectories_per_episode)
    return {*validation_seeds(config, seed), *train}


TIES = "latest"
"""What a run's selection record says of ties (``nirl_mj.learn.selection``); runs before 6c30c7d,
which kept the first of equal scores, have no ``ties`` key."""


def select(learner: IrlLoop, rollouts: Rollouts, validation: list[int]) -> dict:
    """The kept policy to report, by the configured rule, with how it was chosen; ``validation``
    is the run's validation arenas (``run.json``'s ``validation_seeds``).

    "validation": the ``final_candidates`` best first-round policies are evaluated
    on the second round's arenas too, and the best over both rounds wins (the latest
    on ties, as everywhere: ``nirl_mj.learn.selection``): picking the maximum of many
    noisy 20-arena estimates favours lucky ones, a fresh estimate of the few best
    corrects that. With ``end_check_arenas``: :func:`_end_checked`.
    """
    loop = learner.loop
    first = learner.selected
    if loop.end_check_arenas and learner.kept:
        return _end_checked(learner, rollouts, validation[: loop.end_check_arenas])
    second_round = validation[loop.validation_arenas :]
    if not second_round or not learner.kept:
        return {"rule": loop.selection, "iteration": first, "ties": TIES}
    candidates = sorted(_rule_order(learner)[: loop.final_candidates])
    combined = {}
    for i in candidates:
        policy = _greedy(learner.kept[i], learner.config)
        second = evaluate(None, policy, second_round, rollouts=rollouts)[0]["success_rate"]
        combined[i] = (learner.scores[i] + second) / 2
    chosen = candidates[latest_best([combined[i] for i in candidates])]
    return {
        "rule": f"{loop.selection}, best {loop.final_candidates} re-validated",
        "iteration": chosen,
        "ties": TIES,
        "first_round_best": first,
        "candidates": {str(i): {"first": learner.scores[i], "both": combined[i]} for i in candidates},
    }


def _rule_order(learner: IrlLoop) -> list[int]:
    """The kept iterates by the rule's score, best first, the latest first among equals; NaN (no
    score) last."""
    score = [-np.inf if np.isnan(x) else x for x in learner.scores]
    return sorted(range(len(score)), key=lambda i: (-score[i], -i))


def _number(x: float) -> float | None:
    """A score as strict JSON holds it: NaN (no demonstrated pair scored) as None."""
    return None if np.isnan(x) else float(x)


def _end_checked(learner: IrlLoop, rollouts: Rollouts, arenas: list[int]) -> dict:
    """The ``final_candidates`` best iterates by the rule, and the last, each driven greedily once
    in every arena of ``arenas``; kept: the one whose episodes ended most often before the time
    limit (an arrival, a collision, a physics error: any end, ``episode_end``, never which), the
    rule's order among equals (``end_ties``). A policy caught in a loop runs into the limit
    (docs/RESULTS.md, "What NIRL's weakest unseen runs fail by"); the rule's scores, on the
    demonstrated states, did not see it there."""
    order = _rule_order(learner)
    best = order[: learner.loop.final_candidates]
    candidates = [*best, *({len(learner.kept) - 1} - set(best))]
    ended = {}
    for i in candidates:
        _, trajectories = evaluate(None, _greedy(learner.kept[i], learner.config), arenas, rollouts=rollouts)
        ended[i] = sum(t.outcome in TERMINAL_OUTCOMES for t in trajectories)
    chosen = max(candidates, key=lambda i: (ended[i], -order.index(i)))
    return {
        "rule": f"{learner.loop.selection}, best {learner.loop.final_candidates} and the last end-checked",
        "iteration": chosen,
        "ties": TIES,
        "end_ties": "rule order",
        "first_round_best": learner.selected,
        "end_check_arenas": len(arenas),
        "candidates": {
            str(i): {"score": _number(learner.scores[i]), "ended": ended[i]} for i in sorted(candidates)
        },
    }


def finish(run: RunDir, learner: IrlLoop, record: dict) -> dict:
    """Writes the selected and last policy, the selected reward, and the final record (last)."""
    chosen = record["selection"]["iteration"]
    run.write_policy(learner.kept[chosen], learner.kept[-1])
    run.write_reward(RewardModel(learner.thetas[chosen], learner.loop.reward_features).to_dict())
    n_train = learner.iteration * learner.loop.trajectories_per_episode
    record = {
        **record,
        "iterations": learner.iteration,
        "selected_iteration": chosen,
        "train_seeds": domain_seeds("train", record["seed"], n_train),
    }
    run.write_record(record)
    return record
