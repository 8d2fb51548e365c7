"""The learner's configuration: the shared loop's, one per reward step, and the named presets.

:class:`LoopConfig` holds what every method shares (Algorithm 1 less its reward
step: rollouts, SARSA, backpropagation, selection); each reward step has its own
config (:data:`STEP_CONFIGS`), and :attr:`LoopConfig.method` says which one
runs. A :class:`LearnerConfig` is the loop's config with every step's, so that a
setting of a step that does not run is kept (and compared on resume) rather than
refused: an experiment may set RE's horizon once for all its methods.

On disk (``run.json``, ``experiment.json``) a learner config is one flat
``{field: value}`` object, field names unique across the loop and the steps;
:meth:`LearnerConfig.to_dict` and :meth:`LearnerConfig.from_dict` convert, so
runs written before the split load unchanged.

The named variants are data, :data:`PRESETS`: changes from the field defaults
(``"default"``, the project's, and ``"paper"``, the algorithm as the paper
writes it).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

METHODS = ("nirl", "al", "re", "scirl")
"""The reward steps, by method name (``nirl_mj.learn.methods`` builds them)."""
REWARD_SOURCES = ("learned", "progress", "constant")
SELECTIONS = ("demo_balanced", "last", "demo_accuracy", "validation")
PRETREATMENTS = {"none": None, "map": "uniform", "map-majority": "empirical"}
"""``pretreatment`` -> the prior of eq. 10 that ``learn.pretreat.map_pretreat`` applies (None: none)."""
TERMINAL_VALUES = ("learned", "outcome")  # learn/terminal.py
EXPECTATIONS = ("state", "trajectory", "suffix")
MATCHINGS = {
    "paper": "eq. 11 expectations of whole trajectories",
    "occupancy": "every action, a classifier of the expert's actions",
    "policy": "the learner's policies so far, docs/ALGORITHM.md",
}
"""NIRL's margin readings (``MaxMarginConfig.matching``), each with what its alternatives are."""


@dataclass(frozen=True)
class LoopConfig:
    """The shared loop (``nirl_mj.learn.loop.IrlLoop``), and the settings several reward steps read."""

    variant: str = "default"  # the preset this config started from (a label in run records)
    method: str = "nirl"  # the reward step: "nirl" (max margin, eq. 11-13) or a baseline (learn/methods.py)
    episodes: int = 60  # ~2-4 min per run on one core (planar training drive)
    trajectories_per_episode: int = 10
    gamma: float = 0.9  # eq. 14 and eq. 11 (paper: 0.65, about three decisions ahead)
    alpha: float = 0.8  # eq. 14
    eta: float = 5.0  # eq. 8, Boltzmann parameter at the first iteration (low: every action gets tried)
    eta_final: float = 60.0  # eta is interpolated linearly to this over the episodes
    # "paper" (eq. 4-5), "extended" or "bearing" (learn/reward.py; the default since 2026-11-24, 2nd round)
    reward_features: str = "bearing"
    margin_loss: float = (
        0.1  # l(s, a) for a != a_E in the structured losses of max margin and SCIRL (paper: 1)
    )
    # stop when the reward step's margin t <= epsilon (the paper gives no value); None: never (runs
    # written before 2026-11-30 hold -inf, read as None: their JSON was not strict)
    epsilon: float | None = None
    reward_scaling: bool = True  # rewards mapped into [0, 1 - gamma]
    # the value of an episode's end in the targets (learn/terminal.py): "learned" (the absorbing
    # state's reward from the demonstrations' and the learner's ends) or "outcome" (an arrival
    # worth terminal_arrival_value, other ends 0: reads the task's outcome unless that value is 0,
    # the paper's targets, where every end is worth 0)
    terminal_value: str = "learned"
    terminal_arrival_value: float = 1.0  # an arrival's value in the "outcome" reading
    net_step: float = 0.4  # sigma_2 of eq. 15
    net_l2: float = 1e-3  # lambda_2 of eq. 15
    replay_episodes: int = 10  # 0: train on this episode's pairs only (paper)
    net_epochs: int = 4  # full-batch steps (no replay) or minibatch epochs (replay)
    # value-fitting rounds per iteration: eq. 14's targets computed again from the network, then
    # net_epochs of eq. 15, this many times (paper: 1, one set of targets per iteration); more rounds
    # carry the values further along the replay window's pairs, as fitted Q iteration does
    fit_rounds: int = 1
    batch_size: int = 64
    input_scaling: bool = True  # network input D/7 and V/9 instead of raw phi
    input_bearing: bool = True  # network input (cos, sin) of the sector centre in V's place (inputs.py)
    # the reported policy: "demo_balanced" (mean per-action recall on the demonstrations), "last"
    # (the last iterate), "demo_accuracy" (the paper) or "validation" (success on validation arenas:
    # reads the task's success, an oracle)
    selection: str = "demo_balanced"
    validation_arenas: int = 20
    validate_every: int = 5
    # validation selection: the best `final_candidates` policies are re-validated on as many
    # new validation arenas, and the best over both sets is chosen (1: no second round); with
    # end_check_arenas, the candidates of the end check (below)
    final_candidates: int = 3
    # a check that the kept policy's episodes end (any end, never which: ``episode_end``): the
    # `final_candidates` best iterates by demo_balanced or demo_accuracy, and the last, are driven
    # greedily on this many validation arenas each, and the one whose episodes end before the time
    # limit most often is kept (the rule's order among equals; a collision counts as an end, so it
    # prefers a crash to a timeout); a policy caught in a loop runs into the limit. 0: the rule alone
    end_check_arenas: int = 0
    reward_source: str = "learned"  # "progress" / "constant": the controls (a known reward, no step)
    # the inner learner (docs/notebook/algorithm.md, "Inner learner"): what a target bootstraps
    # from, Q(s', a') of the next pair taken ("sarsa", eq. 14) or max_a' Q(s', a') ("q": Q-learning,
    # the greedy policy's values); the hidden units of the network (paper: 10); n-step targets, the next n
    # rewards before the bootstrap (paper: 1, eq. 14)
    bootstrap: str = "q"
    hidden_units: int = 32
    n_step: int = 3
    train_drive: str = "planar"  # the training rollouts' drive (same kinematics, ~1.9x the decisions/s)
    # "map": the demonstrations' ambiguous states relabelled with eq. 10's MAP action before anything
    # reads them (paper section IV-A, learn/pretreat.py, uniform prior); "map-majority": eq. 10 with
    # the empirical prior, i.e. each ambiguous state's most frequent action; "none": as recorded
    pretreatment: str = "none"

    @property
    def reads_outcome(self) -> bool:
        """Whether the value targets read the task's outcome (an arrival worth a fixed value)."""
        return self.terminal_value == "outcome" and self.terminal_arrival_value != 0

    def __post_init__(self) -> None:
        object.__setattr__(self, "epsilon", never_stop(self.epsilon))
        _choice("method", self.method, METHODS)
        _choice("reward_source", self.reward_source, REWARD_SOURCES)
        _choice("reward_features", self.reward_features, ("paper", "extended", "bearing"))
        _choice("selection", self.selection, SELECTIONS)
        _choice("terminal_value", self.terminal_value, TERMINAL_VALUES)
        _choice("train_drive", self.train_drive, ("planar", "tyre", "rollers"))
        _choice("bootstrap", self.bootstrap, ("sarsa", "q"))
        _choice("pretreatment", self.pretreatment, tuple(PRETREATMENTS))
        _bounds(self, gamma=(0.0, 1.0, "()"), alpha=(0.0, 1.0, "(]"), eta=(0.0, None, "()"),
                eta_final=(0.0, None, "()"), margin_loss=(0.0, None, "[)"), net_step=(0.0, None, "()"),
                net_l2=(0.0, None, "[)"), terminal_arrival_value=(None, None, "()"))  # fmt: skip
        _counts(self, episodes=1, trajectories_per_episode=1, net_epochs=1, fit_rounds=1, batch_size=1,
                replay_episodes=0, validation_arenas=1, validate_every=1, final_candidates=1,
                hidden_units=1, n_step=1, end_check_arenas=0)  # fmt: skip
        if self.end_check_arenas and self.selection in ("last", "validation"):
            raise ValueError(
                f"end_check_arenas = {self.end_check_arenas} checks the candidates of a rule that reads "
                f"the demonstrations (demo_balanced, demo_accuracy), not {self.selection!r}; set it to 0"
            )


@dataclass(frozen=True)
class MaxMarginConfig:
    """NIRL's reward step, maximum margin planning (eq. 11-13; ``learn/mmp.py``)."""

    # "paper": eq. 11 expectations; "occupancy": per-pair sums, every action an alternative (a
    # classifier of the expert's actions; the default until 2026-11-25, the NIRL-classifier row);
    # "policy" (the default since 2026-11-25): per-pair sums, the alternatives in each demonstrated
    # state the learner's policies so far, by their action probabilities there; their rollouts do not
    # enter (the expert's continuation follows every alternative: learn/mmp.py, docs/ALGORITHM.md)
    matching: str = "policy"
    # occupancy and policy matchings: what follows a deviation from the expert's pair. 1: the learner's mean
    # discounted sum (its own behaviour); 0: the expert's own continuation,
    # mu(s, a) = f(s, a) + gamma mu_E(s', a'_E) (akin to SCIRL's heuristic, which uses
    # mu_E(s, a_E): docs/ALGORITHM.md); in between: a mixture.
    future_mix: float = 0.0
    mmp_lambda: float = 0.0  # lambda_1 of eq. 13
    mmp_steps: int = 30
    mmp_step_size: float = 0.5  # sigma_1
    mmp_step_decay: float = 0.0  # sigma_1 / (1 + decay * i) over iterations i (paper: constant, 0)

    def __post_init__(self) -> None:
        _choice("matching", self.matching, tuple(MATCHINGS))
        _bounds(
            self,
            future_mix=(0.0, 1.0, "[]"),
            mmp_lambda=(0.0, None, "[)"),
            mmp_step_size=(0.0, None, "()"),
            mmp_step_decay=(0.0, None, "[)"),
        )
        _counts(self, mmp_steps=1)


@dataclass(frozen=True)
class ApprenticeshipConfig:
    """AL's reward step, the projection variant (``learn/al.py``)."""

    # what a feature expectation is. "state" (default since 2026-11-25): per demonstrated state, the
    # expert's discounted suffix against the learner's policy in that state followed by the same
    # continuation, as NIRL's default margin reads them (learn/al.py); "trajectory": eq. 11, each
    # trajectory's discounted sum from its start (the papers' reading; with gamma 0.65 it sees ~3
    # steps; the AL-traj row); "suffix": the mean discounted suffix sum over every visited pair
    al_expectations: str = "state"

    def __post_init__(self) -> None:
        _choice("al_expectations", self.al_expectations, EXPECTATIONS)


@dataclass(frozen=True)
class RelativeEntropyConfig:
    """RE-IRL's reward step (``learn/reirl.py``)."""

    re_expectations: str = "state"  # as ApprenticeshipConfig.al_expectations (learn/reirl.py)
    # pairs per RE sample (and its importance ratio); gamma^16: 1e-3 at 0.65, 0.19 at 0.9
    re_horizon: int = 16
    re_step: float = 0.5  # gradient-ascent step on the dual g(theta)
    re_steps: int = 30  # ascent steps per iteration, warm-started from the last theta
    re_pool: int = 10  # iterations whose rollouts are pooled as importance samples
    # Hoeffding confidence of the L1 widths epsilon_i (0: no L1 term; the comparisons' RE row runs 0,
    # tuned on the development domain: experiments/definition.py)
    re_confidence: float = 0.95
    # how the L1 term -sum eps_i |theta_i| is stepped. "subgradient" (the paper): theta_i flips by
    # +-re_step eps_i around 0 every step; "proximal" (soft-thresholding): such theta_i rest at 0
    re_l1_step: str = "proximal"

    def __post_init__(self) -> None:
        _choice("re_expectations", self.re_expectations, EXPECTATIONS)
        _choice("re_l1_step", self.re_l1_step, ("proximal", "subgradient"))
        _bounds(self, re_step=(0.0, None, "()"), re_confidence=(0.0, 1.0, "[)"))
        _counts(self, re_horizon=1, re_steps=1, re_pool=1)


@dataclass(frozen=True)
class ScirlConfig:
    """SCIRL's reward step (``learn/scirl.py``)."""

    scirl_steps: int = 40  # normalised subgradient steps (as the authors' code)
    scirl_step_size: float = 3.0  # step size / (k + 1) at step k (authors: 3 / (k + 1))

    def __post_init__(self) -> None:
        _bounds(self, scirl_step_size=(0.0, None, "()"))
        _counts(self, scirl_steps=1)


STEP_CONFIGS: dict[str, type] = {
    "nirl": MaxMarginConfig,
    "al": ApprenticeshipConfig,
    "re": RelativeEntropyConfig,
    "scirl": ScirlConfig,
}

PRESETS: dict[str, dict[str, Any]] = {
    "default": {},
    # The algorithm as the paper writes it (docs/ALGORITHM.md lists what "default" changes, and why).
    "paper": {
        "gamma": 0.65,
        "bootstrap": "sarsa",
        "hidden_units": 10,
        "n_step": 1,
        "eta": 10.0,
        "eta_final": 10.0,
        "reward_features": "paper",
        "input_bearing": False,
        "matching": "paper",
        "future_mix": 1.0,
        "episodes": 120,
        "margin_loss": 1.0,
        "mmp_step_decay": 0.0,
        "reward_scaling": False,
        "terminal_value": "outcome",
        "terminal_arrival_value": 0.0,
        "replay_episodes": 0,
        "net_epochs": 20,
        "input_scaling": False,
        "selection": "demo_accuracy",
        "epsilon": 0.0,
    },
}
VARIANTS = tuple(PRESETS)
RECORD_FALLBACKS: dict[str, Any] = {
    "bootstrap": "sarsa",
    "hidden_units": 10,
    "n_step": 1,
    "input_bearing": False,
    "terminal_value": "outcome",
    "pretreatment": "none",
    "fit_rounds": 1,
    "end_check_arenas": 0,
}
"""Fields added after run records were first written, with the value that reproduces what those
runs did (:meth:`LearnerConfig.from_record`)."""
RETIRED: dict[str, tuple[Any, str]] = {
    "weight_averaging": (
        0.0,
        "Polyak averaging of the kept policy's weights, retired on 2026-11-26: it did "
        "not pay (docs/ALGORITHM.md); commit d3ea6fe still runs it",
    ),
    "reward_ceiling": (
        1.0,
        "rewards scaled into [0, c (1 - gamma)], retired on 2026-11-27: it did not lift RE-IRL out "
        'of its timeouts (docs/notebook/algorithm.md, "A reward ceiling for RE"); commit 7626b6d '
        "still runs it",
    ),
}
"""Fields that were removed, with the value at which they did nothing: a record or experiment that
holds one at that value loads as it was trained; any other value is refused with the reason."""


def _choice(name: str, value: Any, accepted: tuple[str, ...]) -> None:
    if value not in accepted:
        raise ValueError(f"unknown {name} {value!r}; accepted: {', '.join(accepted)}")


def _bounds(config: Any, **fields: tuple[float | None, float | None, str]) -> None:
    """Each field a finite number within (low, high); ``ends`` "()", "[]", "[)" or "(]" say which
    ends are open (None: unbounded)."""
    for name, (low, high, ends) in fields.items():
        value = getattr(config, name)
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        ok = ok and (low is None or (value >= low if ends[0] == "[" else value > low))
        ok = ok and (high is None or (value <= high if ends[1] == "]" else value < high))
        if not ok:
            interval = (
                f"{ends[0]}{'-inf' if low is None else low}, {'inf' if high is None else high}{ends[1]}"
            )
            raise ValueError(f"{name} = {value!r}: expected a finite number in {interval}")


def _counts(config: Any, **minimums: int) -> None:
    """Each field a whole number >= its minimum."""
    for name, low in minimums.items():
        value = getattr(config, name)
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ValueError(f"{name} = {value!r}: expected a whole number >= {low}")


def holds_retired(flat: Mapping[str, Any]) -> bool:
    """Whether ``flat`` holds a retired field (:data:`RETIRED`) at a value other than its neutral one."""
    return any(name in flat and flat[name] != neutral for name, (neutral, _) in RETIRED.items())


def without_retired(flat: Mapping[str, Any], where: str) -> dict[str, Any]:
    """``flat`` less the retired fields (:data:`RETIRED`) that hold their neutral value; ValueError
    naming the field and why it went if one holds another."""
    for name, (neutral, why) in RETIRED.items():
        if name in flat and flat[name] != neutral:
            raise ValueError(f"{where} {name} = {flat[name]!r}: {why} (only {neutral!r}, which does nothing, "
                             "is still read)")  # fmt: skip
    return {k: v for k, v in flat.items() if k not in RETIRED}


def _owners(step_configs: Mapping[str, type] | None = None) -> dict[str, type]:
    """Every flat field name -> the config class that holds it (of :data:`STEP_CONFIGS` unless
    given); TypeError naming both classes if two hold one name (a flat ``--config`` name must say
    which field it sets)."""
    owners: dict[str, type] = {}
    for cls in (LoopConfig, *(STEP_CONFIGS if step_configs is None else step_configs).values()):
        for f in dataclasses.fields(cls):
            if owners.setdefault(f.name, cls) is not cls:
                raise TypeError(f"learner setting {f.name!r} is a field of both {owners[f.name].__name__} "
                                f"and {cls.__name__}: flat names must be unique")  # fmt: skip
    return owners


@dataclass(frozen=True)
class LearnerConfig:
    """The loop's config and every reward step's; :attr:`step` is the one that runs."""

    loop: LoopConfig = field(default_factory=LoopConfig)
    steps: Mapping[str, Any] = field(default_factory=lambda: {m: cls() for m, cls in STEP_CONFIGS.items()})

    @property
    def step(self) -> Any:
        """The config of the reward step that runs (``loop.method``'s)."""
        return self.steps[self.loop.method]

    @staticmethod
    def field_defaults() -> dict[str, Any]:
        """Every flat field name with its default value (for checking overrides)."""
        return LearnerConfig().to_dict()

    @classmethod
    def preset(cls, name: str = "default", **changes: Any) -> LearnerConfig:
        """The preset ``name`` (:data:`PRESETS`) with flat ``changes`` on top."""
        _choice("variant", name, VARIANTS)
        return cls.from_dict({**PRESETS[name], "variant": name, **changes})

    @classmethod
    def from_dict(cls, flat: Mapping[str, Any]) -> LearnerConfig:
        """A config from flat ``{field: value}`` (a run record's); missing fields take their defaults."""
        owners = _owners()
        flat = without_retired(flat, "learner setting")
        unknown = sorted(set(flat) - set(owners))
        if unknown:
            raise ValueError(
                f"unknown learner setting(s) {', '.join(unknown)}; accepted: {', '.join(owners)}"
            )

        def build(config_cls: type) -> Any:
            return config_cls(**{k: v for k, v in flat.items() if owners[k] is config_cls})

        return cls(build(LoopConfig), {m: build(c) for m, c in STEP_CONFIGS.items()})

    @classmethod
    def from_record(cls, flat: Mapping[str, Any]) -> LearnerConfig:
        """The config a run record (``run.json``) was trained with: as :meth:`from_dict`, but a field
        the record lacks takes its value from before the field existed (:data:`RECORD_FALLBACKS`),
        not today's default, so runs written by older versions load as they were trained."""
        return cls.from_dict({**RECORD_FALLBACKS, **flat})

    def to_dict(self) -> dict[str, Any]:
        """The flat form stored in run records: the loop's fields, then every step's."""
        flat = dataclasses.asdict(self.loop)
        for config in self.steps.values():
            flat |= dataclasses.asdict(config)
        return flat

    def settings_read(self) -> dict[str, Any]:
        """The flat fields this learner may read: the loop's and its own reward step's (not the other
        steps', which :meth:`to_dict` keeps; with a known ``reward_source`` no step runs, and its
        fields are kept all the same). Two learners with equal ``settings_read()`` compute the same
        numbers; ``nirl-mj compare --reuse`` and restored cells compare these."""
        flat = dataclasses.asdict(self.loop)
        return flat | dataclasses.asdict(self.step)

    def replace(self, **changes: Any) -> LearnerConfig:
        """A copy with flat ``changes`` (field names of the loop or of any step)."""
        return LearnerConfig.from_dict({**self.to_dict(), **changes})


def never_stop(epsilon: float | None) -> float | None:
    """``epsilon`` as a config holds it: a margin the loop can never fall to (-inf, or nan, which no
    margin is at most) is None, "never stop", as records written before 2026-11-30 held -inf."""
    return None if epsilon is None or math.isnan(epsilon) or epsilon == -math.inf else epsilon


def checked_changes(changes: Mapping[str, Any], where: str, exclude: tuple[str, ...] = ()) -> dict[str, Any]:
    """Flat field changes checked against the fields' default types (whole numbers become floats
    where a float is expected); ``where`` names the source in errors, ``exclude`` lists fields that
    are set elsewhere. Raises ValueError naming the field and what it accepts."""
    defaults = {k: v for k, v in LearnerConfig.field_defaults().items() if k not in exclude}
    out = {}
    changes = without_retired(changes, f"{where}:")
    for key, value in changes.items():
        if key not in defaults:
            raise ValueError(f"{where}: unknown learner setting {key!r}; accepted: {', '.join(defaults)}")
        kind = float if defaults[key] is None else type(defaults[key])  # None: an optional number
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if type(value) is not kind:
            raise ValueError(f"{where}.{key} = {value!r}: expected a {kind.__name__}")
        out[key] = never_stop(value) if key == "epsilon" else value  # as it is stored: strict JSON
    return out
