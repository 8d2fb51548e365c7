"""The information budget: what each method reads, in a fixed vocabulary.

A learner from demonstrations reads the demonstrations, phi(s) and that its own episodes ended;
never the task's reward, outcome or success, in training or in selecting a policy. A method
that reads more is a reference, and its record says so. Every training run's ``run.json``,
every method of a compare or main-job ``results.json`` and a suite's or sweep's ``results.json``
(under ``reads``, by method) carry a ``reads`` list of :data:`VOCABULARY` words, computed here from
the method's settings; their tables show it by :func:`reads_text`. tests/test_information_budget.py
checks the IRL loop's lists against what it touches: rollouts whose outcomes are swapped and whose
poses and target are redrawn (all that the task's reward is computed from) leave a learner that
does not read them in the same state, bit for bit.
"""

from __future__ import annotations

from typing import Any

VOCABULARY = {
    "demonstrations": "the expert's recorded state-action pairs",
    "features": "phi(s), the 16 state features (what every policy acts on)",
    "episode_end": "that an episode of its own ended (a terminal state), not how: the dynamics",
    "task_outcome": "which end an episode came to: arrival or collision (a timeout is no end: episode_end)",
    "task_reward": "the task's reward (progress, +1 on arrival, -1 on collision)",
    "task_success_selection": "the task's success on arenas other than the tests (validation arenas, or "
    "its own training episodes), to choose a policy",
    "interactive_expert": "the expert queried in states the learner visits (DAgger)",
    "hand_written": "a policy written by hand for this task (it knows the goal without learning it)",
    "demonstrator": "it is the demonstrator (it reads what its kind reads: the sensor expert the rays, "
    "odometry and target, the planner the whole arena)",
}
"""Every word a ``reads`` list may hold, with what it means."""

TASK_SIGNALS = ("task_outcome", "task_reward", "task_success_selection", "interactive_expert", "hand_written",
                "demonstrator")  # fmt: skip
"""The words that make a method a reference rather than a learner from demonstrations."""

LEARNER_BUDGET = ("demonstrations", "features", "episode_end")
"""All that a learner from demonstrations may read."""


def _ordered(words: set[str]) -> list[str]:
    return [w for w in VOCABULARY if w in words]


def learner_reads(config: Any) -> list[str]:
    """What a run of the shared IRL loop reads, from its ``LearnerConfig``."""
    loop = config.loop
    words = {"demonstrations", "features", "episode_end"}
    if loop.reward_source == "progress":
        words.add("task_reward")  # the progress control trains on the task's own shaping reward
    if loop.reads_outcome:
        words.add("task_outcome")
    if loop.selection == "validation":
        words.add("task_success_selection")
    return _ordered(words)


def rl_reads(algo: str, selection: str = "last") -> list[str]:
    """What a Stable-Baselines3 run reads: the task's reward (PPO, DQN), or the demonstrations
    through a discriminator (GAIL, AIRL and their variants); and the task's success if it chooses
    among its checkpoints by it (``experiments.rl.SELECTIONS``)."""
    words = {"features", "episode_end"}
    words |= {"task_reward", "task_outcome"} if algo in ("ppo", "dqn") else {"demonstrations"}
    if selection in ("training_success", "validation_success"):
        words.add("task_success_selection")
    return _ordered(words)


def method_reads(method: Any, shared_config: dict | None = None) -> list[str]:
    """What a method of an experiment (``definition.MethodSpec``) reads; ``shared_config`` is the
    experiment's ``[config]`` (learner changes for every trainable method)."""
    kind = method.kind
    if kind == "irl":
        return learner_reads(method.learner_config(shared_config or {}))
    if kind == "rl":
        return rl_reads(method.algo, method.selection)
    if kind == "bc":
        return _ordered({"demonstrations", "features"})
    if kind == "dagger":
        return _ordered({"demonstrations", "features", "interactive_expert"})
    if kind == "rule":
        return ["features", "hand_written"]
    if kind == "forward":
        return ["hand_written"]
    if kind == "expert":
        return ["demonstrator"]
    if kind == "plugin":  # as it declares (experiments.plugins), read when the experiment was loaded
        return _ordered(set(method.declared_reads))
    raise ValueError(f"unknown method kind {kind!r}")


def reads_by_method(experiment: Any) -> dict[str, list[str]]:
    """What each method of an experiment (``definition.Experiment``) reads, by name, in its order."""
    return {m.name: method_reads(m, experiment.config) for m in experiment.methods}


def is_reference(reads: list[str]) -> bool:
    """Whether a method that reads ``reads`` is a reference (it reads a task signal or an expert)."""
    return any(w in TASK_SIGNALS for w in reads)


def reads_text(reads: list[str] | None) -> str:
    """A method's ``reads`` for a table cell; a reference's (it reads a task signal) in bold."""
    if reads is None:  # a summary written before reads were recorded
        return "?"
    text = ", ".join(reads) or "nothing"
    return f"**reference:** {text}" if is_reference(reads) else text


READS_TERM = (
    "*reads*: what a method reads in training or in choosing its policy (`nirl_mj/experiments/reads.py`), "
    "a **reference** reading a task signal that a learner from demonstrations does not"
)
"""What a table's reads column means, for a report's terms (no full stop: a report ends the sentence)."""


def check_words(reads: list[str], where: str) -> None:
    """Raises ValueError naming ``where`` if ``reads`` holds a word outside :data:`VOCABULARY`."""
    unknown = [w for w in reads if w not in VOCABULARY]
    if unknown:
        raise ValueError(f"{where}: unknown reads word(s) {unknown}; accepted: {', '.join(VOCABULARY)}")
