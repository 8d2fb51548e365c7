"""Draws one arena of each floor-plan family from the top as docs/images/floor_plans.png.

Each panel is ``tasks/structured.toml`` with ``arena.floor_plan`` set to the family and no
random obstacles (the family alone), except "mixed" (the task as shipped: a family drawn per
episode plus 5 random obstacles) and "random" (the paper's navigate task). Walls are dark,
obstacles grey, the dashed line runs from start (blue) to target (green), and the orange line
is the planner's shortest clearance-weighted path (the cost field of nirl_mj.experts.planner,
followed downhill), which shows the arena is solvable.
Run from anywhere: ``python docs/scripts/floor_plans_figure.py [--seed N]``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from nirl_mj.data.atomic import write_figure  # noqa: E402
from nirl_mj.experts.planner import cost_field  # noqa: E402
from nirl_mj.sim.drive import BODY_RADIUS  # noqa: E402
from nirl_mj.sim.layout import Layout, generate_layout  # noqa: E402
from nirl_mj.sim.spec import load_task, replace  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "images" / "floor_plans.png"
PANELS = ("corridors", "pockets", "clusters", "blocks", "rooms", "slalom", "mixed", "random")


def _task(panel: str):
    if panel == "random":
        return load_task("navigate")
    task = load_task(ROOT / "tasks" / "structured.toml")
    if panel == "mixed":
        return task
    return replace(task, arena={"floor_plan": panel, "static_obstacles": 0})


def _path(layout: Layout, inflate: float, step: float = 0.5) -> np.ndarray:
    """Points (K, 2) from start downhill on the planner's cost field until the target."""
    field = cost_field(layout, inflate)
    angles = np.linspace(0.0, 2 * math.pi, 32, endpoint=False)
    ring = step * np.column_stack([np.cos(angles), np.sin(angles)])
    p = np.array(layout.start, dtype=float)
    points = [p]
    for _ in range(2000):
        if math.dist(p, layout.target) < 1.0:
            break
        candidates = p + ring
        p = candidates[np.argmin(field(candidates[:, 0], candidates[:, 1]))]
        points.append(p)
    return np.array(points)


def _draw(ax, layout: Layout, title: str) -> None:
    for o in layout.obstacles:
        if o.shape == "cylinder":
            ax.add_patch(plt.Circle((o.x, o.y), o.size[0], color="0.55"))
            continue
        hx, hy = o.size
        c, s = math.cos(o.yaw), math.sin(o.yaw)
        corners = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]) @ np.array([[c, s], [-s, c]])
        ax.add_patch(plt.Polygon(corners + (o.x, o.y), color="0.2" if o.is_wall else "0.55"))
    path = _path(layout, BODY_RADIUS + 0.1)
    ax.plot(path[:, 0], path[:, 1], color="tab:orange", lw=1.3)
    ax.plot(*zip(layout.start, layout.target, strict=True), "--", color="0.6", lw=0.8)
    ax.plot(*layout.start, "o", color="tab:blue", ms=6)
    ax.plot(*layout.target, "*", color="tab:green", ms=11)
    ax.set_xlim(0, layout.size[0])
    ax.set_ylim(0, layout.size[1])
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=10)


def main(argv: list[str] | None = None) -> Path:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=3, help="arena seed of every panel")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    fig, axes = plt.subplots(2, 4, figsize=(13, 7.2), dpi=110)
    for ax, panel in zip(axes.ravel(), PANELS, strict=True):
        task = _task(panel)
        layout = generate_layout(task.arena, np.random.RandomState(args.seed))
        title = f"mixed (drew {layout.floor_plan}) + 5 random" if panel == "mixed" else panel
        _draw(ax, layout, title if panel != "random" else "random (navigate)")
    fig.suptitle(f"Floor plans (arena.floor_plan), 100 m x 100 m, seed {args.seed}", fontsize=12)
    fig.tight_layout()
    out = write_figure(args.out, fig)
    plt.close(fig)
    print(out)
    return out


if __name__ == "__main__":
    main()
