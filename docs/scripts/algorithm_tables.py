"""The renderers of docs/ALGORITHM.md's own tables (merged into render_docs.RENDERERS).

- ``departures``: the default's departures from the paper (:data:`DEPARTURES`), each with why and
  what undoing it measured: the default row minus the ablated row, paired by run (the runs of one
  index share their training seed, demonstrations and test arenas), with its 95 % interval, from
  the stored ``docs/results/*/results.json``, and the command that recomputes it. A departure
  measured only at a superseded default says at which; one never measured, or measured without a
  stored result, says so in words.
- ``removed``: the departures removed from the default (:data:`REMOVED`), with the same columns.
- ``reads``: what each built-in method reads (``nirl_mj.experiments.reads``), from the code.

    python docs/scripts/algorithm_tables.py departures    # print one
"""

from __future__ import annotations

import json
import sys
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))

from experiment_index import RECORDED  # noqa: E402

from nirl_mj.experiments.stats import paired  # noqa: E402

TODAY = ""
"""``Ablation.at`` for a measurement at today's default."""


@dataclass(frozen=True)
class Ablation:
    """A departure undone in a stored experiment: ``default`` minus ``ablated``, paired by run.

    ``results`` is the folder under docs/results/ holding the ablated row; ``default_results`` the
    one holding the default row when another experiment ran it on the same runs (same training
    seeds, demonstrations and test arenas); ``at`` the default the measurement was made at
    (:data:`TODAY`, or the date of a superseded one)."""

    results: str
    ablated: str
    default: str
    default_results: str | None = None
    at: str = TODAY
    note: str = ""


@dataclass(frozen=True)
class Unstored:
    """A departure measured without a stored result, or never: ``text`` says which, ``command`` how."""

    text: str
    command: str = ""


@dataclass(frozen=True)
class Departure:
    what: str
    why: str
    evidence: tuple[Ablation | Unstored, ...]


ROUND1 = "2026-11-24"
BALL = "\\|\\|theta\\|\\| <= 1"  # escaped for a table cell
DEV = "development arenas, demonstrations drawn per run"
DECAY = "2026-11-27 (decaying step)"
"""The default the development-domain ablations (departures, information_budget, paper_steps) were
measured at: today's but for the max-margin step, which decayed (``mmp_step_decay = 0.1``; removed
after them, :data:`REMOVED`)."""


VALIDATION_NOTE = (
    "success on 20 validation arenas of every 5th iterate, the best 3 on 20 more, which "
    "reads the task; development arenas"
)  # NIRL-validation (experiments/training.py select)


def undone(ablated: str, note: str = DEV) -> tuple[Ablation, Ablation]:
    """A departure undone alone on the same development runs at today's default
    (tasks/ablations/departures_today.toml) and at the decaying step's (tasks/ablations/departures.toml)."""
    return (
        Ablation("departures_today", ablated, "NIRL", note=note),
        Ablation("departures", ablated, "NIRL", at=DECAY, note=note),
    )


DEPARTURES: tuple[Departure, ...] = (
    Departure(
        '**Reward features** `reward_features = "bearing"`: per action the block [D/7, one-hot V, cos and '
        "sin of V's sector centre, I, U, 1], 27 values (162 in all); paper: phi(s) in the action's block "
        "(eq. 4-5, 96)",
        f"with {BALL} the components must share a scale (D/7); a linear reward needs one-hot V to "
        'prefer "turn towards the target\'s sector" and a constant to prefer an action as such; (cos, sin) '
        "carry that preference to the sectors behind the robot, which the expert almost never saw",
        (
            *undone("features-paper", f"phi(s) in the action's block; {DEV}"),
            Ablation(
                "table1_nirl_onehot",
                "NIRL",
                "NIRL-bearing",
                "nirl_bearing",
                ROUND1,
                "(cos, sin) added to the one-hot block",
            ),
        ),
    ),
    Departure(
        "**The margin's alternatives** `matching = \"policy\"`: in every demonstrated state the expert's "
        "pair against each policy the learner has run, by its Boltzmann probabilities there; paper: eq. 11's "
        'whole-trajectory expectations on both sides (`"paper"`)',
        "eq. 11 weighs each trajectory's first few decisions, in open space near the start: blind to "
        'obstacles. With every action an alternative (`"occupancy"`) theta is a classifier of the expert\'s '
        "actions that never reads the learner; with its policies, a state where all of them already take "
        "the expert's action costs nothing",
        (
            Ablation("departures_today", "matching-paper", "NIRL", note=f"eq. 11's expectations; {DEV}"),
            Ablation("table1_fair", "NIRL-classifier", "NIRL", note="every action an alternative"),
        ),
    ),
    Departure(
        "**What follows a deviation** `future_mix = 0`: the expert's own continuation gamma mu_E(next) on "
        "both sides, so it cancels; paper: the learner's feature expectations mu^(i)",
        "with the learner's continuation the gradient holds a term gamma (mu^(i) - mu_E) shared by every "
        'action: it matches action frequencies, and the reward comes to prefer "forward", the expert\'s '
        "most frequent action, nearly everywhere",
        (
            Ablation("departures_today", "learner-mu", "NIRL", note=f"`future_mix = 1`; {DEV}"),
            Ablation(
                "nirl_reading",
                "NIRL-learner-mu",
                "NIRL-g90-n3",
                "nirl_discount",
                ROUND1,
                "the learner's mean continuation, `future_mix = 1`",
            ),
        ),
    ),
    Departure(
        "**Margin loss** `margin_loss = 0.1`; paper: 1",
        f"with features in [0, 1] and {BALL} a margin of 1 cannot be met, and the step becomes a "
        'majority-class classifier ("forward")',
        (*undone("margin-1"),),
    ),
    Departure(
        "**Reward scaling** `reward_scaling = true`: the replay window's rewards mapped affinely into "
        "[0, 1 - gamma]; paper: theta^T f as it is, targets outside [0, 1] clipped",
        "the sigmoid Q lives in (0, 1): raw rewards put most targets outside it, and the network learns "
        "their sign",
        (*undone("raw-rewards"),),
    ),
    Departure(
        '**The value of an episode\'s end** `terminal_value = "learned"` (`learn/terminal.py`); paper '
        "preset: every end worth 0",
        "on rewards scaled into [0, 1 - gamma] every step pays, so an end worth 0 makes ending the worst "
        "thing a policy can do and it circles; a fixed value for an arrival would read the task's outcome",
        (
            Ablation(
                "information_budget_today",
                "NIRL-outcome",
                "NIRL",
                note="the task's outcome instead: an arrival worth 1, other ends 0; development arenas",
            ),
            Ablation(
                "information_budget",
                "NIRL-outcome",
                "NIRL",
                at=DECAY,
                note="the task's outcome instead: an arrival worth 1, other ends 0; development arenas",
            ),
            *undone("end-0", f"every end worth 0; {DEV}"),
        ),
    ),
    Departure(
        "**Q-learning targets** `bootstrap = \"q\"`: max_a' Q(s', a'); paper: SARSA's Q(s', a') of the next "
        "pair taken (eq. 14)",
        "the greedy policy is the one reported, so its values are the ones to learn; SARSA's targets value "
        "the exploring Boltzmann policy, which collides",
        (*undone("sarsa"),),
    ),
    Departure(
        "**3-step targets** `n_step = 3`, cut at the trajectory's end; paper: 1",
        "an end (arrival or collision) reaches the pairs that led to it three times faster",
        (
            *undone("n1"),
            Ablation(
                "paper_steps", "step-const-n1", "NIRL", at=DECAY, note=f"with the constant step too; {DEV}"
            ),
        ),
    ),
    Departure(
        "**Discount** `gamma = 0.9`, in the targets and the reward step's suffix sums; paper: 0.65",
        "0.65 sees about three decisions ahead: too short to value a detour around an obstacle",
        (*undone("gamma-065"),),
    ),
    Departure(
        "**Hidden units** `hidden_units = 32`; paper: 10",
        "more room for the values of six actions; still a small share of the simulation's cost",
        (*undone("hidden-10"),),
    ),
    Departure(
        "**Input scaling** `input_scaling = true`: D/7 (and V/9 without the next row); paper: raw phi(s)",
        "D (0..7) and V (1..9) brought to the scale of the 0/1 flags I and U, for sigmoid units",
        (*undone("raw-inputs", f"the bearing inputs kept; {DEV}"),),
    ),
    Departure(
        "**Bearing inputs** `input_bearing = true`: (cos, sin) of V's sector centre in V's place, 17 inputs",
        'on V/9 "target behind on the left" (5/9) and "behind on the right" (6/9) are neighbours, where '
        "the right actions are opposite; with (cos, sin) they differ in the sign of one input",
        (*undone("no-bearing-in", f"V/9 inputs; {DEV}"),),
    ),
    Departure(
        "**Experience replay** `replay_episodes = 10`, `net_epochs = 4`, `batch_size = 64`: minibatch "
        "epochs over the last 10 iterations' pairs; paper preset: this iteration's pairs, 20 full-batch "
        "steps",
        "one iteration's pairs are too few to learn from (measured on the project's 2-D prototype "
        "before this code)",
        (*undone("no-replay", f"20 full-batch epochs on this iteration's pairs; {DEV}"),),
    ),
    Departure(
        "**Exploration** eta from 5 to 60, linearly over the iterations (`eta`, `eta_final`); paper preset: "
        "10 throughout (the paper gives no value)",
        "a high eta from the start never tries the actions the random initial network undervalues; a low "
        "one tries everything, a high one exploits",
        (*undone("eta-10"),),
    ),
    Departure(
        '**Selection** `selection = "demo_balanced"`: the kept policy whose greedy actions predict the '
        "demonstrations best in balanced accuracy (mean per-action recall); paper: plain accuracy "
        '(`"demo_accuracy"`)',
        "plain accuracy favours the always-forward network, which matches most of the expert's labels; "
        "per-action recall does not",
        (
            Ablation("departures_today", "select-accuracy", "NIRL", note=f"plain accuracy; {DEV}"),
            Ablation("table1_fair", "NIRL-last", "NIRL", note="the last iterate, no selection"),
            Ablation(
                "information_budget_today",
                "NIRL-validation",
                "NIRL",
                note=VALIDATION_NOTE,
            ),
            Ablation(
                "information_budget",
                "NIRL-validation",
                "NIRL",
                at=DECAY,
                note=VALIDATION_NOTE,
            ),
        ),
    ),
    Departure(
        "**Budget** `episodes = 60`, no `epsilon` (the margin t is reported, never a stop); paper "
        "preset: 120 iterations, stop when t <= 0",
        "a run stays within minutes on one core; `iter-120` restores the 120 iterations only: the stop is "
        "not ablated (the default's policies reading keeps the first policy among the alternatives, "
        "so t falls as they pile up, not only as the learner matches)",
        (*undone("iter-120"),),
    ),
    Departure(
        '**All of the above** undone: `--variant paper` (`learn/config.py`, `PRESETS["paper"]`)',
        'the paper\'s algorithm as written collapses to "always forward"',
        (Ablation("table1_fair", "NIRL-paper", "NIRL"),),
    ),
)
"""The rows of docs/ALGORITHM.md's departures table, in the order of the learner's steps."""

REMOVED: tuple[Departure, ...] = (
    Departure(
        "**A decaying max-margin step** sigma_1 / (1 + 0.1 i) over iterations i (`mmp_step_decay = 0.1`, "
        "the default until 2026-11-27); today's default and the paper's: constant (`mmp_step_decay = 0`, "
        "still an option)",
        "it was to damp theta's swings as theta chases the learner; undone, NIRL scored as well",
        (
            Ablation("departures", "step-const", "NIRL", at=DECAY, note=DEV),
            Ablation(
                "paper_steps", "step-const-n1", "NIRL", at=DECAY, note=f"with one-step targets too; {DEV}"
            ),
            Ablation(
                "table1_decaying_step",
                "NIRL",
                "NIRL",
                "table1_fair",
                note="today's, the constant step, minus Table I's row before the removal; final test domain",
            ),
        ),
    ),
)
"""Departures removed from the default because undoing them cost nothing measurable (the fair-comparison
issue: "a departure that does not pay is removed"), with that evidence."""


def _results(folder: str) -> dict:
    return json.loads((ROOT / "docs" / "results" / folder / "results.json").read_text(encoding="utf-8"))


def by_run(folder: str, method: str) -> dict[int, float]:
    """A stored method's success per run index (``by_run``, or its cells where a summary predates it)."""
    summary = _results(folder)
    if method not in summary["methods"]:
        raise ValueError(f"docs/results/{folder} has no method {method}")
    stored = summary["methods"][method].get("by_run")
    if stored:
        return {int(r): float(v) for r, v in stored.items()}  # JSON keys are strings
    cells = summary["cells"].values()
    return {int(c["run"]): float(c["success_rate"]) for c in cells if c["method"] == method}


def task_file(folder: str) -> str | None:
    """The experiment file that recomputes ``docs/results/FOLDER`` (docs/EXPERIMENTS.md's index)."""
    name = _results(folder).get("experiment")
    found = []
    for path in sorted((ROOT / "tasks").rglob("*.toml")):
        experiment = "kind" in tomllib.loads(path.read_text(encoding="utf-8"))
        if experiment and RECORDED.get(path.stem, path.stem) == folder:
            found.append(path)
    found.sort(key=lambda p: p.stem != name)  # the file of the results' own experiment name first
    return str(found[0].relative_to(ROOT)) if found else None


UNFILED = {
    "table1_decaying_step": "docs/results/table1_decaying_step (tasks/table1.toml at commit 7115e0b, "
    "with the decaying max-margin step)",
    "table1_nirl_onehot": "docs/results/table1_nirl_onehot (written by tasks/table1_nirl.toml of 2026-11-24; "
    "its runs 0-4 recompute as `NIRL-g90-n3` of tasks/ablations/nirl_discount.toml)",
}
"""Stored results that no experiment file of today recomputes, with where they came from."""


def command(folder: str) -> str:
    task = task_file(folder)
    if task is None:
        return UNFILED.get(folder, f"docs/results/{folder} (no experiment file recomputes it)")
    return f"`nirl-mj compare --task {task}`"


def _points(value: float) -> str:
    return f"{100 * value:+.1f}"


def measured(a: Ablation) -> str:
    """The result cell of one stored ablation: default minus ablated, [95 % CI], runs."""
    ablated = by_run(a.results, a.ablated)
    default = by_run(a.default_results or a.results, a.default)
    runs = sorted(set(ablated) & set(default))
    if not runs:
        raise ValueError(f"{a.default} and {a.ablated} share no run")
    p = paired([default[r] for r in runs], [ablated[r] for r in runs])
    ci = f" [{_points(p['ci'][0])}, {_points(p['ci'][1])}]" if p["ci"][0] is not None else ""
    when = "today's default" if a.at == TODAY else f"ablated at the default of {a.at}"
    against = f"`{a.default}` minus `{a.ablated}`" + (f" ({a.note})" if a.note else "")
    return f"{when}, {p['runs']} runs: **{_points(p['mean'])}**{ci}, {against}"


def _cells(evidence: Ablation | Unstored) -> tuple[str, str]:
    if isinstance(evidence, Unstored):
        return evidence.text, evidence.command
    folders = dict.fromkeys([evidence.default_results or evidence.results, evidence.results])
    return measured(evidence), " and ".join(command(f) for f in folders)


def render_departures(rows: tuple[Departure, ...] = DEPARTURES) -> str:
    lines = [
        "| departure (the default; the paper) | why | undone: default minus ablated, success points "
        "[95 % CI] | command |",
        "|---|---|---|---|",
    ]
    for d in rows:
        cells = [_cells(e) for e in d.evidence]
        result = "; ".join(c[0] for c in cells)
        commands = "; ".join(dict.fromkeys(c[1] for c in cells if c[1]))
        lines.append(f"| {d.what} | {d.why} | {result} | {commands or '-'} |")
    return "\n".join(lines)


def render_reads() -> str:
    """The built-in methods grouped by what they read (``nirl_mj.experiments.reads``)."""
    from nirl_mj.experiments.definition import BUILTIN_METHODS
    from nirl_mj.experiments.reads import is_reference, method_reads

    groups: dict[tuple[str, ...], list[str]] = {}
    for name, method in BUILTIN_METHODS.items():
        groups.setdefault(tuple(method_reads(method)), []).append(name)
    lines = ["| methods | reads | |", "|---|---|---|"]
    for reads, names in groups.items():
        kind = "reference" if is_reference(list(reads)) else "learner from demonstrations"
        lines.append(f"| {', '.join(f'`{n}`' for n in names)} | {', '.join(reads)} | {kind} |")
    return "\n".join(lines)


RENDERERS: dict[str, Callable[..., str]] = {
    "departures": render_departures,
    "removed": lambda: render_departures(REMOVED),
    "reads": render_reads,
}


def main() -> None:
    print(RENDERERS[sys.argv[1]](*sys.argv[2:]))


if __name__ == "__main__":
    main()
