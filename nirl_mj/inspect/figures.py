"""Reports of a run: the paper's figures as PNGs and a Markdown summary.

- ``margin.png``: the margin t per iteration (paper Fig. 4a);
- ``cost.png``: the network cost J(Omega) per iteration (Fig. 4b);
- ``weights.png``: ||dW1||_1 and ||dW2||_1 per iteration (Fig. 7);
- ``paths.png``: paths of the policies in a few test arenas (Fig. 5);
- ``training.png``: training success, demonstration (balanced) accuracy and
  validation success per iteration, where a collapse shows at once.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless: files only
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from nirl_mj.data.atomic import write_figure  # noqa: E402
from nirl_mj.data.trajectory import Trajectory  # noqa: E402
from nirl_mj.inspect.recording import layout_of  # noqa: E402

_COLOURS = {
    "target": "tab:green",
    "collision": "tab:red",
    "timeout": "tab:orange",
    "physics_error": "tab:purple",
}


def _line_plot(path: Path, series: dict[str, Sequence[float]], ylabel: str, title: str) -> None:
    fig, ax = plt.subplots(figsize=(6, 3.2), dpi=110)
    for label, values in series.items():
        x = [i for i, v in enumerate(values) if v is not None]
        ax.plot(x, [values[i] for i in x], label=label, marker="." if len(x) < 30 else None)
    ax.set_xlabel("iteration (NIRL episode)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if len(series) > 1:
        ax.legend(fontsize=8)
    fig.tight_layout()
    write_figure(path, fig)
    plt.close(fig)


def training_plots(m: Sequence[dict], out_dir: str | Path) -> list[Path]:
    """Fig. 4a, 4b, 7 and the training curves of a run's metrics rows ``m``; returns the files."""
    out = Path(out_dir)
    col = {k: [row[k] for row in m] for k in m[0]} if m else {}
    plots = {
        "margin.png": ({"margin t": col.get("margin", [])}, "margin", "Margin per iteration (Fig. 4a)"),
        "cost.png": ({"J(Omega)": col.get("cost", [])}, "cost", "Network cost per iteration (Fig. 4b)"),
        "weights.png": (
            {"||dW1||_1": col.get("dw1", []), "||dW2||_1": col.get("dw2", [])},
            "L1 norm of the change",
            "Weight changes per iteration (Fig. 7)",
        ),
        "training.png": (
            {
                "training success": col.get("success_rate", []),
                "demo accuracy": col.get("demo_accuracy", []),
                "demo balanced accuracy": col.get("demo_balanced_accuracy", []),
                "validation success": col.get("validation_success", []),
            },
            "fraction",
            "Learning curves",
        ),
    }
    files = []
    for name, (series, ylabel, title) in plots.items():
        _line_plot(out / name, series, ylabel, title)
        files.append(out / name)
    return files


def paths_plot(path: str | Path, runs: dict[str, Sequence[Trajectory]], arenas: int = 3) -> Path:
    """Top-down view of the first ``arenas`` test arenas with each policy's path (Fig. 5)."""
    names = list(runs)
    arenas = max(1, min([arenas, *(len(v) for v in runs.values())]))
    fig, axes = plt.subplots(1, arenas, figsize=(4 * arenas, 4.2), dpi=110)
    for k, ax in enumerate(np.atleast_1d(axes)):
        first = runs[names[0]][k]
        layout = layout_of(first)
        for o in layout.obstacles:
            if o.shape == "cylinder":
                ax.add_patch(plt.Circle((o.x, o.y), o.size[0], color="0.6"))
            else:
                hx, hy = o.size
                corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
                c, s = np.cos(o.yaw), np.sin(o.yaw)
                pts = corners @ np.array([[c, s], [-s, c]]) + [o.x, o.y]
                ax.add_patch(plt.Polygon(pts, color="0.35" if o.is_wall else "0.6"))
        for name, style in zip(names, ["-", "--", ":", "-."] * 3, strict=False):
            t = runs[name][k]
            ax.plot(
                t.poses[:, 0],
                t.poses[:, 1],
                style,
                color=_COLOURS[t.outcome],
                lw=1.4,
                label=f"{name} ({t.outcome})",
            )
        ax.plot(*layout.start, "bo")
        ax.plot(*layout.target, "g*", ms=12)
        ax.set_xlim(0, layout.size[0])
        ax.set_ylim(0, layout.size[1])
        ax.set_aspect("equal")
        ax.set_title(f"test arena {k}", fontsize=9)
        ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    write_figure(path, fig)
    plt.close(fig)
    return Path(path)


def results_table(results: dict[str, dict]) -> str:
    """Markdown table of evaluation results by policy name; a ``reads`` list in a result (what the
    method reads, ``nirl_mj.experiments.reads``) becomes a last column."""
    reads = any("reads" in r for r in results.values())
    lines = [
        "| policy | success | collision | timeout | mean path (m) | SPL | tests |"
        + (" reads |" if reads else ""),
        "|---|---|---|---|---|---|---|" + ("---|" if reads else ""),
    ]
    for name, r in results.items():
        line = (
            f"| {name} | {r['success_rate']:.0%} | {r['collision_rate']:.0%} | {r['timeout_rate']:.0%} | "
            f"{r['mean_path_length']:.1f} | {r['spl']:.2f} | {r['tests']} |"
        )
        lines.append(line + (f" {', '.join(r.get('reads', [])) or 'nothing'} |" if reads else ""))
    return "\n".join(lines)
