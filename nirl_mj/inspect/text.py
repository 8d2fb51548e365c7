"""One-line and few-line text summaries for a terminal: episodes, datasets, evaluations."""

from __future__ import annotations

from nirl_mj.data.trajectory import Trajectory, path_length


def phi_text(phi) -> str:
    """One phi(s) (16 values) as "D 0000000 V 1 I 0 U 0000000": the danger levels of S1-S4 and S7-S9,
    the target's sector and whether it is detected, the wall flags of the same sensors."""
    d, u = ("".join(str(int(v)) for v in part) for part in (phi[0:7], phi[9:16]))
    return f"D {d} V {int(phi[7])} I {int(phi[8])} U {u}"


def episode_line(t: Trajectory) -> str:
    """Arena seed, outcome, decisions and metres driven of one episode."""
    return f"seed {t.arena_seed:10d}  {t.outcome:13s} steps {len(t):4d}  path {path_length(t):6.1f} m"


def summary_lines(summary: dict) -> str:
    """Outcome rates, episode lengths and action shares of a ``summarise`` result (continuous
    actions: their mean shares of the forward speed and of the yaw rate)."""
    if summary.get("action_kind") == "continuous":
        mean = summary["mean_action"]
        actions = (
            f"continuous actions ({summary['pairs']} pairs): mean shares forward {mean['forward']:+.2f}, "
            f"yaw rate {mean['yaw_rate']:+.2f} (size {mean['abs_yaw_rate']:.2f})"
        )
    else:
        shares = "  ".join(f"{name} {frac:.1%}" for name, frac in summary["action_fractions"].items())
        actions = f"actions ({summary['pairs']} pairs): {shares}"
    return (
        f"episodes {summary['episodes']}  success {summary['success_rate']:.0%}  collision "
        f"{summary['collision_rate']:.0%}  timeout {summary['timeout_rate']:.0%}  diverged "
        f"{summary['physics_error_rate']:.0%}  steps mean {summary['mean_steps']:.1f} "
        f"(min {summary['min_steps']}, max {summary['max_steps']})\n{actions}"
    )


def predictability_line(p: dict) -> str:
    """How well phi(s) predicts the demonstrator's actions (``learn.predictability``)."""
    return (
        "predictability from phi(s) (class-weighted logistic regression, first half -> second half): "
        f"balanced accuracy {p['balanced_accuracy']:.2f}, accuracy {p['accuracy']:.2f} "
        f"(majority action alone: {p['majority_share']:.2f})"
    )


def evaluation_line(task: str, metrics: dict) -> str:
    """Success, collision and timeout rates, path length and SPL of a held-out evaluation."""
    return (
        f"{metrics['tests']} held-out tests of {task}: success {metrics['success_rate']:.0%}  collision "
        f"{metrics['collision_rate']:.0%}  timeout {metrics['timeout_rate']:.0%}  path "
        f"{metrics['mean_path_length']:.1f} m  SPL {metrics['spl']:.2f}"
    )
