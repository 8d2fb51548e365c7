"""Experiment specifications: the only module that reads experiment files (``tasks/table1.toml``, ...).

An experiment file is TOML. ``kind = "compare"`` (the paper's Table I protocol,
``nirl-mj compare``), ``kind = "sweep"`` (Fig. 6, ``nirl-mj sweep``) or ``kind = "suite"``
(the protocol of compare along one or more ``[[axis]]``, ``nirl-mj suite``) says what
runs it; every other key is documented in docs/EXPERIMENTS.md. An unknown key,
a wrong type or a value out of range raises :class:`ExperimentError` naming the
file, the key and what is accepted, as task files do (``nirl_mj.sim.spec``).

A *method* is a row of the results: a trainable IRL method (``kind = "irl"``:
NIRL's loop with a reward step from ``nirl_mj.learn.methods.REWARD_STEPS`` and a
preset of ``nirl_mj.learn.config``), behaviour cloning (``"bc"``), DAgger with the
demonstrator as its interactive expert (``"dagger"``, ``nirl_mj.experiments.dagger``), a
reference policy (``"forward"``, ``"rule"``), the demonstrator itself driving the test arenas
(``"expert"``), or a Stable-Baselines3 learner (``"rl"``,
``nirl_mj.experiments.rl``; compare and suite experiments, not sweep; needs ``nirl-mj[gym]``): PPO or DQN on
the task's reward (the RL reference), or GAIL / AIRL, PPO on a discriminator's reward learned
from the demonstrations. The built-in ones are :data:`BUILTIN_METHODS`; ``[method.NAME]``
tables add others or change built-in ones.

``[quick]`` holds values of the same keys that ``--quick`` uses instead (tables
merged key by key): the smoke version of the same experiment.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nirl_mj.experiments.rl import ALGOS, DEFAULT_STEPS, LEGACY, SELECTIONS, run_config
from nirl_mj.experiments.seeds import SEED_LIMIT, TEST_DOMAINS
from nirl_mj.experts import demonstrator_names
from nirl_mj.learn.config import METHODS, VARIANTS, LearnerConfig, checked_changes, without_retired
from nirl_mj.sim import spec as specs
from nirl_mj.sim.floorplans import FAMILIES
from nirl_mj.sim.spec import SpecError

KINDS = specs.EXPERIMENT_KINDS
METHOD_KINDS = ("irl", "bc", "dagger", "forward", "rule", "rl", "expert", "plugin")

COMMON_KEYS = ("kind", "description", "task", "test_task", "set", "seed", "runs", "tests", "methods",
               "method", "demos", "config", "quick", "test_domain")  # fmt: skip
KEYS = {
    "compare": (*COMMON_KEYS, "paper", "strip"),
    "sweep": (*COMMON_KEYS, "obstacles", "speeds"),
    "suite": (*COMMON_KEYS, "axis"),
}
DEMO_KEYS = ("expert", "episodes", "per_run")
METHOD_KEYS = (
    "kind",
    "variant",
    "method",
    "config",
    "algo",
    "steps",
    "selection",
    "envs",
    "settings",
    "train_drive",
    "plugin",
)
RL_KEYS = ("algo", "steps", "selection", "envs", "settings", "train_drive")  # kind = "rl" (dagger: settings)
PAPER_KEYS = ("avg", "best", "worst")
STRIP_KEYS = ("method", "snapshots", "camera", "width", "height")
AXIS_KEYS = ("name", "values", "test_task")
SET_SECTIONS = ("arena", "robot", "sensing", "control")
_NAME = re.compile(r"^[A-Za-z0-9_-]+$")  # method names become file and cell names


class ExperimentError(SpecError):
    """An experiment file or value is invalid; the message names the key and what is accepted."""


@dataclass(frozen=True)
class MethodSpec:
    """One row of the results. ``variant`` also chooses behaviour cloning's settings (``kind = "bc"``:
    ``learn.bc.CloneSettings.of``); ``variant``/``method``/``config`` matter for ``kind = "irl"``:
    ``LearnerConfig.preset(variant, method=method, **experiment config, **config)``; ``algo``,
    ``steps`` (decisions of training), ``selection`` (``experiments.rl.SELECTIONS``), ``envs``
    (environments sharing each rollout), ``settings`` (PPO's, ``experiments.rl.TUNABLE``; DQN's,
    ``TUNABLE_DQN``) and ``train_drive`` (the training episodes' drive, ``sim.spec.DRIVES``; "" the
    task's) for ``kind = "rl"`` only; ``settings`` also for ``kind = "dagger"`` (its rounds and
    learner episodes per round: ``experiments.dagger.DaggerConfig.of``) and ``"plugin"``."""

    name: str
    kind: str
    variant: str = "default"
    method: str = "nirl"
    config: dict = field(default_factory=dict)
    algo: str = "ppo"
    steps: int = DEFAULT_STEPS
    selection: str = LEGACY["selection"]
    envs: int = LEGACY["envs"]
    settings: dict = field(default_factory=dict)  # rl: experiments.rl.TUNABLE(_DQN); dagger: its budget
    plugin: str = ""  # kind "plugin": the entry point of group nirl_mj.methods (experiments.plugins)
    declared_reads: tuple[str, ...] = ()  # kind "plugin": what the method declares it reads
    train_drive: str = ""  # rl: the training episodes' drive ("": the task's; tests drive the task's)

    @property
    def trains(self) -> bool:
        """Whether this method is a learner of NIRL's loop (kind ``irl``): learner settings, and a
        training run (``OUT/runs/NAME/SEED``) that a sweep trains as a cell of its own. An ``rl`` or
        plugin method keeps a run directory there too, trained inside its test cell."""
        return self.kind == "irl"

    @property
    def drives_continuous(self) -> bool:
        """Whether this method can act on a task with continuous actions: the references and the
        demonstrator (each decision driven as its continuous twin) and PPO on the reward. The
        learners from demonstrations choose among the six discrete actions."""
        return self.kind in ("forward", "rule", "expert") or (self.kind == "rl" and self.algo == "ppo")

    def learner_config(self, shared: dict) -> LearnerConfig:
        """The learner's configuration: the variant's, then the experiment's ``[config]``, then ours."""
        return LearnerConfig.preset(self.variant, **{**shared, **self.config, "method": self.method})


RL_STEPS, RL_ENVS = 50_000, 8
"""The budget (decisions) and the environments per rollout of GAIL and AIRL (the rows of
tasks/table1.toml; the variants of issue 16 keep one environment and no selection); the RL references
train twice as long, PPO-reward at PPO's learning rate decayed linearly to 0."""

BUILTIN_METHODS = {
    "NIRL": MethodSpec("NIRL", "irl", "default", "nirl"),
    "NIRL-paper": MethodSpec("NIRL-paper", "irl", "paper", "nirl"),
    # the default's last iterate: the same training (selection does not change it), no selection
    "NIRL-last": MethodSpec("NIRL-last", "irl", "default", "nirl", {"selection": "last"}),
    # the default's margin until 2026-11-25: every action an alternative, a classifier of the expert's
    # actions that never reads the learner's rollouts (docs/ALGORITHM.md)
    "NIRL-classifier": MethodSpec("NIRL-classifier", "irl", "default", "nirl", {"matching": "occupancy"}),
    "AL": MethodSpec("AL", "irl", "default", "al"),  # per-state reading (learn/al.py)
    # per-state reading (learn/reirl.py) without the L1 term (re_confidence = 0: Hoeffding widths of 0,
    # a conditional logit of the expert's actions): tuned on the development domain
    # (tasks/ablations/baselines_discount.toml); the widths zeroed all but two components of theta
    "RE": MethodSpec("RE", "irl", "default", "re", {"re_confidence": 0.0}),
    # the whole-trajectory reading of eq. 11 (the papers'; the default rows until 2026-11-25)
    "AL-traj": MethodSpec("AL-traj", "irl", "default", "al", {"al_expectations": "trajectory"}),
    "RE-traj": MethodSpec("RE-traj", "irl", "default", "re", {"re_expectations": "trajectory"}),
    # the paper's discount: tuned on the development domain (tasks/ablations/scirl_tuning.toml);
    # at NIRL's 0.9, SCIRL's heuristic scores weigh the pair itself 1 - gamma = 10 %
    "SCIRL": MethodSpec("SCIRL", "irl", "default", "scirl", {"gamma": 0.65}),
    # behaviour cloning with the default NIRL's inputs and width, a class-balanced loss and early
    # stopping on held-out demonstrations (learn/bc.py); BC-paper: the paper's network, unweighted
    # (the BC row until 2026-11-26)
    "BC": MethodSpec("BC", "bc"),
    "BC-paper": MethodSpec("BC-paper", "bc", "paper"),
    "DAgger": MethodSpec("DAgger", "dagger"),
    "forward": MethodSpec("forward", "forward"),
    "rule": MethodSpec("rule", "rule"),
    # the experiment's demonstrator driving the test arenas (its own success and SPL)
    "expert": MethodSpec("expert", "expert"),
    # the RL reference, driven by its policy's mode (greedy, as NIRL and the rule act) in validation
    # and tests, its checkpoint chosen by success on 20 validation arenas (it reads the task's reward
    # anyway); all tuned on the development domain: the budget (tasks/ablations/rl_reference.toml),
    # greedy driving and the selection (tasks/ablations/rl_greedy.toml: sampled, it collided in
    # 13-16 % of the tests there), the learning rate (tasks/ablations/rl_bearing.toml, below) and its
    # linear decay to 0 (tasks/ablations/rl_schedule.toml: 94.8 % against 90.8 %);
    # 50,000 and 200,000 decisions scored less there and in tasks/ablations/rl_budget.toml; 50
    # validation arenas changed one run in five (tasks/ablations/rl_validation.toml); NIRL's bearing
    # code for V (cos, sin of its sector's centre), as NIRL, BC and DAgger see it, stopped the fall
    # but scored less at 1e-4 (tasks/ablations/rl_inputs.toml) and more at 3e-4, Stable-Baselines3's
    # default (tasks/ablations/rl_bearing.toml: 98.0 % against 94.8 % and the rule's 96.8 %)
    "PPO-reward": MethodSpec(
        "PPO-reward",
        "rl",
        algo="ppo",
        steps=2 * RL_STEPS,
        selection="validation_success",
        envs=RL_ENVS,
        settings={"learning_rate": 3e-4, "lr_schedule": "linear", "act": "greedy", "inputs": "bearing"},
    ),  # fmt: skip
    # the same reference by DQN (experiments.rl.SETTINGS["dqn"], one environment), acting greedily on its
    # Q-values as NIRL and the rule do; its checkpoint chosen by success on 20 validation arenas,
    # driven as the tests drive it: training success kept checkpoints whose greedy policy timed out
    # (tasks/ablations/rl_dqn.toml)
    "DQN-reward": MethodSpec(
        "DQN-reward", "rl", algo="dqn", steps=2 * RL_STEPS, selection="validation_success", envs=1
    ),
    # adversarial imitation: PPO (SB3's settings but 1024-decision rollouts, 50,000 decisions) on a
    # discriminator's reward, its checkpoint chosen by the paper's rule (balanced accuracy on the
    # demonstrations); AIRL's policy and discriminator see phi(s) in NIRL's bearing code, GAIL's
    # scaled, and AIRL's tests take its policy's mode, GAIL's draw from it (each the higher on the
    # development domain: tasks/ablations/adversarial_bearing.toml, rl_greedy.toml)
    "GAIL": MethodSpec("GAIL", "rl", algo="gail", steps=RL_STEPS, selection="demo_balanced", envs=RL_ENVS),
    "AIRL": MethodSpec(
        "AIRL",
        "rl",
        algo="airl",
        steps=RL_STEPS,
        selection="demo_balanced",
        envs=RL_ENVS,
        settings={"inputs": "bearing", "act": "greedy"},
    ),
    # GAIL's last checkpoint (as NIRL-last is NIRL's) with PPO's rate decayed linearly to 0: the higher last
    # checkpoints on the development domain (tasks/ablations/adversarial_schedule.toml: 78.8 % against
    # 66.8 at GAIL's constant rate), where GAIL's rule kept the decayed run's early checkpoints
    "GAIL-linear-last": MethodSpec(
        "GAIL-linear-last",
        "rl",
        algo="gail",
        steps=RL_STEPS,
        selection="last",
        envs=RL_ENVS,
        settings={"lr_schedule": "linear"},
    ),
    # the same with an absorbing state (Kostrikov et al. 2019): an episode's end is no longer free
    "GAIL-absorbing": MethodSpec("GAIL-absorbing", "rl", algo="gail-absorbing", steps=50_000),
    "AIRL-absorbing": MethodSpec("AIRL-absorbing", "rl", algo="airl-absorbing", steps=50_000),
    # the policy's reward centred and scaled as it runs (the imitation library's default for AIRL)
    "GAIL-norm": MethodSpec("GAIL-norm", "rl", algo="gail-norm", steps=50_000),
    "AIRL-norm": MethodSpec("AIRL-norm", "rl", algo="airl-norm", steps=50_000),
    # the discriminator regularised by a gradient penalty on the expert's pairs (R1), weight 10, 1, 0.1
    "GAIL-gp": MethodSpec("GAIL-gp", "rl", algo="gail-gp", steps=50_000),
    "AIRL-gp": MethodSpec("AIRL-gp", "rl", algo="airl-gp", steps=50_000),
    "GAIL-gp1": MethodSpec("GAIL-gp1", "rl", algo="gail-gp1", steps=50_000),
    "AIRL-gp1": MethodSpec("AIRL-gp1", "rl", algo="airl-gp1", steps=50_000),
    "GAIL-gp0_1": MethodSpec("GAIL-gp0_1", "rl", algo="gail-gp0_1", steps=50_000),
    "AIRL-gp0_1": MethodSpec("AIRL-gp0_1", "rl", algo="airl-gp0_1", steps=50_000),
    # AIRL's reward as a state-only g(s), Fu et al.'s disentangled form
    "AIRL-state": MethodSpec("AIRL-state", "rl", algo="airl-state", steps=50_000),
    # 2 discriminator steps per rollout, each on all of it (the imitation library's default number)
    "GAIL-d2": MethodSpec("GAIL-d2", "rl", algo="gail-d2", steps=50_000),
    "AIRL-d2": MethodSpec("AIRL-d2", "rl", algo="airl-d2", steps=50_000),
}
"""The methods an experiment may list without defining them."""


@dataclass(frozen=True)
class StripSpec:
    """The Fig. 8 strip: ``snapshots`` frames of ``method``'s first run on its first test arena."""

    method: str
    snapshots: int = 5
    camera: str = "top"
    width: int = 480
    height: int = 360


TRAINING_AXES = {
    "demonstrations": "episodes of demonstrations per run",
    "demonstrator": "who demonstrates (nirl_mj.experts: an expert kind or a DEMONSTRATORS name)",
}
"""Axes along which the learners train again: a value changes the demonstrations."""

TEST_AXES = {
    "obstacles": ("arena", "static_obstacles"),
    "speed": ("control", "speed"),
    "moving": ("arena", "moving_obstacles"),
    "family": ("arena", "floor_plan"),
}
"""Axes along which the policies trained once on ``task`` are tested unchanged: the test task's
(section, field) a value sets."""

AXES = (*TRAINING_AXES, *TEST_AXES)


@dataclass(frozen=True)
class Axis:
    """A suite's axis: ``name`` (:data:`AXES`), its ``values`` in order, and for a test axis the task
    its values change (the experiment's ``test_task`` unless the axis names its own)."""

    name: str
    values: tuple
    test_task: specs.TaskSpec | None = None

    @property
    def trains(self) -> bool:
        """Whether a value changes the training (the demonstrations) rather than the tests only."""
        return self.name in TRAINING_AXES

    def task_at(self, value: Any) -> specs.TaskSpec:
        """The test task at ``value`` of a test axis."""
        section, key = TEST_AXES[self.name]
        return specs.replace(self.test_task, **{section: {key: value}})

    def identity(self) -> dict:
        return {"name": self.name, "values": list(self.values),
                "test_task": None if self.test_task is None else self.test_task.to_dict()}  # fmt: skip


def value_name(value: Any) -> str:
    """An axis value as it appears in cell ids, file names and the CSV (3.0 -> "3")."""
    return f"{value:g}" if isinstance(value, float) else str(value)


@dataclass(frozen=True)
class Experiment:
    """A resolved experiment: tasks loaded, methods looked up, ``[quick]`` applied if asked."""

    kind: str
    name: str
    source: str
    description: str
    task: specs.TaskSpec  # demonstrations and training
    test_task: specs.TaskSpec  # the tests (the sweep's cells change its obstacles and speed)
    seed: int  # demonstrations; run r trains with seed + r and is tested on arenas of seed + r
    runs: int
    tests: int
    methods: tuple[MethodSpec, ...]
    expert: str
    demos: int
    config: dict  # learner config changes for every "irl" method
    paper: dict  # method -> {"avg", "best", "worst"} in percent
    strip: StripSpec | None
    obstacles: tuple[int, ...]
    speeds: tuple[float, ...]
    quick: bool
    # demonstrations drawn per run (run r's seeded seed + r) instead of one set for every run
    demos_per_run: bool = False
    test_domain: str = "test"  # "test": the development arenas; "final": the reported tables' arenas
    axes: tuple[Axis, ...] = ()  # a suite's
    # the file's [set] (with --quick, its [quick] table's merged in), as the tasks above hold it:
    # what --check prints; not part of the identity (the tasks are)
    overrides: dict = field(default_factory=dict, compare=False)

    def identity(self) -> dict:
        """Everything that changes a cell's result, as JSON: an output directory holds one identity."""
        data = {
            "kind": self.kind,
            "task": self.task.to_dict(),
            "test_task": self.test_task.to_dict(),
            "seed": self.seed,
            # not "runs": a run's cells depend on its index alone, so more runs extend an experiment
            "tests": self.tests,
            "methods": [_method_identity(m) for m in self.methods],
            "expert": self.expert,
            "demos": self.demos,
            "config": self.config,
            # The learners' resolved settings too: a training run resumes only with its own
            # (nirl_mj.experiments.training), so a change of defaults in the code is refused here, up front.
            "learners": {m.name: m.learner_config(self.config).to_dict() for m in self.methods if m.trains},
            "obstacles": list(self.obstacles),
            "speeds": list(self.speeds),
        }
        # only when set: the identities of experiments written before these keys stay unchanged
        if self.demos_per_run:
            data["demos_per_run"] = True
        if self.test_domain != "test":
            data["test_domain"] = self.test_domain
        if self.axes:
            data["axes"] = [axis.identity() for axis in self.axes]
        return json.loads(json.dumps(data))

    def at(self, value: Any) -> Experiment:
        """A suite with a training axis at one of its values: the comparison its cells of that value
        belong to (the demonstrations' count or demonstrator changed)."""
        (axis,) = self.axes
        change = {"demonstrations": {"demos": value}, "demonstrator": {"expert": value}}[axis.name]
        return dataclasses.replace(self, kind="compare", axes=(), **change)

    def cell_task(self, obstacles: int, speed: float) -> specs.TaskSpec:
        """The test task of a sweep cell: ``obstacles`` static obstacles, ``speed`` m/s."""
        return specs.replace(
            self.test_task, arena={"static_obstacles": obstacles}, control={"speed": float(speed)}
        )


def load_experiment(path: str | Path, quick: bool = False, kind: str | None = None) -> Experiment:
    """Reads and validates an experiment file (a path, or a name under ``tasks/``); with ``kind``,
    refuses an experiment of another kind (naming the command that runs it)."""
    given, path = path, specs.shipped_path(path)
    if path.suffix != ".toml" and not path.is_file():
        path = specs.TASKS_DIR / f"{path}.toml"
        if not path.is_file():
            names = ", ".join(shipped_experiments(kind))
            raise ExperimentError(f"no experiment {str(given)!r} under tasks/: accepted: {names}, or a .toml "
                                  "file's path (tasks/ablations/ and tasks/archive/ hold more)")  # fmt: skip
    data = specs.read_toml(path, "experiment file", ExperimentError)
    experiment = from_dict(data, str(path), path.parent, quick)
    if kind is not None and experiment.kind != kind:
        raise ExperimentError(
            f"{given} is a {experiment.kind} experiment: run it with `nirl-mj {experiment.kind}`"
        )
    return experiment


def shipped_experiments(kind: str | None = None) -> list[str]:
    """The names (under ``tasks/``, without ``.toml``) of the shipped experiments of ``kind`` (any kind
    if None), but those of ``tasks/ablations/`` and ``tasks/archive/``: dozens of past measurements."""
    names = []
    for path in sorted(specs.TASKS_DIR.rglob("*.toml")):
        name = path.relative_to(specs.TASKS_DIR).with_suffix("")
        if name.parts[0] in ("ablations", "archive"):
            continue
        try:
            found = specs.read_toml(path, "experiment file", ExperimentError).get("kind")
        except ExperimentError:
            continue
        if found in KINDS and kind in (None, found):
            names.append(name.as_posix())
    return names


def from_dict(
    data: dict, source: str = "<dict>", base: Path | None = None, quick: bool = False
) -> Experiment:
    """Validates a plain dict (as read from TOML); relative task paths are taken from ``base``."""
    kind = data.get("kind")
    if kind is None and {"arena", "robot", "sensing", "control"} & set(data):
        kinds = " or ".join(map(repr, KINDS))
        raise ExperimentError(f"{source} is a task file, not an experiment: an experiment names it with "
                              f"task = ... and says kind = {kinds} (docs/EXPERIMENTS.md)")  # fmt: skip
    if kind not in KINDS:
        raise ExperimentError(f"{source}: kind = {kind!r}: accepted: {', '.join(KINDS)}")
    _known(data, KEYS[kind], source, f"(kind {kind})")
    overrides = _table(data.get("quick", {}), f"{source}: quick")
    _known(overrides, [k for k in KEYS[kind] if k not in ("kind", "quick")], f"{source}: quick", "")
    full_methods = data.get("methods", ["NIRL"])
    if quick and "quick" not in data:  # else --quick would run the full protocol under a -quick name
        raise ExperimentError(f"{source} has no [quick] table, whose values --quick takes: run it without "
                              "--quick (or --runs 1), or give it one (docs/EXPERIMENTS.md)")  # fmt: skip
    if quick:
        data = _merge(data, overrides)
    quick_keys = data.get("quick", {}) if quick else {}

    def where(key: str) -> str:
        """Where a key's value came from, for error messages."""
        return f"{source}: {'quick.' if key in quick_keys else ''}{key}"

    base = base or specs.TASKS_DIR.parent  # a dict from no file: relative paths are the checkout's

    overrides = _table(data.get("set", {}), where("set"))
    _known(overrides, SET_SECTIONS, where("set"), "")
    for section, values in overrides.items():  # each a table of the task's section (arena = {...})
        _table(values, f"{where('set')}.{section}")
    task = _task(data.get("task", "navigate"), base, overrides, where("task"), where("set"))
    test_task = _task(
        data.get("test_task", data.get("task", "navigate")), base, overrides, where("test_task"), where("set")
    )

    demos = _table(data.get("demos", {}), where("demos"))
    _known(demos, DEMO_KEYS, where("demos"), "")
    expert = _choice(demos.get("expert", "sensor"), demonstrator_names(), f"{where('demos')}.expert")
    config = _learner_changes(_table(data.get("config", {}), where("config")), where("config"))
    try:  # each value in its range here, named as [config]'s, whichever learners read it (or none)
        LearnerConfig.preset("default", **config)
    except ValueError as exc:
        raise ExperimentError(f"{where('config')}: {exc}") from None
    methods = _methods(data, config, where, full_methods)

    strip = None
    if "strip" in data:
        table = _table(data["strip"], where("strip"))
        _known(table, STRIP_KEYS, where("strip"), "")
        strip = StripSpec(
            method=_member(table.get("method"), [m.name for m in methods], f"{where('strip')}.method"),
            snapshots=_int(table.get("snapshots", 5), f"{where('strip')}.snapshots", 2),  # a strip's two ends
            camera=_str(table.get("camera", "top"), f"{where('strip')}.camera"),
            width=_int(table.get("width", 480), f"{where('strip')}.width", 16),
            height=_int(table.get("height", 360), f"{where('strip')}.height", 16),
        )
        _check_frame(strip, where("strip"))
    experiment = Experiment(
        kind=kind,
        name=Path(source).stem,
        source=source,
        description=_str(data.get("description", ""), where("description")),
        task=task,
        test_task=test_task,
        seed=_int(data.get("seed", 0), where("seed"), 0),
        runs=_int(data.get("runs", 1), where("runs"), 1),
        tests=_int(data.get("tests", 100), where("tests"), 1),
        methods=methods,
        expert=expert,
        demos=_int(demos.get("episodes", 30), f"{where('demos')}.episodes", 1),
        config=config,
        paper=_paper(data.get("paper", {}), methods, where("paper"), full_methods),
        strip=strip,
        obstacles=tuple(_int(v, f"{where('obstacles')}[{i}]", 0)
                        for i, v in enumerate(_list(data.get("obstacles", []), where("obstacles")))),
        speeds=tuple(_number(v, f"{where('speeds')}[{i}]")
                     for i, v in enumerate(_list(data.get("speeds", []), where("speeds")))),
        quick=quick,
        demos_per_run=_bool(demos.get("per_run", False), f"{where('demos')}.per_run"),
        test_domain=_choice(data.get("test_domain", "test"), TEST_DOMAINS, where("test_domain")),
        axes=_axes(data, test_task, base, where, overrides) if kind == "suite" else (),
        overrides=overrides,
    )  # fmt: skip
    check_seed_range(experiment, where("seed"))
    check_actions(experiment.methods, (experiment.task, experiment.test_task), source)
    if kind == "sweep":
        rl = [m.name for m in methods if m.kind == "rl"]
        if rl:
            raise ExperimentError(f'{where("methods")}: {", ".join(rl)}: kind = "rl" runs in compare '
                                  "and suite experiments, not in a sweep")  # fmt: skip
        if not experiment.obstacles or not experiment.speeds:
            raise ExperimentError(f"{source}: a sweep needs non-empty obstacles and speeds lists")
        for key, names in (("obstacles", [str(n) for n in experiment.obstacles]),
                           ("speeds", [f"{v:g}" for v in experiment.speeds])):  # fmt: skip
            if len(set(names)) != len(names):
                raise ExperimentError(f"{source}: {key} {names}: every value must differ (one cell each)")
        for n in experiment.obstacles:
            for v in experiment.speeds:
                try:
                    experiment.cell_task(n, v)
                except SpecError as exc:
                    raise ExperimentError(f"{source}: cell ({n} obstacles, {v} m/s): {exc}") from None
    if not quick and "quick" in data:  # a mistake in [quick] is found now, not at the first --quick
        try:
            from_dict(data, source, base, quick=True)
        except ExperimentError as exc:
            raise ExperimentError(f"{exc} (in the file's --quick run: its [quick] table)") from None
    return experiment


def check_seed_range(experiment: Experiment, where: str) -> None:
    """Refuses run seeds ``seed .. seed + runs - 1`` beyond 2^32 - 1 (:data:`seeds.SEED_LIMIT`)."""
    if experiment.seed + experiment.runs - 1 >= SEED_LIMIT:
        raise ExperimentError(f"{where} = {experiment.seed} with runs = {experiment.runs}: the run seeds "
                              "seed .. seed + runs - 1 must stay in 0 .. 2^32 - 1")  # fmt: skip


def _axes(data: dict, test_task: specs.TaskSpec, base: Path, where, overrides: dict) -> tuple[Axis, ...]:
    """A suite's ``[[axis]]`` tables: one training axis, or one or more test axes."""
    tables = _list(data.get("axis", []), where("axis"))
    if not tables:
        raise ExperimentError(
            f"{where('axis')}: a suite needs at least one [[axis]] table; axes: {', '.join(AXES)}"
        )
    axes = []
    for i, table in enumerate(tables):
        at = f"{where('axis')}[{i}]"
        table = _table(table, at)
        _known(table, AXIS_KEYS, at, "")
        name = _choice(table.get("name"), AXES, f"{at}.name")
        values = _list(table.get("values"), f"{at}.values")
        if not values:
            raise ExperimentError(f"{at}.values: list at least one value")
        checked = tuple(_axis_value(name, v, f"{at}.values[{j}]") for j, v in enumerate(values))
        if len({value_name(v) for v in checked}) != len(checked):
            raise ExperimentError(f"{at}.values {list(values)}: every value must differ (one point each)")
        if name in TRAINING_AXES:
            if "test_task" in table:
                raise ExperimentError(f"{at}.test_task: only a test axis ({', '.join(TEST_AXES)}) takes one")
            axes.append(Axis(name, checked))
            continue
        # an axis's own task keeps its arenas; the robot, its sensing and control stay [set]'s
        robot = {k: v for k, v in overrides.items() if k != "arena"}
        task = (
            _task(table["test_task"], base, robot, f"{at}.test_task", where("set"))
            if "test_task" in table
            else test_task
        )
        axis = Axis(name, checked, task)
        for v in checked:
            try:
                axis.task_at(v)
            except SpecError as exc:
                raise ExperimentError(f"{at}: {name} = {value_name(v)}: {exc}") from None
        axes.append(axis)
    names = [a.name for a in axes]
    if len(set(names)) != len(names):
        raise ExperimentError(f"{where('axis')}: an axis is given twice: {names}")
    if any(a.trains for a in axes) and len(axes) > 1:
        raise ExperimentError(
            f"{where('axis')}: {names}: a training axis ({', '.join(TRAINING_AXES)}) "
            "must be the suite's only axis (its values train every learner again)"
        )
    return tuple(axes)


def _axis_value(name: str, value: Any, where: str) -> Any:
    if name in ("demonstrations",):
        return _int(value, where, 1)
    if name in ("obstacles", "moving"):
        return _int(value, where, 0)
    if name == "speed":
        return _number(value, where, 0.0)
    accepted = demonstrator_names() if name == "demonstrator" else FAMILIES
    return _choice(value, accepted, where)


def check_actions(methods: Sequence[MethodSpec], tasks: Sequence[specs.TaskSpec], source: str) -> None:
    """Refuses, before anything runs, methods that cannot act on a task with continuous actions."""
    continuous = [t.name for t in tasks if t.control.actions == "continuous"]
    discrete = [m.name for m in methods if not m.drives_continuous]
    if continuous and discrete:
        raise ExperimentError(
            f"{source}: task {continuous[0]} has continuous actions, and {', '.join(discrete)} choose among "
            'the six discrete actions: accepted on it: rule, forward, expert and kind = "rl" with '
            'algo = "ppo"; or set [control] actions = "discrete"'
        )


def _methods(data: dict, config: dict, where, full_methods: list) -> tuple[MethodSpec, ...]:
    """The listed methods resolved; a ``[method.NAME]`` table must name one of them, or one of
    ``full_methods`` (the file's list, which ``[quick] methods`` may shorten)."""
    defined = _table(data.get("method", {}), where("method"))
    names = _list(data.get("methods", ["NIRL"]), where("methods"))
    if not names:
        raise ExperimentError(f"{where('methods')}: list at least one method")
    out = []
    for name in names:
        if not isinstance(name, str) or not _NAME.match(name):
            raise ExperimentError(f"{where('methods')}: {name!r}: a name of letters, digits, _ and -")
        if name not in defined and name not in BUILTIN_METHODS and name not in _installed():
            raise ExperimentError(
                f"{where('methods')}: unknown method {name!r}; built in: {', '.join(BUILTIN_METHODS)}; "
                f"{_installed_text()}; or define it in a [method.NAME] table"
            )
        out.append(_method(name, defined.get(name), config, f"{where('method')}.{name}"))
    if len(set(names)) != len(names):
        raise ExperimentError(f"{where('methods')}: a method is listed twice: {names}")
    listed = {n for n in full_methods if isinstance(n, str)} if isinstance(full_methods, list) else set()
    for name in sorted((set(defined) - set(names)) & listed):  # kept for the full run, checked all the same
        _method(name, defined[name], config, f"{where('method')}.{name}")
    unused = sorted(set(defined) - set(names) - listed)
    if unused:
        raise ExperimentError(f"{where('method')}: {', '.join(unused)} defined but not in methods = {names}")
    return tuple(out)


def _installed() -> dict:
    from nirl_mj.experiments.plugins import discovered

    return discovered()


def _installed_text() -> str:
    """The installed methods, for an error that names a method no package provides."""
    return f"installed (entry points nirl_mj.methods): {', '.join(_installed()) or 'none'}"


def _method(name: str, table: Any, config: dict, where: str) -> MethodSpec:
    base = BUILTIN_METHODS.get(name)
    if base is not None and name in _installed():  # else the built-in would run under the plugin's name
        from nirl_mj.experiments.plugins import package_of

        raise ExperimentError(f"{where}: {name!r} is a built-in method, and the installed package "
                              f"{package_of(_installed()[name])} provides a method of that name too; rename "
                              "its entry point (docs/EXTENDING.md)")  # fmt: skip
    if base is None and name in _installed():
        base = MethodSpec(name, "plugin", plugin=name)
    if table is None:
        method = base
    else:
        table = _table(table, where)
        _known(table, METHOD_KEYS, where, "")
        if base is None and "plugin" in table and "kind" not in table:
            raise ExperimentError(f'{where}: plugin = {table["plugin"]!r} names an installed method: add '
                                  'kind = "plugin" to the table (docs/EXTENDING.md)')  # fmt: skip
        if base is None and "kind" not in table and any(k in table for k in ("steps", "settings")):
            # an installed method's table, with no package installed that provides it
            raise ExperimentError(
                f"{where}: unknown method {name!r}: not built in, and no installed package provides it "
                f"(docs/EXTENDING.md); {_installed_text()}; or give the table a kind (docs/EXPERIMENTS.md)"
            )
        default = base or MethodSpec(name, "irl")
        kind = _choice(table.get("kind", default.kind), METHOD_KINDS, f"{where}.kind")
        changes = _learner_changes(_table(table.get("config", {}), f"{where}.config"), f"{where}.config")
        if kind != "irl" and (changes or "method" in table):
            raise ExperimentError(f'{where}: method and config apply to kind = "irl" only')
        if kind not in ("irl", "bc", "dagger") and "variant" in table:
            raise ExperimentError(f'{where}: variant applies to kind = "irl", "bc" and "dagger" only')
        if kind == "dagger" and any(k in table for k in RL_KEYS if k != "settings"):
            raise ExperimentError(f"{where}: DAgger takes settings (its rounds and episodes) only")
        if kind not in ("rl", "plugin", "dagger") and any(k in table for k in RL_KEYS):
            raise ExperimentError(f'{where}: {", ".join(RL_KEYS)} apply to kind = "rl" only')
        if kind == "plugin" and any(k in table for k in RL_KEYS if k not in ("steps", "settings")):
            raise ExperimentError(f"{where}: a plugin takes steps (its budget) and settings only")
        if "plugin" in table and kind != "plugin":
            raise ExperimentError(f'{where}: plugin applies to kind = "plugin" only')
        method = MethodSpec(
            name,
            kind,
            _choice(table.get("variant", default.variant), VARIANTS, f"{where}.variant"),
            _choice(table.get("method", default.method), METHODS, f"{where}.method"),
            changes,
            _choice(table.get("algo", default.algo), ALGOS, f"{where}.algo"),
            _int(table.get("steps", default.steps), f"{where}.steps", 1),
            _choice(table.get("selection", default.selection), SELECTIONS, f"{where}.selection"),
            _int(table.get("envs", default.envs), f"{where}.envs", 1),
            _table(table.get("settings", default.settings), f"{where}.settings"),
            _str(table.get("plugin", default.plugin), f"{where}.plugin"),
            train_drive=_choice(table["train_drive"], specs.DRIVES, f"{where}.train_drive")
            if "train_drive" in table
            else default.train_drive,
        )
    if method.kind == "rl":
        try:
            run_config(method.algo, method.selection, method.envs, method.settings, method.train_drive)
        except ValueError as exc:
            raise ExperimentError(f"{where}: {exc}") from None
    if method.kind == "dagger":
        from nirl_mj.experiments.dagger import DaggerConfig

        try:
            DaggerConfig.of(method.settings)
        except ValueError as exc:
            raise ExperimentError(f"{where}.settings: {exc}") from None
    if method.kind == "plugin":
        from nirl_mj.experiments.plugins import load_method

        if not method.plugin:
            raise ExperimentError(
                f'{where}: kind = "plugin" needs plugin = the name of an installed method; '
                f"{_installed_text()}"
            )
        if method.plugin not in _installed():
            raise ExperimentError(f"{where}: plugin = {method.plugin!r}: no installed package provides it; "
                                  f"{_installed_text()}")  # fmt: skip
        try:
            declared = load_method(method.plugin, method.settings).reads  # declarations, settings checked now
        except SpecError as exc:
            raise ExperimentError(f"{where}: {exc}") from None
        method = dataclasses.replace(method, declared_reads=tuple(declared))
    if method.trains:
        try:
            method.learner_config(config)
        except (TypeError, ValueError) as exc:
            raise ExperimentError(f"{where}: {exc}") from None
    return method


CLONE_FIT = "balanced, early-stopped (2026-11-26)"
"""The fit of behaviour cloning and DAgger in their default variant, in their identity: the fit of
that name changed on 2026-11-26 (``learn/bc.py``), so a cell computed before is never taken for one
computed after. The paper variant is the fit of before, and its identity is as it was."""


def _method_identity(method: MethodSpec) -> dict:
    """A method as JSON for the experiment's identity; ``algo`` and ``steps`` only for kind "rl", and
    ``selection`` and ``envs`` only where they are not the legacy ones, ``settings`` (rl, dagger) only
    where set, so that the identity of an experiment written before they existed is unchanged."""
    data = dataclasses.asdict(method)
    if method.kind == "plugin":
        from nirl_mj.experiments.plugins import source_digest, version_of

        return {"name": method.name, "kind": "plugin", "plugin": method.plugin, "steps": method.steps,
                "settings": method.settings, "version": version_of(method.plugin),
                "source": source_digest(method.plugin), "reads": sorted(method.declared_reads)}  # fmt: skip
    del data["plugin"], data["declared_reads"]
    legacy = method.kind == "rl" and (method.selection, method.envs) == (LEGACY["selection"], LEGACY["envs"])
    for key in RL_KEYS:
        unset = key in ("settings", "train_drive") and not data[key]
        own = method.kind == "rl" or (method.kind == "dagger" and key == "settings")
        if not own or (legacy and key in LEGACY) or unset:
            del data[key]
    if method.kind in ("bc", "dagger") and method.variant == "default":
        data["clone"] = CLONE_FIT
    return data


def _learner_changes(table: dict, where: str) -> dict:
    """Learner config changes (flat field names), each checked against the field's default type."""
    exclude = ("variant", "method")
    try:
        table = without_retired(table, f"{where}:")  # a retired setting at its neutral value is dropped
        _known(table, [k for k in LearnerConfig.field_defaults() if k not in exclude], where, "")
        return checked_changes(table, where, exclude)
    except ValueError as exc:
        raise ExperimentError(str(exc)) from None


def _paper(table: Any, methods: tuple[MethodSpec, ...], where: str, full_methods: Any) -> dict:
    """The paper's rows of the methods run (a row of a method that ``[quick] methods`` leaves out is
    checked, then dropped)."""
    table = _table(table, where)
    names = [m.name for m in methods]
    listed = [n for n in full_methods if isinstance(n, str)] if isinstance(full_methods, list) else []
    out = {}
    for name, row in table.items():
        _member(name, names + [n for n in listed if n not in names], f"{where}.{name}")
        row = _table(row, f"{where}.{name}")
        _known(row, PAPER_KEYS, f"{where}.{name}", "")
        values = {k: _number(row[k], f"{where}.{name}.{k}", 0.0, 100.0) for k in PAPER_KEYS if k in row}
        if name in names:
            out[name] = values
    return out


def _task(value: Any, base: Path, overrides: dict, where: str, set_where: str) -> specs.TaskSpec:
    """The task ``value`` names, changed by ``overrides`` (the experiment's ``[set]``, found at
    ``set_where`` for messages)."""
    name = _str(value, where)
    path = Path(name)
    if path.suffix == ".toml" and not path.is_absolute():
        # never the working directory's: the experiment means the same task wherever it runs
        found = [p for p in (base / path, specs.TASKS_DIR.parent / path) if p.is_file()]
        if not found:
            raise ExperimentError(f"{where} = {name!r}: no such file beside the experiment ({base / path}) "
                                  f"or in the checkout ({specs.TASKS_DIR.parent / path})")  # fmt: skip
        name = str(found[0])
    try:
        task = specs.load_task(name)
    except SpecError as exc:
        raise ExperimentError(f"{where}: {exc}") from None
    try:
        return specs.replace(task, **overrides) if overrides else task
    except SpecError as exc:  # a value of [set] (or [quick.set]): say so, not only the task's name
        raise ExperimentError(f"{set_where}: {exc}") from None


def _merge(data: dict, changes: dict) -> dict:
    """``data`` with ``changes`` applied, tables merged key by key."""
    out = dict(data)
    for key, value in changes.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def _known(table: dict, accepted, where: str, note: str) -> None:
    unknown = sorted(set(table) - set(accepted))
    if unknown:
        raise ExperimentError(
            f"{where}: unknown key(s) {', '.join(unknown)}{' ' + note if note else ''}; "
            f"accepted: {', '.join(accepted)}"
        )


def _table(value: Any, where: str) -> dict:
    if not isinstance(value, dict):
        raise ExperimentError(f"{where}: expected a table, got {value!r}")
    return value


def _list(value: Any, where: str) -> list:
    if not isinstance(value, list):
        raise ExperimentError(f"{where} = {value!r}: expected a list")
    return value


def _check_frame(strip: StripSpec, where: str) -> None:
    """The strip's camera and frame size as the renderer accepts them, checked now: the strip is
    drawn after every cell has run, too late to refuse a typo."""
    from nirl_mj.inspect.video import RenderError, check_frame  # imports MuJoCo: only for a [strip]

    try:
        check_frame(strip.camera, strip.width, strip.height)
    except RenderError as exc:
        raise ExperimentError(f"{where}: {exc}") from None


def _str(value: Any, where: str) -> str:
    if not isinstance(value, str):
        raise ExperimentError(f"{where} = {value!r}: expected a string")
    return value


def _bool(value: Any, where: str) -> bool:
    if not isinstance(value, bool):
        raise ExperimentError(f"{where} = {value!r}: expected true or false")
    return value


def _choice(value: Any, accepted, where: str) -> str:
    if value not in accepted:
        raise ExperimentError(f"{where} = {value!r}: accepted: {', '.join(accepted)}")
    return value


def _member(value: Any, accepted: list[str], where: str) -> str:
    if value not in accepted:
        raise ExperimentError(f"{where}: {value!r} is not a method of this experiment: {', '.join(accepted)}")
    return value


def _int(value: Any, where: str, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ExperimentError(f"{where} = {value!r}: expected a whole number")
    if value < low:
        raise ExperimentError(f"{where} = {value}: must be >= {low}")
    return value


def _number(value: Any, where: str, low: float = 0.0, high: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ExperimentError(f"{where} = {value!r}: expected a finite number")
    if not low <= value <= high:
        raise ExperimentError(f"{where} = {value}: must be in [{low}, {high}]")
    return float(value)
