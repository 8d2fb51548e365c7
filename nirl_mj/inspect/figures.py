"""Reports of a run: the NIRL paper's figures as PNGs and a Markdown summary.

The NIRL paper is :data:`NIRL_PAPER` (``../shared/paper/``); its figure numbers are quoted below.

- ``margin.png``: the margin t of the max-margin reward step per iteration (the paper's Fig. 4a);
- ``cost.png``: the network cost J(Omega) (eq. 15) per iteration (Fig. 4b);
- ``weights.png``: ||dW1||_1 and ||dW2||_1 per iteration (Fig. 7);
- ``training.png``: training success and the demonstrations' (balanced) accuracy per iteration,
  where a collapse shows at once (and validation success where the run validated);
- ``paths.png``: paths of the policies in a few test arenas (Fig. 5), axes in metres.

Every training-curve figure marks the iteration whose policy the run selected (``selected``):
a vertical line labelled :data:`SELECTED_LABEL`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Polygon

from nirl_mj.data.atomic import write_figure
from nirl_mj.data.trajectory import Trajectory, path_length
from nirl_mj.inspect.canvas import subplots
from nirl_mj.inspect.recording import layout_of

NIRL_PAPER = "*Neural Inverse Reinforcement Learning with a Nonlinear Policy Representation*"
"""The paper this project makes real ("the NIRL paper" in reports), as README.md cites it: by the title of
the stored copy (``../shared/paper/nirl-paper.md``), which names no authors or venue."""

SPL_TEXT = (
    "*SPL*, success weighted by path length (Anderson et al. 2018) = (1/N) sum_i S_i L_i / max(L_i, P_i) "
    "over the N test episodes, S_i = 1 if episode i reached the target (else 0), P_i the path driven "
    "(metres), L_i the straight line from the start to the target's rim, a lower bound of the shortest "
    "path (so SPL errs low); from 0 to 1, 1 if every test drove straight to the target, a failed test "
    "counting 0"
)
"""SPL's definition for a report (``nirl_mj.data.outcomes``, docs/EXPERIMENTS.md)."""

SCT_TEXT = (
    "*SCT*, success weighted by completion time (Yokoyama et al. 2021) = (1/N) sum_i S_i C_i / "
    "max(C_i, T_i), T_i the episode's duration (decisions x the decision period, seconds) and "
    "C_i = L_i / v the time of that straight line at the commanded speed v: a robot that turns or backs "
    "off on the spot loses time that SPL does not see"
)
"""SCT's definition for a report (``nirl_mj.data.outcomes``, docs/EXPERIMENTS.md)."""

SELECTED_LABEL = "selected policy (iteration {iteration})"
"""The label of the vertical line that marks the selected iteration on every training curve."""

SUCCESS_PATH = "path of successful tests (m)"
"""The results table's path column: the mean path of the tests that reached the target."""

ITERATION_LABEL = "iteration (one pass of Algorithm 1)"

OUTCOME_TEXT = {
    "target": "reached the target",
    "collision": "collided",
    "timeout": "timed out",
    "physics_error": "physics error",
}
"""Outcome -> how a figure says it."""

_OUTCOME_MARKERS = {"target": "o", "collision": "X", "timeout": "s", "physics_error": "P"}
"""The marker at a path's end, by how the episode ended."""

_POLICY_STYLES = (  # colour, line style, width: the first drawn widest, below the others
    ("tab:blue", "-", 3.2),
    ("tab:orange", "--", 2.0),
    ("black", "-", 1.1),
    ("tab:purple", "-.", 1.1),
    ("tab:brown", ":", 1.1),
)


def _line_figure(
    series: dict[str, Sequence[float | None]], ylabel: str, title: str, selected: int | None = None
):
    """One training curve per series (iterations with a value only; a series without any is left
    out), and the selected iteration as a dashed vertical line labelled :data:`SELECTED_LABEL`."""
    fig, ax = subplots(figsize=(6.4, 3.4), dpi=110)
    for label, values in series.items():
        x = [i for i, v in enumerate(values) if v is not None and v == v]  # v == v: not NaN
        if x:
            ax.plot(x, [values[i] for i in x], label=label, marker="." if len(x) < 30 else None)
    if selected is not None and selected >= 0:
        ax.axvline(selected, color="0.2", linestyle="--", linewidth=1.0,
                   label=SELECTED_LABEL.format(iteration=selected))  # fmt: skip
    ax.set_xlabel(ITERATION_LABEL)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def training_figures(m: Sequence[dict], selected: int | None = None) -> dict:
    """The training figures of a run's metrics rows ``m`` by file name (matplotlib figures on their
    own canvases, :mod:`nirl_mj.inspect.canvas`), each marking the ``selected`` iteration (None: no mark)."""
    col = {k: [row.get(k) for row in m] for k in m[0]} if m else {}
    plots = {
        "margin.png": (
            {"margin t": col.get("margin", [])},
            "margin t (reward units)",
            "Margin t of the max-margin reward step (NIRL paper, Fig. 4a)",
        ),
        "cost.png": (
            {"J(Omega)": col.get("cost", [])},
            "cost J(Omega) (cross-entropy, nats)",
            "Network cost J(Omega), eq. 15 (NIRL paper, Fig. 4b)",
        ),
        "weights.png": (
            {"||dW1||_1 (hidden layer)": col.get("dw1", []), "||dW2||_1 (output layer)": col.get("dw2", [])},
            "L1 norm of the change in weights",
            "Change of the network's weights per iteration (NIRL paper, Fig. 7)",
        ),
        "training.png": (
            {
                "training success (exploring policy)": col.get("success_rate", []),
                "demonstration accuracy": col.get("demo_accuracy", []),
                "demonstration balanced accuracy": col.get("demo_balanced_accuracy", []),
                "validation success": col.get("validation_success", []),
            },
            "fraction (0 to 1)",
            "Learning curves",
        ),
    }
    return {
        name: _line_figure(series, ylabel, title, selected) for name, (series, ylabel, title) in plots.items()
    }


def training_plots(m: Sequence[dict], out_dir: str | Path, selected: int | None = None) -> list[Path]:
    """The NIRL paper's Fig. 4a, 4b, 7 and the learning curves of a run's metrics rows ``m`` in
    ``out_dir`` (:func:`training_figures`, ``selected`` marked); returns the files."""
    out = Path(out_dir)
    files = []
    for name, fig in training_figures(m, selected).items():
        write_figure(out / name, fig)
        files.append(out / name)
    return files


def _draw_layout(ax, layout) -> None:
    for o in layout.obstacles:
        if o.shape == "cylinder":
            ax.add_patch(Circle((o.x, o.y), o.size[0], color="0.7", zorder=1))
        else:
            hx, hy = o.size
            corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
            c, s = np.cos(o.yaw), np.sin(o.yaw)
            pts = corners @ np.array([[c, s], [-s, c]]) + [o.x, o.y]
            ax.add_patch(Polygon(pts, color="0.45" if o.is_wall else "0.7", zorder=1))


def paths_figure(runs: dict[str, Sequence[Trajectory]], arenas: int = 3):
    """Top-down view (metres) of the first ``arenas`` test arenas with each policy's path (the NIRL
    paper's Fig. 5; a matplotlib figure on its own canvas, :mod:`nirl_mj.inspect.canvas`). Each
    policy has its own colour and style; the first is drawn widest and lowest, the next ones
    narrower above it, so that a path that
    runs along another (always forward's, which starts as every other does) stays visible. A
    marker at a path's end says how it ended (:data:`OUTCOME_TEXT`); each panel's legend gives
    every path's outcome and length, the figure's the start, target and end markers."""
    names = list(runs)
    arenas = max(1, min([arenas, *(len(v) for v in runs.values())]))
    fig, axes = subplots(1, arenas, figsize=(4.6 * arenas, 5.4), dpi=110, squeeze=False)
    for k, ax in enumerate(axes[0]):
        layout = layout_of(runs[names[0]][k])
        _draw_layout(ax, layout)
        for z, name in enumerate(names):
            colour, style, width = _POLICY_STYLES[z % len(_POLICY_STYLES)]
            t = runs[name][k]
            label = f"{name}: {OUTCOME_TEXT[t.outcome]}, {path_length(t):.0f} m"
            ax.plot(t.poses[:, 0], t.poses[:, 1], style, color=colour, lw=width, label=label, zorder=3 + z)
            ax.plot(*t.poses[-1, :2], _OUTCOME_MARKERS[t.outcome], color=colour, ms=8, mec="white", mew=0.8,
                    zorder=10 + z)  # fmt: skip
        ax.plot(*layout.start, "o", color="tab:blue", mfc="white", ms=9, mew=2, zorder=20)
        ax.plot(*layout.target, "*", color="tab:green", ms=14, zorder=20)
        ax.set_xlim(0, layout.size[0])
        ax.set_ylim(0, layout.size[1])
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(f"test arena {k}", fontsize=10)
        ax.grid(alpha=0.2)
        ax.legend(fontsize=7, loc="best", framealpha=0.8)
    keys = [
        Line2D([], [], ls="none", marker="o", color="tab:blue", mfc="white", ms=8, mew=2, label="start"),
        Line2D([], [], ls="none", marker="*", color="tab:green", ms=12, label="target"),
        *(Line2D([], [], linestyle="none", marker=_OUTCOME_MARKERS[o], color="0.3", ms=8,
                 label=f"path end: {OUTCOME_TEXT[o]}") for o in ("target", "collision", "timeout")),
    ]  # fmt: skip
    fig.suptitle("Paths in held-out test arenas, seen from above (grey: obstacles)", fontsize=10, y=0.985)
    fig.legend(handles=keys, loc="upper center", bbox_to_anchor=(0.5, 0.945), ncol=len(keys), fontsize=8,
               frameon=False)  # fmt: skip
    fig.tight_layout(rect=(0, 0, 1, 0.9))
    return fig


def paths_plot(path: str | Path, runs: dict[str, Sequence[Trajectory]], arenas: int = 3) -> Path:
    """Writes :func:`paths_figure` to ``path`` (PNG)."""
    fig = paths_figure(runs, arenas)
    write_figure(path, fig)
    return Path(path)


def _cell(value: float | None, spec: str) -> str:
    return "-" if value is None or value != value else format(value, spec)


def _words(reads: list[str] | None) -> str:
    return ", ".join(reads or []) or "nothing"


def results_table(results: dict[str, dict], reads_cell: Callable[[list[str] | None], str] = _words) -> str:
    """Markdown table of evaluation results by policy name.

    The path column is the mean path of the successful tests only (metres; "-" where none
    succeeded), where every row holds it (``success_path_length``:
    :func:`nirl_mj.experiments.main_job.report_rows` computes it from the test episodes); without it
    (stored results hold the mean over every test, crashes included, which makes a policy that
    crashes early look efficient) there is no path column. SCT where a row has it ("-" for the
    others); no SCT column where none has. A ``reads`` list in a result (what the method reads,
    ``nirl_mj.experiments.reads``) becomes a last column, each cell written by ``reads_cell``
    (``experiments.reads.reads_text``, which marks a reference, passed in because ``inspect`` may not
    import ``experiments``; by default the words joined)."""
    rows = results.values()
    reads = any("reads" in r for r in rows)
    path = bool(results) and all("success_path_length" in r for r in rows)
    sct = any("sct" in r for r in rows)
    columns = ["policy", "success", "collision", "timeout", *([SUCCESS_PATH] if path else []), "SPL",
               *(["SCT"] if sct else []), "tests", *(["reads"] if reads else [])]  # fmt: skip
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for name, r in results.items():
        cells = [name, f"{r['success_rate']:.0%}", f"{r['collision_rate']:.0%}", f"{r['timeout_rate']:.0%}"]
        cells += [_cell(r["success_path_length"], ".1f")] if path else []
        cells += [f"{r['spl']:.2f}", *([_cell(r.get("sct"), ".2f")] if sct else []), str(r["tests"])]
        cells += [reads_cell(r.get("reads"))] if reads else []
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
