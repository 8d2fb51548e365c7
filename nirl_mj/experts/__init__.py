"""Demonstrators: who drives the robot when demonstrations are recorded.

An expert is reset at the start of every episode with the environment and its
first timestep, then asked for one action (0..5) per timestep. What it may
look at differs: the planner reads the whole arena through ``env``; the
sensor-based expert only ever reads ``timestep.observation``. On a task with
continuous actions each decision is driven (and recorded) as the action's
continuous twin (``nirl_mj.sim.drive.action_share``, by ``sim.episode.run_episode``).
"""

from __future__ import annotations

from nirl_mj.sim.episode import Agent as Expert

__all__ = ["DEMONSTRATORS", "EXPERT_KINDS", "Expert", "demonstrator_names", "make_expert"]

EXPERT_KINDS = ("planner", "sensor", "noisy", "rule", "forward")
"""Demonstrators by name: the map-aware planner, the sensor-based expert, either
of them with noise, and the reference policies on phi(s)."""

DEMONSTRATORS = {
    "sensor-random10": {"kind": "noisy", "base": "sensor", "slip": 0.0, "random": 0.1},
    "sensor-random30": {"kind": "noisy", "base": "sensor", "slip": 0.0, "random": 0.3},
    "sensor-random50": {"kind": "noisy", "base": "sensor", "slip": 0.0, "random": 0.5},
    "sensor-late2": {"kind": "sensor", "delay": 2},
}
"""Named demonstrators of experiment files beyond :data:`EXPERT_KINDS` (the demonstrator suite,
tasks/suites/quality.toml): the sensor expert with 10, 30 or 50 % of its decisions replaced by a
uniformly random action (which may be the one it chose), and the sensor expert turning two decisions
(one second) late, a systematic flaw (:class:`nirl_mj.experts.late.LateExpert`). Values are
``nirl_mj.experiments.demos.ExpertConfig`` fields."""


def demonstrator_names() -> tuple[str, ...]:
    """Every demonstrator an experiment file may name: the expert kinds and :data:`DEMONSTRATORS`."""
    return (*EXPERT_KINDS, *DEMONSTRATORS)


def make_expert(
    kind: str, base: str = "sensor", slip: float = 0.1, random: float = 0.05, seed: int = 0
) -> Expert:
    """Builds a demonstrator by name; ``base``, ``slip``, ``random`` and ``seed`` configure
    the noisy one (see :class:`nirl_mj.experts.noisy.NoisyExpert`)."""
    if kind == "planner":
        from nirl_mj.experts.planner import PlannerExpert

        return PlannerExpert()
    if kind == "sensor":
        from nirl_mj.experts.sensor import SensorExpert

        return SensorExpert()
    if kind == "noisy":
        from nirl_mj.experts.noisy import NoisyExpert

        if base == "noisy" or base not in EXPERT_KINDS:
            raise ValueError(f"noisy expert base {base!r}: accepted: planner, sensor, rule, forward")
        return NoisyExpert(make_expert(base), slip=slip, random=random, seed=seed)
    if kind in ("rule", "forward"):
        from nirl_mj.experts.policies import PolicyAgent

        return PolicyAgent.named(kind)
    raise ValueError(f"unknown expert {kind!r}: accepted: {', '.join(EXPERT_KINDS)}")
