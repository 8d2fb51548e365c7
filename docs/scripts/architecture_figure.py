"""Draws nirl_mj's rooms and the imports between them as docs/images/architecture.png.

The arrows come from the code: every import statement under nirl_mj/ (inside functions too),
read with ``ast``, counted per pair of rooms. An arrow is grey if the rules in pyproject.toml's
``[tool.importlinter]`` contracts (the layers, and the forbidden imports) allow it, red if not.
Run from anywhere: ``python docs/scripts/architecture_figure.py``.
"""

from __future__ import annotations

import ast
import json
import textwrap
import tomllib
from collections import Counter
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyBboxPatch  # noqa: E402

from nirl_mj.data.atomic import write_figure  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "nirl_mj"
OUT = ROOT / "docs" / "images" / "architecture.png"

# Where each room sits (x0, y0, x1, y1): upper rooms above lower ones; learn stands beside
# experts and sim because it imports neither, gym beside inspect likewise.
BOXES = {  # sized for the module lists as they are (2026-11-30: experiments 27 modules, sim 14)
    "cli": (-4.0, 11.2, 4.0, 12.2),
    "experiments": (-4.0, 8.6, 4.0, 10.5),
    "inspect": (-4.0, 6.3, -0.6, 7.9),
    "gym": (0.6, 6.3, 4.0, 7.9),
    "learn": (-4.0, 1.6, -0.6, 5.6),
    "experts": (0.6, 4.2, 4.0, 5.6),
    "sim": (0.6, 1.6, 4.0, 3.6),
    "data": (-4.0, 0.0, 4.0, 0.9),
}
LANE_START, LANE_STEP = 4.35, 0.3  # |x| of the innermost lane beside the boxes, and the spacing
EXIT_BELOW_TOP = 0.2  # a lane leaves its room's side this far below the box's top
ALLOWED_COLOUR, BROKEN_COLOUR = "#555555", "#d62728"


def rooms() -> dict[str, list[str]]:
    """Room -> its modules' short names: the sub-packages of nirl_mj (cli among them), and any
    top-level module."""
    found = {p.parent.name: [] for p in sorted(PACKAGE.glob("*/__init__.py"))}
    for room, names in found.items():
        names.extend(p.stem for p in sorted((PACKAGE / room).glob("*.py")) if p.stem != "__init__")
    found.update({p.stem: [] for p in sorted(PACKAGE.glob("*.py")) if p.stem != "__init__"})
    return found


def room_imports(names: set[str]) -> Counter[tuple[str, str]]:
    """(importer room, imported room) -> number of import statements between the rooms ``names``
    (nirl_mj/__init__.py left out)."""
    counts: Counter[tuple[str, str]] = Counter()
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts  # ("nirl_mj", room, ...)
        if len(parts) < 2 or parts[1] == "__init__":
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                dotted = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:  # relative: resolved against the importing module's package
                    package = parts[: len(parts) - node.level]
                    base = ".".join([*package, base] if base else package)
                dotted = [f"{base}.{alias.name}" for alias in node.names]
            else:
                continue
            targets = {name.split(".")[1] for name in dotted if name.startswith(PACKAGE.name + ".")}
            counts.update((parts[1], t) for t in targets & names if t != parts[1])
    return counts


def allowed_pairs(names: list[str]) -> set[tuple[str, str]]:
    """The room pairs pyproject.toml's contracts allow: a lower layer, unless forbidden."""
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    (layers,) = [c["layers"] for c in contracts if c["type"] == "layers"]
    level = {room.strip(): i for i, layer in enumerate(layers) for room in layer.split("|")}
    forbidden = {
        (source.split(".")[-1], target.split(".")[-1])
        for c in contracts
        if c["type"] == "forbidden"
        for source in c["source_modules"]
        for target in c["forbidden_modules"]
    }
    return {(a, b) for a in names for b in names if level[a] < level[b] and (a, b) not in forbidden}


def _free_x(a: tuple, b: tuple) -> float | None:
    """The middle of the widest x-interval where a vertical arrow joins boxes ``a`` and ``b``
    (one above the other) without crossing another box, or None."""
    top, bottom = (a, b) if a[1] > b[1] else (b, a)
    free = [(max(a[0], b[0]), min(a[2], b[2]))]
    for box in BOXES.values():
        if bottom[3] < box[3] and box[1] < top[1] and box not in (a, b):  # between them
            free = [
                piece
                for lo, hi in free
                for piece in ((lo, min(hi, box[0])), (max(lo, box[2]), hi))
                if piece[1] - piece[0] > 0.3
            ]
    widest = max(free, key=lambda piece: piece[1] - piece[0], default=None)
    return None if widest is None else (widest[0] + widest[1]) / 2


def _arrow(ax, points: list[tuple[float, float]], colour: str, width: float) -> None:
    """A polyline through ``points`` with an arrowhead at the last one."""
    xs, ys = zip(*points, strict=True)
    ax.plot(xs[:-1], ys[:-1], color=colour, lw=width, solid_capstyle="butt")
    ax.annotate(
        "",
        xy=points[-1],
        xytext=points[-2],
        arrowprops={"arrowstyle": "-|>", "color": colour, "lw": width, "shrinkA": 0, "shrinkB": 0},
    )


def _draw_boxes(ax, modules: dict[str, list[str]]) -> None:
    for room, (x0, y0, x1, y1) in BOXES.items():
        ax.add_patch(
            FancyBboxPatch(
                (x0, y0), x1 - x0, y1 - y0, boxstyle="round,pad=0,rounding_size=0.12",
                facecolor="#eef3fa", edgecolor="#2b4c7e", lw=1.4, zorder=3,
            )
        )  # fmt: skip
        label = "the nirl-mj command" if room == "cli" else ", ".join(modules[room])
        wrapped = textwrap.fill(label, width=int((x1 - x0) * 9.5))
        ax.text((x0 + x1) / 2, y1 - 0.12, room, ha="center", va="top", fontsize=12, weight="bold", zorder=4)
        ax.text((x0 + x1) / 2, y1 - 0.5, wrapped, ha="center", va="top", fontsize=8, color="#333", zorder=4)


def _draw_imports(ax, counts: Counter, allowed: set[tuple[str, str]]) -> None:
    """Arrows between boxes that face each other; the rest run in lanes beside the boxes, one lane
    per importing room and side (upper rooms outside, so that lanes do not cross on the way in)."""

    def style(a: str, b: str) -> tuple[str, float]:
        return ALLOWED_COLOUR if (a, b) in allowed else BROKEN_COLOUR, 1.0 + 0.25 * min(counts[(a, b)], 8)

    lanes: dict[tuple[str, str], list[str]] = {}  # (side, importer) -> imported rooms
    for a, b in sorted(counts, key=lambda pair: -BOXES[pair[0]][3]):
        src, dst = BOXES[a], BOXES[b]
        x = _free_x(src, dst)
        if src[1] < dst[3] and dst[1] < src[3]:  # side by side
            y = (max(src[1], dst[1]) + min(src[3], dst[3])) / 2
            x_from, x_to = (src[2], dst[0]) if src[0] < dst[0] else (src[0], dst[2])
            _arrow(ax, [(x_from, y), (x_to, y)], *style(a, b))
        elif x is not None:
            if (b, a) in counts:  # both ways: two arrows side by side
                x += 0.35 if src[1] > dst[1] else -0.35
            y_from, y_to = (src[1], dst[3]) if src[1] > dst[1] else (src[3], dst[1])
            _arrow(ax, [(x, y_from), (x, y_to)], *style(a, b))
        else:
            # The side the importer, else the imported room, leans to; left for two centred rooms.
            centres = [(box[0] + box[2]) / 2 for box in (src, dst)]
            side = "right" if next((c for c in centres if abs(c) > 0.1), 0.0) > 0 else "left"
            lanes.setdefault((side, a), []).append(b)

    lane_x: dict[tuple[str, str], float] = {}
    entries: dict[tuple[str, str], list[str]] = {}  # (side, imported) -> importers, lowest first
    for side in ("left", "right"):
        keys = sorted((k for k in lanes if k[0] == side), key=lambda k: BOXES[k[1]][3])
        for i, (_, a) in enumerate(keys):
            lane_x[(side, a)] = (-1 if side == "left" else 1) * (LANE_START + LANE_STEP * i)
            for b in lanes[(side, a)]:
                entries.setdefault((side, b), []).append(a)
    for (side, a), targets in lanes.items():
        src, x_lane = BOXES[a], lane_x[(side, a)]
        lowest = src[3]
        for b in targets:
            dst = BOXES[b]
            # Outer lanes (upper rooms) enter lower on the box's side, all below its own exit.
            order = entries[(side, b)]
            top = dst[3] - 2 * EXIT_BELOW_TOP
            y_in = top - (top - dst[1]) * (order.index(a) + 1) / (len(order) + 1)
            lowest = min(lowest, y_in)
            _arrow(ax, [(x_lane, y_in), (dst[2] if side == "right" else dst[0], y_in)], *style(a, b))
        x_side, y_exit = (src[2] if side == "right" else src[0]), src[3] - EXIT_BELOW_TOP
        ax.plot([x_side, x_lane, x_lane], [y_exit, y_exit, lowest], color=ALLOWED_COLOUR, lw=1.6)


def draw(modules: dict[str, list[str]], counts: Counter, allowed: set[tuple[str, str]]) -> plt.Figure:
    """The figure: a box per room with its modules, an arrow per pair of rooms in ``counts``."""
    missing = set(modules) - set(BOXES)
    if missing:
        raise SystemExit(f"rooms without a place in the figure: {sorted(missing)}; add them to BOXES")
    fig, ax = plt.subplots(figsize=(8.6, 10.6), dpi=110)
    ax.set_xlim(-6.0, 6.0)
    ax.set_ylim(-1.45, 12.4)
    ax.set_aspect("equal")
    ax.axis("off")
    _draw_boxes(ax, modules)
    _draw_imports(ax, counts, allowed)
    ax.plot([], [], color=ALLOWED_COLOUR, lw=2, label="imports, as the rules allow")
    ax.plot([], [], color=BROKEN_COLOUR, lw=2, label="imports against the rules")
    ax.legend(
        loc="upper center", bbox_to_anchor=(0, -0.2), bbox_transform=ax.transData,
        ncol=2, frameon=False, fontsize=9,
    )  # fmt: skip
    ax.text(
        0, -0.75,
        "An arrow A -> B: a module of A imports one of B (thicker: more import statements).\n"
        "From the code by docs/scripts/architecture_figure.py; rules: pyproject.toml [tool.importlinter].",
        ha="center", va="top", fontsize=8, color="#444",
    )  # fmt: skip
    fig.tight_layout()
    return fig


def main() -> None:
    modules = rooms()
    counts = room_imports(set(modules))
    allowed = allowed_pairs(list(modules))
    broken = sorted(pair for pair in counts if pair not in allowed)
    for a, b in broken:
        print(f"warning: {a} imports {b} against the rules ({counts[(a, b)]} import statements)")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    # the rooms and their modules go into the PNG, so that tests/test_docs.py sees when they change
    print(write_figure(OUT, draw(modules, counts, allowed), {"Description": json.dumps(modules)}))


if __name__ == "__main__":
    main()
