"""Stable-Baselines3 learners: the RL reference on the task's own reward, and GAIL / AIRL.

``ppo`` and ``dqn`` learn from the task's reward (the RL reference). ``gail`` and ``airl`` learn
from the demonstrations: PPO with every reward replaced by a discriminator's
(``nirl_mj.experiments.adversarial``); they never read the task's reward. ``gail-absorbing`` and
``airl-absorbing`` are the same with an absorbing state (Kostrikov et al. 2019); ``gail-norm`` and
``airl-norm`` with the policy's reward normalised by its running mean and variance; ``gail-gp`` and
``airl-gp`` with a gradient penalty on the discriminator; ``airl-state`` with a state-only g(s);
``gail-d2`` and ``airl-d2`` with two full-batch discriminator steps per rollout.

NIRL never reads the task's reward; this reference does, with the same observation as NIRL,
phi(s) (``features``, 16 values, scaled to [0, 1] by their upper bounds, or with ``inputs =
"bearing"`` in NIRL's code: :func:`observation_code`), and the same held-out
tests (``nirl-mj eval --run RUN``). The environment is ``nirl_mj.gym.NavigationEnv``; every
training episode draws the arena of ``seeds.domain_seed("train", seed, k)`` for its k-th episode
(:class:`~nirl_mj.gym.wrappers.ArenaSeeds`), recorded as the run's ``train_seeds``, so held-out
tests skip them like a NIRL run's.

The run directory (``nirl_mj.data.rundir``) holds ``run.json`` (``"kind": "rl"``, the algorithm,
its settings, the task, seed and arenas, every checkpoint's selection score, ``finished`` once the
checkpoint after the last update is written), ``model.zip``
(Stable-Baselines3's file, rewritten atomically at every checkpoint), the selected checkpoint
``selected-<decisions>.zip`` that the record names (:data:`SELECTIONS`), GAIL's and AIRL's
``discriminator.npz`` (the last checkpoint's: AIRL's reward maps show it, not the selected
checkpoint's) and ``eval.json``. A resume of a stopped run replays it from its seed to its last
checkpoint, keeping the scores recorded there, and trains on: it ends bit for bit as the
uninterrupted run (:func:`_replays`; the episodes in progress, PPO's rollout and DQN's replay buffer
are in no file); a replay that does not reach the saved model there
(another machine's arithmetic, a lost model) trains on from the replay and lists that checkpoint in
the record's ``inexact_resumes``. A resume that trains on to a new total continues from the saved
model, with the arenas that follow and the success window of ``training_success`` as it was, and
lists the run's ``budgets``: a stop of it later goes on from the saved model too.

Needs the optional extra ``nirl-mj[gym]``; imported only by the commands that train or load an
RL run, so the core install does not need it.
"""

from __future__ import annotations

import json
import os
import re
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from nirl_mj.data.atomic import leftover_temporaries
from nirl_mj.data.lock import writes
from nirl_mj.data.rundir import (
    DISCRIMINATOR_FILE,
    EVAL_FILE,
    MODEL_FILE,
    POLICIES,
    RUN_FILE,
    SELECTED_MODEL_FILE,
    SELECTED_MODEL_PATTERN,
    RunDir,
    RunError,
)
from nirl_mj.experiments.observation_code import observation_code, scaled
from nirl_mj.experiments.reads import rl_reads
from nirl_mj.experiments.seeds import domain_seed, domain_seeds
from nirl_mj.sim import spec as specs

ADVERSARIAL = ("gail", "airl", "gail-absorbing", "airl-absorbing", "gail-norm", "airl-norm",
               "gail-gp", "airl-gp", "gail-gp1", "airl-gp1", "gail-gp0_1", "airl-gp0_1",
               "airl-state", "gail-d2", "airl-d2")  # fmt: skip
"""PPO on a discriminator's reward (nirl_mj.experiments.adversarial); "-absorbing": with an absorbing
state; "-norm": the reward normalised as it runs; "-gp", "-gp1", "-gp0_1": a gradient penalty on
the discriminator, weight 10, 1, 0.1; "airl-state": AIRL with a state-only g(s); "-d2": two
full-batch discriminator steps per rollout (the imitation library's default number of updates)."""
ALGOS = ("ppo", "dqn", *ADVERSARIAL)
SETTINGS: dict[str, dict[str, Any]] = {
    # Stable-Baselines3's defaults but for a smaller PPO rollout (episodes are ~60-340 decisions).
    "ppo": {"n_steps": 1024, "batch_size": 64, "n_epochs": 10, "gamma": 0.99, "learning_rate": 3e-4},
    "dqn": {"buffer_size": 100_000, "learning_starts": 1000, "gamma": 0.99, "learning_rate": 1e-4,
            "exploration_fraction": 0.2, "target_update_interval": 1000},
}  # fmt: skip
for _kind in ADVERSARIAL:  # the policy learner is PPO, with the RL reference's settings
    SETTINGS[_kind] = dict(SETTINGS["ppo"])
"""Each algorithm's settings (recorded in the run; a resume must use the same)."""

SELECTIONS = ("last", "demo_balanced", "training_success", "validation_success")
"""How a run chooses the policy it hands to tests among its checkpoints: ``last`` (the last
checkpoint); ``demo_balanced``, the paper's rule as NIRL uses it (the greedy action's balanced
accuracy on the demonstrations; GAIL and AIRL, which read them anyway); ``training_success``, the
task's success over the last :data:`SUCCESS_WINDOW` training episodes that ended before the
checkpoint (every one on a fresh arena); ``validation_success``, the checkpoint's own success, as
the tests drive it, on the same :data:`VALIDATION_ARENAS` arenas of the validation domain at every
checkpoint (paired: the same arenas and the same sampling stream), stopping once it can no longer
reach the best score so far (:func:`_validation_scorer`: its entry in the record then has no
``score`` (null), ``at_most``, the most it could have reached, and ``driven``, the arenas it
scored: driven, or for a policy acting by its mode, reused where it would drive an earlier
checkpoint's episode again). The last two read the task's success (recorded as
``task_success_selection``): for PPO and DQN, which read its reward anyway.
The best score wins, the later checkpoint on a tie (the rule of every method:
``nirl_mj.learn.selection``)."""
VALIDATION_ARENAS = 20
"""Arenas of the validation domain that ``validation_success`` drives every checkpoint on."""
SUCCESS_WINDOW = 30
"""Training episodes that ``training_success`` scores a checkpoint on (about the episodes of 5,000
decisions, one checkpoint's span, at Table I's 20 obstacles)."""
LEGACY = {"selection": "last", "envs": 1}
"""What a run recorded before selection and vectorised environments existed did: its config holds
neither key, so it still resumes and its cells keep their identity."""


def default_selection(algo: str) -> str:
    """The selection ``nirl-mj rl --algo ALGO`` uses unless told (each reads only what the algorithm
    reads anyway); an experiment's row uses its own (``definition.MethodSpec.selection``)."""
    return "demo_balanced" if algo in ADVERSARIAL else "training_success"


TUNABLE = {"learning_rate": (float, 0.0, None), "n_epochs": (int, 1, None), "batch_size": (int, 2, None),
           "ent_coef": (float, None, None), "clip_range": (float, 0.0, None), "gae_lambda": (float, 0.0, 1.0),
           "gamma": (float, 0.0, 1.0), "target_kl": (float, 0.0, None),
           "validation_arenas": (int, 1, None), "checkpoint_every": (int, 1, None)}  # fmt: skip
"""PPO's settings an experiment may change (``[method.NAME] settings = {...}``): (type, lowest, highest);
a float's lowest is excluded (an int's included), ``ent_coef`` is any number >= 0; and the words of
:data:`CHOICES`. ``validation_arenas`` is the selection's, not PPO's: the arenas
``validation_success`` drives every checkpoint on (default :data:`VALIDATION_ARENAS`; the first
:data:`VALIDATION_ARENAS` are the default's). ``checkpoint_every``, the decisions between
checkpoints (default :data:`CHECKPOINT_EVERY`; a multiple of ``envs``): the selection scores fewer
checkpoints of the same training (checkpoints never change it)."""
TUNABLE_DQN = {"exploration_fraction": (float, 0.0, 1.0), "validation_arenas": TUNABLE["validation_arenas"],
               "checkpoint_every": TUNABLE["checkpoint_every"]}  # fmt: skip
"""DQN's settings an experiment may change, as :data:`TUNABLE`'s: ``exploration_fraction``, the part
of the run's decisions over which epsilon falls from 1 to 0.05 (0.2 of 100,000 by default: 0.4 of
50,000 explores over the same first 20,000 decisions); ``validation_arenas`` and ``checkpoint_every``
as PPO's."""
CHOICES = {
    "lr_schedule": ("constant", "linear"),
    "act": ("sampled", "greedy"),
    "inputs": ("scaled", "bearing"),
}
"""PPO's settings that take a word: ``lr_schedule`` ``linear`` decays ``learning_rate`` linearly to 0
at the run's last decision (Stable-Baselines3's ``LinearSchedule``), ``constant`` keeps it; ``act``,
how validation and tests drive a discrete PPO policy (:func:`model_policy`): ``sampled`` (the
default) draws each action from its distribution, ``greedy`` takes its mode. Training is the same
either way. ``inputs``, what the networks see of phi(s) (:func:`observation_code`): ``scaled`` (the
default) or ``bearing``, NIRL's default code (``nirl_mj.learn.inputs``); an adversarial learner's
discriminator reads the same code as its policy."""
DEFAULT_STEPS = 50_000
"""The decisions of ``nirl-mj rl`` and of an experiment's ``rl`` method that gives no ``steps``."""
CHECKPOINT_EVERY = 5_000
"""Decisions between checkpoints (each one scored by the selection); ``envs`` must divide it."""


def tuned(algo: str, changes: dict) -> dict:
    """``changes`` to the algorithm's settings checked (:data:`TUNABLE` and :data:`CHOICES` for PPO
    and its adversarial learners, :data:`TUNABLE_DQN` for DQN): ValueError naming the key and what
    is accepted."""
    tunable, choices = (TUNABLE_DQN, {}) if algo == "dqn" else (TUNABLE, CHOICES)
    out = {}
    for key, value in changes.items():
        if key in choices:
            if value not in choices[key]:
                raise ValueError(f"settings.{key} = {value!r}: accepted: {', '.join(choices[key])}")
            out[key] = value
            continue
        if key not in tunable:
            raise ValueError(f"settings.{key}: accepted for {algo}: {', '.join([*tunable, *choices])}")
        kind, low, high = tunable[key]
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        ok = type(value) is kind and np.isfinite(value)
        if key == "ent_coef":
            ok, wanted = ok and value >= 0, "a float >= 0"
        elif kind is int:
            ok, wanted = ok and value >= low, f"an int >= {low}"
        else:
            ok = ok and value > low and (high is None or value <= high)
            wanted = f"a float in ({low}, {'inf)' if high is None else f'{high}]'}"
        if not ok:
            raise ValueError(f"settings.{key} = {value!r}: expected {wanted}")
        out[key] = value
    return out


def run_config(
    algo: str, selection: str, envs: int, changes: dict | None = None, train_drive: str = ""
) -> dict:
    """The settings a run records: the algorithm's with ``changes`` (:func:`tuned`), PPO's rollout
    split over ``envs`` environments (``n_steps`` per environment, the same decisions per update),
    the selection, and ``train_drive`` where given (:data:`~nirl_mj.sim.spec.DRIVES`: the
    training episodes' drive; "" the task's, as runs recorded before it existed)."""
    if train_drive and train_drive not in specs.DRIVES:
        raise ValueError(f"train_drive {train_drive!r}: accepted: {', '.join(specs.DRIVES)}")
    if selection not in SELECTIONS:
        raise ValueError(f"selection {selection!r}: accepted: {', '.join(SELECTIONS)}")
    if selection == "demo_balanced" and algo not in ADVERSARIAL:
        raise ValueError(f"selection demo_balanced reads demonstrations; {algo} has none: use "
                         "training_success, validation_success or last")  # fmt: skip
    config = {"algo": algo, **SETTINGS[algo], **tuned(algo, changes or {})}
    every = config.get("checkpoint_every", CHECKPOINT_EVERY)
    if envs < 1 or every % envs:
        raise ValueError(f"envs = {envs}: must be >= 1 and divide the {every} decisions between "
                         "checkpoints")  # fmt: skip
    if every == CHECKPOINT_EVERY:  # the default: the default's identity
        config.pop("checkpoint_every", None)
    if "validation_arenas" in config and selection != "validation_success":
        raise ValueError(
            f"settings.validation_arenas goes with selection validation_success, not {selection}"
        )
    if config.get("validation_arenas") == VALIDATION_ARENAS:  # the default: the default's identity
        del config["validation_arenas"]
    if train_drive:
        config["train_drive"] = train_drive
    if (selection, envs) == (LEGACY["selection"], LEGACY["envs"]):
        return config
    if "n_steps" in config:
        if config["n_steps"] % envs:
            raise ValueError(f"envs = {envs}: must divide PPO's rollout of {config['n_steps']} decisions")
        config["n_steps"] //= envs
    return {**config, "selection": selection, "envs": envs}


def _algorithm(algo: str):
    if algo not in ALGOS:
        raise ValueError(f"unknown algorithm {algo!r}: accepted: {', '.join(ALGOS)}")
    import stable_baselines3

    return stable_baselines3.DQN if algo == "dqn" else stable_baselines3.PPO


def _environment(
    task: specs.TaskSpec,
    seed: int,
    first_episode: int,
    envs: int = 1,
    legacy: bool = False,
    config: dict | None = None,
):
    """``envs`` training environments stepped in turn in one process, phi(s) coded as ``config`` says
    (:func:`observation_code`); every episode draws the next arena of the train domain from one
    :class:`ArenaStream` (returned with them).
    ``legacy``: as runs before 2026-11-26 trained, the first episode in the arena of seed ``seed``
    (Stable-Baselines3's seeding), the later ones from the stream."""
    import gymnasium
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    from nirl_mj.gym.arena_stream import ArenaStream
    from nirl_mj.gym.env import NavigationEnv
    from nirl_mj.gym.wrappers import ArenaSeeds

    stream = ArenaStream(lambda k: domain_seed("train", seed, k), start=first_episode)
    code, box = observation_code(config or {})

    def make() -> gymnasium.Env:
        arenas = ArenaSeeds(
            NavigationEnv(task, observation="features"), stream=stream, replace_given=not legacy
        )
        wrapped = gymnasium.wrappers.TransformObservation(arenas, code, box)
        return Monitor(wrapped, info_keywords=("is_success",))

    return DummyVecEnv([make] * envs), stream


def _demo_scorer(
    model: Any, trajectories: list, code: Callable[[np.ndarray], np.ndarray] = scaled
) -> Callable[[], float]:
    """The greedy action's balanced accuracy on the demonstrated pairs (selection demo_balanced);
    ``code``: phi(s) -> the policy's observation (:func:`observation_code`)."""
    import torch

    from nirl_mj.data.trajectory import stack_pairs
    from nirl_mj.learn.predictability import balanced_accuracy

    phi, actions = stack_pairs(trajectories)
    x = torch.as_tensor(code(phi))

    def score() -> float:
        with torch.no_grad():
            probs = model.policy.get_distribution(x).distribution.probs
        return balanced_accuracy(actions, probs.argmax(dim=1).numpy())

    return score


def _model_settings(config: dict) -> dict:
    """The keyword arguments of the algorithm's constructor from a run's config: its own keys
    dropped, ``lr_schedule`` turned into the learning rate's schedule."""
    own = ("algo", "selection", "envs", "discriminator", "lr_schedule", "train_drive", "act",
           "validation_arenas", "checkpoint_every", "inputs")  # fmt: skip
    settings = {k: v for k, v in config.items() if k not in own}
    if config.get("lr_schedule") == "linear":
        from stable_baselines3.common.utils import LinearSchedule

        settings["learning_rate"] = LinearSchedule(settings["learning_rate"], 0.0, 1.0)
    return settings


def _validation_scorer(
    model: Any, record: dict, task: specs.TaskSpec, seed: int
) -> Callable[[float | None], tuple[float, int]]:
    """The checkpoint's success on the run's validation arenas, driven as the tests drive it
    (selection validation_success): the same arenas and the same sampling stream every time.

    ``score(best)`` returns (success, arenas scored). Given ``best``, the best score so far, it
    stops once the checkpoint can no longer reach it: the arenas left cannot change the selection
    (the best score wins, the later checkpoint on a tie), so they are not driven, and the success
    returned is then the most the checkpoint could have scored, below ``best``
    (:data:`VALIDATION_CUT`: False drives every arena).

    A policy that acts by its mode (DQN, PPO with ``act = "greedy"``) is a function of phi(s), and an
    episode is a function of its arena and its actions (``sim.episode``): where the checkpoint takes,
    in every state of the episode an earlier checkpoint drove in an arena, the action taken there,
    it would drive that episode again, so its outcome is reused and the arena is not driven
    (:data:`VALIDATION_REUSE`; ``score.reused`` counts them). The scores are the same either way."""
    from nirl_mj.data.outcomes import outcome_rates
    from nirl_mj.experts.policies import PolicyAgent
    from nirl_mj.sim.episode import run_episode
    from nirl_mj.sim.task import make_env

    env = make_env(task)
    seeds = record["validation_seeds"]
    by_mode = VALIDATION_REUSE and not _samples(record, None) and task.control.actions == "discrete"
    driven_before: dict[int, tuple[list[np.ndarray], list[int], int]] = {}  # arena: phi(s), actions, success

    def outcome(policy: Callable[[np.ndarray], int], arena: int) -> int:
        """1 if the policy reaches the target in ``arena``, counted as the tests' metrics count it
        (``data.outcomes``); reused where the policy would drive the episode driven before."""
        before = driven_before.get(arena)
        if before is not None and all(policy(phi) == action for phi, action in zip(*before[:2], strict=True)):
            score.reused += 1
            return before[2]
        seen: list[np.ndarray] = []

        def recording(phi: np.ndarray) -> int:
            seen.append(phi.copy())
            return policy(phi)

        trajectory = run_episode(env, PolicyAgent(recording if by_mode else policy, "validation"), arena)
        success = int(outcome_rates([trajectory.outcome])["success_rate"])
        actions = getattr(trajectory, "actions", None)
        if by_mode and actions is not None and len(actions) == len(seen):
            driven_before[arena] = (seen, [int(a) for a in actions], success)
        return success

    def score(best: float | None = None) -> tuple[float, int]:
        policy = model_policy(model, record, sampled=None, seed=seed, shares=True)
        cut = VALIDATION_CUT and best is not None and best == best  # a NaN best is replaced by any score
        needed = round(best * len(seeds)) if cut else None
        successes = 0
        for scored, arena in enumerate(seeds, start=1):
            successes += outcome(policy, arena)
            reachable = successes + len(seeds) - scored
            if needed is not None and reachable < needed:
                return reachable / len(seeds), scored
        return successes / len(seeds), len(seeds)

    score.reused = 0
    return score


VALIDATION_CUT = True
"""Whether ``validation_success`` stops driving a checkpoint that can no longer reach the best score
so far (:func:`_validation_scorer`); the selection is the same either way (a test checks it)."""
VALIDATION_REUSE = True
"""Whether ``validation_success`` reuses the outcome of an arena whose episode a policy acting by its
mode would drive again (:func:`_validation_scorer`); the scores are the same either way (a test
checks it)."""


def _clear_rl_run(run: RunDir) -> None:
    """Removes an RL run's files (for ``overwrite``); anything else in the directory refuses it."""
    ours = {RUN_FILE, MODEL_FILE, SELECTED_MODEL_FILE, EVAL_FILE, DISCRIMINATOR_FILE}
    leftovers = {p.name for p in leftover_temporaries(run.path)}  # a killed write's temporaries
    names = run.names() - leftovers
    selected = re.escape(SELECTED_MODEL_PATTERN).replace(re.escape("{steps}"), r"\d+")
    extra = {n for n in names - ours if not re.fullmatch(selected, n)}
    if not run.is_run or run.read_record().get("kind") != "rl" or extra:
        raise RunError(f"{run} is not an RL run directory; --overwrite replaces only an RL run")
    run.remove_leftovers()
    for name in sorted(names - {RUN_FILE}) + [RUN_FILE]:  # run.json last: a kill leaves an RL run
        run.file(name).unlink(missing_ok=True)


@writes("training")  # one writer at a time
def train_rl(
    run_dir: str | os.PathLike,
    task: specs.TaskSpec,
    algo: str = "ppo",
    steps: int = DEFAULT_STEPS,
    seed: int = 0,
    resume: bool = False,
    checkpoint_every: int | None = None,
    on_steps: Callable[[int, dict], None] | None = None,
    demos: str | os.PathLike | None = None,
    selection: str | None = None,
    envs: int | None = None,
    changes: dict | None = None,
    train_drive: str | None = None,
    overwrite: bool = False,
) -> dict:
    """Trains (or resumes) ``algo`` for ``steps`` decisions in ``run_dir``; returns the record.
    ``overwrite``: an RL run already in ``run_dir`` is replaced (only an RL run, and only once every
    argument has been checked and the demonstrations read, holding the run's lock).
    GAIL and AIRL need ``demos`` (a dataset path), the demonstrations they imitate. ``selection``
    (:data:`SELECTIONS`; default :func:`default_selection`) scores every checkpoint and keeps the
    best (``selected-<decisions>.zip``); ``envs`` environments share each rollout; ``changes`` tune
    PPO or DQN (:func:`tuned`); ``train_drive`` (``planar``, ``tyre`` or ``rollers``; "" the task's) is the
    drive of the training episodes (as NIRL's ``train_drive`` is of its own); this method's validation
    and tests drive ``task``.
    A resume given no ``selection`` (or ``envs``, ``train_drive`` None) takes the run's own.

    ``on_steps(new decisions, {"episodes", "success"})`` reports progress (success over the last
    100 training episodes). One writer at a time (``nirl_mj.data.lock``)."""
    cls = _algorithm(algo)
    if algo == "dqn" and task.control.actions != "discrete":
        raise ValueError(f"dqn needs discrete actions; task {task.name} has continuous ones: use --algo ppo")
    if algo in ADVERSARIAL and task.control.actions != "discrete":
        raise ValueError(f"{algo}'s discriminator judges the six discrete actions; task {task.name} has "
                         "continuous ones: accepted: --algo ppo")  # fmt: skip
    if steps < 1:
        raise ValueError(f"steps = {steps}: must be >= 1")
    run = RunDir(run_dir)
    if resume and run.is_run and (selection is None or envs is None or train_drive is None):
        saved_config = run.read_record().get("config", {})
        selection = selection or saved_config.get("selection", LEGACY["selection"])
        envs = envs or saved_config.get("envs", LEGACY["envs"])
        train_drive = saved_config.get("train_drive", "") if train_drive is None else train_drive
    selection, envs = selection or default_selection(algo), envs or LEGACY["envs"]
    config = run_config(algo, selection, envs, changes, train_drive or "")
    if checkpoint_every is not None and "checkpoint_every" in config:
        raise ValueError("checkpoint_every is given twice (argument and settings.checkpoint_every): give one")
    if checkpoint_every is None:
        checkpoint_every = config.get("checkpoint_every", CHECKPOINT_EVERY)
    if checkpoint_every < 1 or checkpoint_every % envs:
        raise ValueError(f"checkpoint_every = {checkpoint_every}: must be >= 1, a multiple of envs = {envs}")
    adversarial = algo in ADVERSARIAL
    if adversarial and demos is None:
        raise ValueError(f"{algo} imitates demonstrations: give --demos (a dataset)")
    trajectories = []
    if adversarial:
        from nirl_mj.experiments import adversarial as adv
        from nirl_mj.experiments.training import load_demonstrations

        trajectories = load_demonstrations(demos)  # a dataset file or minari:ID, as train reads
        config["discriminator"] = adv.variant_of(algo).settings()
    validation_arenas = config.get("validation_arenas", VALIDATION_ARENAS)
    record = {"kind": "rl", "algo": algo, "config": config, "steps": steps,
              "task": task.to_dict(), "seed": seed, "demos": _demos_name(demos) if adversarial else None,
              "demo_seeds": sorted({t.arena_seed for t in trajectories}),
              "validation_seeds": domain_seeds("validation", seed, validation_arenas)
              if selection == "validation_success" else [],
              "train_seeds": [], "steps_done": 0, "reads": rl_reads(algo, selection)}  # fmt: skip
    record = json.loads(json.dumps(record))  # as read back from run.json (tuples become lists)
    replay_to = 0  # a resume trains again from the seed up to it (:func:`_replays`)
    if resume:
        saved = run.read_record()
        if adversarial and _demos_name(saved.get("demos") or "") != record["demos"]:
            raise RunError(f"{run} imitated other demonstrations ({saved.get('demos')}); resume with those, "
                           "or train in a new --out")  # fmt: skip
        for key in ("kind", "config", "task", "seed"):
            if saved.get(key) != record[key]:
                raise RunError(f"{run} was trained with another {key}; resume with the same options, "
                               "or train in a new --out")  # fmt: skip
        run.remove_leftovers()
        if run.file(MODEL_FILE).is_file():
            _check_model_matches(run, saved["steps_done"])
        # a resume may train on to a larger total
        record = {**saved, "steps": steps, "reads": record["reads"]}
        if _finished(record, steps):
            return record
        if steps != saved["steps"]:  # two trainings from now on: no uninterrupted run to replay
            record["budgets"] = [*saved.get("budgets", [saved["steps"]]), steps]
        replay_to = _replays(record)
    elif not run.is_empty() and not overwrite:
        raise RunError(f"{run} exists and is not empty; pass --resume to continue it, --overwrite to "
                       "replace it, or choose another --out")  # fmt: skip
    else:
        if not run.is_empty():
            _clear_rl_run(run)
        run.write_record(record)

    legacy = "selection" not in config
    from_saved = resume and not replay_to
    # where training starts: the saved checkpoint, or the seed (a new run, or a replay)
    start = record if from_saved else {"train_seeds": [], "steps_done": 0}
    train_task = specs.replace(task, robot={"drive": config.get("train_drive", task.robot.drive)})
    venv, arenas = _environment(train_task, seed, len(start["train_seeds"]), envs, legacy, config)
    try:  # the environments are closed whatever fails after they start (a model that cannot load, ...)
        callbacks = []
        code, _ = observation_code(config)
        if adversarial:
            expert = adv.expert_transitions(trajectories, code, absorbing=adv.variant_of(algo).absorbing)
            reward = adv.AdversarialReward(algo, config["gamma"], expert, seed)
            if from_saved and run.file(adv.DISCRIMINATOR_FILE).is_file():
                reward.load_state(adv.read_discriminator(run))
            venv = adv.reward_wrapper(venv, reward)
            callbacks.append(adv.training_callback(venv, reward))
        settings = _model_settings(config)
        if from_saved and run.file(MODEL_FILE).is_file():
            model = cls.load(run.model_file(), env=venv, device="cpu")
        else:
            model = cls("MlpPolicy", venv, seed=seed, device="cpu", verbose=0, **settings)
        # a logger that writes nowhere: without one, each learn() makes an empty tempdir/SB3-<time> folder
        from stable_baselines3.common.logger import Logger

        model.set_logger(Logger(folder=None, output_formats=[]))
        if adversarial:
            reward.policy = model.policy
        done_before = list(start["train_seeds"])
        scorer = None  # training_success scores the outcomes the checkpoint is handed; last scores nothing
        if selection == "demo_balanced":
            scorer = _demo_scorer(model, trajectories, code)
        elif selection == "validation_success":
            scorer = _validation_scorer(model, record, task, seed)

        unchecked = bool(replay_to)  # a replay is checked once, at the saved checkpoint

        def checkpoint(outcomes: list[bool], final: bool = False) -> None:
            """Scores the model, keeps it if it is the best yet, then saves it (and the discriminator)
            and the record (``finished`` after the last update). ``outcomes``: the last training
            episodes ended (at most :data:`SUCCESS_WINDOW`). A replayed checkpoint is in the record
            already; at the saved one the replay is checked against the saved model
            (:func:`_same_as_saved`)."""
            nonlocal unchecked
            steps_now = int(model.num_timesteps)
            if steps_now < replay_to:
                return
            if unchecked:
                unchecked = False
                if steps_now != replay_to or not _same_as_saved(run, model, reward if adversarial else None):
                    # another machine's arithmetic, a run resumed by older code, a lost model: on from here
                    record["inexact_resumes"] = [*record.get("inexact_resumes", []), replay_to]
                if steps_now == replay_to:
                    return
            best = record.get("selected")
            score, driven = None, None
            if selection == "validation_success":
                score, driven = scorer(None if best is None else best["score"])
            elif scorer is not None:
                score = scorer()
            elif selection == "training_success" and outcomes:
                score = float(np.mean(outcomes))
            replaced = None
            if score is not None:
                # the episodes the score is over: the validation arenas, the demonstrations, or the window
                over = {
                    "validation_success": len(record["validation_seeds"]),
                    "demo_balanced": len(trajectories),
                }
                entry = {"steps": steps_now, "score": score, "episodes": over.get(selection, len(outcomes))}
                if driven is not None and driven < entry["episodes"]:
                    # cut short, it cannot be kept: no score, the most it could have reached, the
                    # arenas scored
                    entry.update(score=None, at_most=score, driven=driven)
                record["scores"] = [*record.get("scores", []), entry]
                unscored = best is not None and best["score"] != best["score"]  # NaN: any score replaces it
                better = best is None or unscored or (score >= best["score"] and steps_now > best["steps"])
                if better and entry["score"] is not None:  # a checkpoint cut short cannot be kept
                    # a file per selected checkpoint, named in the record: a kill between the two writes
                    # leaves the record naming a file that holds what it says
                    name = SELECTED_MODEL_PATTERN.format(steps=steps_now)
                    run.write_model(model.save, name)
                    record["selected"], replaced = {**entry, "file": name}, (best or {}).get("file")
            if selection == "training_success":
                record["recent_outcomes"] = list(outcomes)  # a resume scores on with the same window
            record.update(steps_done=steps_now, train_seeds=[*done_before, *arenas.used], finished=final)
            # the model, then the discriminator, right before the record, after the scoring (seconds
            # of validation episodes): a kill after the model's write leaves it ahead of its record,
            # which a resume refuses (:func:`_check_model_matches`); the window is a few file writes wide
            run.write_model(model.save)
            if adversarial:
                adv.save_discriminator(run, reward)
            run.write_record(record)
            if replaced:
                run.file(replaced).unlink(missing_ok=True)

        def replaying(n: int, stats: dict) -> None:
            """Progress in a replay: its decisions count as done already (the caller's count does)."""
            now = int(model.num_timesteps)
            on_steps(min(n, max(0, now - replay_to)),
                     {**stats, "replaying": f"{now}/{replay_to}"} if now < replay_to else stats)  # fmt: skip

        outcomes = start.get("recent_outcomes", [])
        progress = _Progress(
            checkpoint, checkpoint_every, replaying if on_steps and replay_to else on_steps, outcomes
        )
        callbacks.append(progress)
        model.learn(steps - start["steps_done"], callback=callbacks, reset_num_timesteps=not from_saved)
        progress.checkpoint_now(final=True)  # the model after its last update (never saved inside the loop)
    finally:
        venv.close()
    return record


def _finished(record: dict, steps: int) -> bool:
    """Whether a run's record holds its training for ``steps`` decisions: its last checkpoint, after the
    last update, written (``finished``; a record of older code has no such key: its decisions reached
    ``steps``). A checkpoint inside the loop may fall at the budget, before PPO's last rollout ends."""
    return record.get("steps_done", 0) >= steps and record.get("finished", True)


def _replays(record: dict) -> int:
    """The decisions an unfinished run's resume replays (0: none). A run stopped before its end is
    trained again from its seed up to its last checkpoint, keeping the scores its record holds (no
    validation episode is driven again), and trains on from there: it ends bit for bit as an
    uninterrupted run would, which no saved state gives (the episodes in progress, PPO's rollout, DQN's
    replay buffer, the discriminator's optimiser are not saved); a stop costs the training up to it,
    not its result. A run trained on to a new total (``budgets`` in its record: two trainings)
    continues from its saved model: no single training from its seed equals it."""
    done = record.get("steps_done", 0)
    return done if done > 0 and "budgets" not in record else 0


def _same_as_saved(run: RunDir, model: Any, reward: Any) -> bool:
    """Whether ``model`` and the discriminator ``reward`` (GAIL, AIRL; else None) equal the run's saved
    ones bit for bit: the decisions counted, the parameters and the optimisers' state."""
    import torch
    from stable_baselines3.common.save_util import load_from_zip_file

    def equal(a: Any, b: Any) -> bool:
        if isinstance(a, dict):
            return isinstance(b, dict) and a.keys() == b.keys() and all(equal(a[k], b[k]) for k in a)
        if isinstance(a, (list, tuple)):
            return isinstance(b, (list, tuple)) and len(a) == len(b) and all(map(equal, a, b))
        if isinstance(a, torch.Tensor | np.ndarray):
            return type(a) is type(b) and a.shape == b.shape and bool((a == b).all())
        return a == b

    from nirl_mj.experiments.adversarial import read_discriminator

    try:  # a lost or damaged file cannot vouch for the replay
        data, params, _ = load_from_zip_file(run.model_file(), device="cpu")
        discriminator = read_discriminator(run) if reward is not None else None
    except (RunError, OSError, ValueError, KeyError, zipfile.BadZipFile):
        return False
    if data.get("num_timesteps") != model.num_timesteps or not equal(params, model.get_parameters()):
        return False
    return reward is None or equal(discriminator, reward.state())


def _check_model_matches(run: RunDir, steps_done: int) -> None:
    """Refuses a saved model of other decisions than its record's ``steps_done``: a process killed
    between writing the model and the record leaves a model whose arenas, scores and outcomes the
    record does not hold (training on from it would train more than asked). Read from the archive's
    ``data`` entry, without torch; an archive that cannot be read is left to the loader's error."""
    try:
        with zipfile.ZipFile(run.model_file()) as archive:
            saved = int(json.loads(archive.read("data"))["num_timesteps"])
    except (OSError, KeyError, ValueError, TypeError, zipfile.BadZipFile):
        return
    if saved != steps_done:
        raise RunError(f"{run}: its model holds {saved} decisions but its record {steps_done} (the process "
                       "was stopped between the two writes); it cannot be used: train it again (nirl-mj rl "
                       f"--overwrite or a new --out; in an experiment, move {run} aside and run it "
                       "again)")  # fmt: skip


def _demos_name(demos: str | os.PathLike) -> str:
    """Demonstrations as a run records them: ``minari:ID``, or a dataset file's absolute path (so that a
    resume from another directory finds the same file)."""
    text = str(demos)
    return text if text.startswith("minari:") or not text else str(Path(text).resolve())


def _Progress(
    checkpoint: Callable[[list[bool], bool], None], every: int, on_steps, outcomes: list[bool]
) -> Any:
    """A Stable-Baselines3 callback: progress after every step, a checkpoint every ``every`` steps
    (handed the outcomes of the last training episodes, at most :data:`SUCCESS_WINDOW`, starting from
    ``outcomes``), but not at the last step of learning: the model is updated after it, and the
    caller checkpoints then."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Progress(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.outcomes: list[bool] = [bool(o) for o in outcomes]

        def last_step(self) -> bool:
            """Whether learning ends after this step: the target reached and, for PPO, its rollout full."""
            if self.num_timesteps < self.model._total_timesteps:
                return False
            n, rollout = self.locals.get("n_steps"), self.locals.get("n_rollout_steps")
            return n is None or rollout is None or n == rollout - 1

        def checkpoint_now(self, final: bool = False) -> None:
            checkpoint(self.outcomes[-SUCCESS_WINDOW:], final)

        def _on_step(self) -> bool:
            for info, done in zip(self.locals["infos"], self.locals["dones"], strict=True):
                if done:
                    self.outcomes.append(bool(info.get("is_success")))
            if on_steps:
                recent = self.outcomes[-100:]
                on_steps(self.training_env.num_envs, {"episodes": len(self.outcomes),
                         "success": sum(recent) / len(recent) if recent else float("nan")})  # fmt: skip
            if self.num_timesteps % every == 0 and not self.last_step():
                self.checkpoint_now()
            return True

    return Progress()


def ensure_rl_trained(
    run_dir: str | os.PathLike,
    task: specs.TaskSpec,
    algo: str,
    steps: int,
    seed: int,
    demos: str | os.PathLike | None = None,
    selection: str | None = None,
    envs: int = 1,
    changes: dict | None = None,
    train_drive: str = "",
) -> dict:
    """Trains the run, resumes it from its last checkpoint, or returns a finished one's record (an
    experiment's cell: ``nirl_mj.experiments.protocol.policy_of``)."""
    run = RunDir(run_dir)
    if run.is_run:
        record = run.read_record()
        if _finished(record, steps) and run.file(MODEL_FILE).is_file():
            _check_model_matches(run, record["steps_done"])
            return record
    return train_rl(run_dir, task, algo, steps, seed, resume=run.is_run, demos=demos, selection=selection,
                    envs=envs, changes=changes, train_drive=train_drive)  # fmt: skip


def is_rl_run(record: dict) -> bool:
    return record.get("kind") == "rl"


def _twist_scale(model, record: dict) -> np.ndarray | None:
    """(m/s, rad/s) of a continuous action of 1, for a model acting in the normalised space of
    ``gym.env.NavigationEnv`` (models saved before it was normalised act in m/s and rad/s: None)."""
    if record["task"]["control"].get("actions", "discrete") != "continuous":
        return None
    if not np.allclose(np.asarray(model.action_space.high, dtype=np.float64), 1.0):
        return None
    from nirl_mj.sim.task import action_scale

    return action_scale(specs.from_dict(record["task"], "run record: task"))


def load_rl_policy(
    run_dir: str | os.PathLike,
    sampled: bool | None = None,
    seed: int = 0,
    policy: str = "selected",
    shares: bool = False,
) -> tuple[Callable[[np.ndarray], int | np.ndarray], dict]:
    """The trained RL policy on phi(s) and the run's record: the checkpoint its selection chose
    (``policy="selected"``; the last one for a run that selects none) or the last (``"last"``).

    PPO's policy is a distribution over the six actions; with ``sampled`` each action is drawn from
    it with a generator seeded by ``seed``, so an evaluation is reproducible; ``sampled=False`` takes
    its mode; ``None`` (the default) drives as the run's setting ``act`` says (:data:`CHOICES`;
    ``sampled`` unless set). DQN, and PPO with continuous actions, act by their deterministic mode:
    a continuous action in m/s and rad/s, or with ``shares`` as the float32 shares in [-1, 1] that
    ``sim.episode.run_episode`` (``nirl-mj eval``) and the Gymnasium environment take."""
    run = RunDir(run_dir)
    record = run.read_record()
    if not is_rl_run(record):
        raise RunError(f"{run} is not an RL run ({RUN_FILE} has no kind = rl)")
    if policy not in POLICIES:
        raise ValueError(f"policy {policy!r}: accepted: {', '.join(POLICIES)}")
    chosen = MODEL_FILE
    if policy == "selected" and "selected" in record:  # runs before 2026-11-26's review: selected.zip
        chosen = record["selected"].get("file", SELECTED_MODEL_FILE)
    model = _algorithm(record["algo"]).load(run.model_file(chosen), device="cpu")
    return model_policy(model, record, sampled, seed, shares), record


def _samples(record: dict, sampled: bool | None) -> bool:
    """Whether :func:`model_policy` draws each action (a discrete PPO policy, ``sampled`` or, if None,
    the run's ``act``) rather than taking its mode."""
    if sampled is None:
        sampled = record.get("config", {}).get("act", "sampled") == "sampled"
    discrete = record["task"]["control"].get("actions", "discrete") == "discrete"
    return sampled and discrete and record["algo"] != "dqn"


def model_policy(
    model: Any, record: dict, sampled: bool | None, seed: int, shares: bool
) -> Callable[[np.ndarray], int | np.ndarray]:
    """``model``'s policy on phi(s) as :func:`load_rl_policy` describes it (``record``: its run's, or
    any dict with the ``algo``, the task's ``control.actions`` and, where set, ``config.act``)."""
    code, _ = observation_code(record.get("config", {}))
    if _samples(record, sampled):
        import torch

        rng = np.random.default_rng(seed)

        def sample(phi: np.ndarray) -> int:
            with torch.no_grad():
                dist = model.policy.get_distribution(torch.as_tensor(code(phi))[None])
            probs = dist.distribution.probs[0].numpy().astype(np.float64)
            return int(rng.choice(len(probs), p=probs / probs.sum()))

        return sample

    scale = _twist_scale(model, record)
    bounds = None  # a continuous model saved before the action space was normalised acts in m/s, rad/s
    if scale is None and shares and record["task"]["control"].get("actions", "discrete") == "continuous":
        from nirl_mj.sim.task import action_scale

        bounds = action_scale(specs.from_dict(record["task"], "run record: task"))

    def mode(phi: np.ndarray) -> int | np.ndarray:
        action, _ = model.predict(code(phi), deterministic=True)
        if scale is not None:  # continuous, normalised: (forward m/s, yaw rate rad/s) for the task
            share = np.clip(action, -1.0, 1.0)
            return share.astype(np.float32) if shares else share * scale
        if bounds is not None:
            return np.clip(np.asarray(action, np.float64) / bounds, -1.0, 1.0).astype(np.float32)
        return action if np.ndim(action) else int(action)

    return mode
