"""How recorded series look and which share a plot: colours, names and groups by scale.

One table serves both the recording (:mod:`nirl_mj.inspect.recording` logs each series' colour and
name once, as static ``SeriesLines``) and the layout (:mod:`nirl_mj.inspect.blueprint` gives each
group its own plot), so a plot never mixes a series climbing to 60 with one that stays below 1.
Colours are Tableau 10, which a reader tells apart also in small plots, and a darker grey.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import NamedTuple

import numpy as np
import rerun as rr

from nirl_mj.data.features import FEATURE_NAMES

RGB = tuple[int, int, int]
BLUE, ORANGE, GREEN, RED = (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40)
PURPLE, BROWN, PINK, GREY = (148, 103, 189), (140, 86, 75), (227, 119, 194), (110, 110, 110)
OLIVE, CYAN = (188, 189, 34), (23, 190, 207)
SENSOR_COLOURS = (BLUE, ORANGE, GREEN, RED, PURPLE, BROWN, PINK)
"""One colour per sensor of phi(s) (S1-S4, S7-S9), the same in the danger and the wall plot."""
REWARD_COLOUR = RED


class Plot(NamedTuple):
    """One plot: its title and the series it holds (``key`` -> colour), all of one scale."""

    title: str
    series: dict[str, RGB]


TRAINING_PLOTS = (
    Plot("cost", {"cost": RED}),
    Plot("margin", {"margin": BLUE}),
    Plot("weight changes", {"dw1": BLUE, "dw2": ORANGE}),
    Plot("on the demonstrations", {"demo_accuracy": BLUE, "demo_balanced_accuracy": ORANGE,
                                   "reward_prefers_forward": GREEN}),
    Plot("rollout outcomes", {"success_rate": GREEN, "collision_rate": RED, "timeout_rate": ORANGE,
                              "validation_success": BLUE}),
    Plot("reward weights", {"theta_norm": PURPLE, "reward_spread": BROWN, "clipped_share": GREY}),
    Plot("policy entropy (nats)", {"policy_entropy": CYAN}),
    Plot("eta", {"eta": OLIVE}),
)  # fmt: skip
"""The training curves, a plot per scale: rates and accuracies (0-1) apart from cost (~0.6),
margin (~-0.01), weight changes (~1-6), entropy (~1.6) and eta (5 -> 60)."""
TRAINING_KEYS = tuple(key for plot in TRAINING_PLOTS for key in plot.series)
"""Training scalars logged under ``training/<key>`` when a metrics row has them."""


class FeatureGroup(NamedTuple):
    """A part of phi(s) logged as its own entity ``P/features/<name>``: columns ``index`` of phi."""

    name: str
    title: str
    index: slice
    colours: tuple[RGB, ...]


FEATURE_GROUPS = (
    FeatureGroup("danger", "danger D per sensor (0 clear .. 7 contact)", slice(0, 7), SENSOR_COLOURS),
    FeatureGroup("target", "target sector V (1..9)", slice(7, 8), (CYAN,)),
    FeatureGroup(
        "flags", "flags: I target seen, U wall per sensor (0/1)", slice(8, 16), (GREY, *SENSOR_COLOURS)
    ),
)
"""phi(s) split by scale: the seven danger levels, the target's sector, and the eight 0/1 flags.
Titles are short enough for a plot a third of a 1600-pixel screen wide."""
SENSOR_NAMES = tuple(name.removeprefix("D_") for name in FEATURE_NAMES[:7])
"""The sensors of phi(s), in the order of :data:`SENSOR_COLOURS`."""


def feature_names(group: FeatureGroup) -> list[str]:
    """The names of ``group``'s series (``D_S1``, ..., ``V``, ``I``, ``U_S1``, ...)."""
    return list(FEATURE_NAMES[group.index])


def log_series_style(rec: rr.RecordingStream, path: str, names: list[str], colours: tuple[RGB, ...]) -> None:
    """Logs the names and colours of ``path``'s series once, as static data (every row shares them)."""
    rec.log(path, rr.SeriesLines(colors=list(colours), names=names, widths=[2.0] * len(names)), static=True)


def log_training_styles(rec: rr.RecordingStream, keys: Iterable[str], prefix: str = "training") -> None:
    """The static style (:data:`TRAINING_PLOTS`) of the training series ``keys`` under ``prefix``."""
    keys = set(keys)
    for plot in TRAINING_PLOTS:
        for key, colour in plot.series.items():
            if key in keys:
                log_series_style(rec, f"{prefix}/{key}", [key], (colour,))


class Swatch(NamedTuple):
    """One legend entry: how the colour is drawn (``line``, ``box``, ``dot`` or ``scale``, a
    gradient through ``colours``), its colour(s) and what it means."""

    kind: str
    colours: tuple[RGB, ...]
    text: str


class LegendSection(NamedTuple):
    """A titled column block of a legend."""

    title: str
    swatches: tuple[Swatch, ...]


_LEGEND_ROW = 18  # pixels per legend line
_LEGEND_FONT = 8.0  # points at 100 dpi: 11 pixels
_SWATCH = 30  # pixels from a swatch's left to its text
_GAP = 14  # pixels between columns


def legend_image(columns: Sequence[Sequence[LegendSection]]) -> np.ndarray:
    """A colour legend as an image (H, W, 3) uint8 for an image view: ``columns`` side by side,
    each its sections one under the other, a swatch then its text per line, dark text on white.
    Swatches are drawn without antialiasing, so each colour appears in the image exactly (the
    tests look for it). Each column is as wide as its longest text, the image as tall as its
    longest column: shown at its own size it needs no scaling."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.patches import Circle, Rectangle

    from nirl_mj.inspect.canvas import figure, to_rgb

    fig = figure(dpi=100)
    renderer = fig.canvas.get_renderer()
    regular, bold = FontProperties(size=_LEGEND_FONT), FontProperties(size=_LEGEND_FONT, weight="bold")

    def text_width(text: str, font: FontProperties) -> float:
        return renderer.get_text_width_height_descent(text, font, ismath=False)[0]

    widths = [max([text_width(s.title, bold) for s in column]
                  + [_SWATCH + text_width(w.text, regular) for s in column for w in s.swatches], default=0.0)
              for column in columns]  # fmt: skip
    rows = max((sum(1 + len(s.swatches) for s in column) + len(column) - 1 for column in columns), default=1)
    width = int(np.ceil(sum(widths) + _GAP * len(columns) + 6))
    height = rows * _LEGEND_ROW + 8
    fig.set_size_inches(width / 100, height / 100)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)  # pixels, y down
    ax.axis("off")
    x = 6.0
    for column, column_width in zip(columns, widths, strict=True):
        y = 4.0
        for s, section in enumerate(column):
            if s:
                y += _LEGEND_ROW
            ax.text(x, y + _LEGEND_ROW / 2, section.title, va="center", fontproperties=bold)
            y += _LEGEND_ROW
            for swatch in section.swatches:
                _draw_swatch(ax, swatch, x, y, Rectangle, Circle)
                ax.text(x + _SWATCH, y + _LEGEND_ROW / 2, swatch.text, va="center", fontproperties=regular)
                y += _LEGEND_ROW
        x += column_width + _GAP
    return to_rgb(fig)


def _draw_swatch(ax, swatch: Swatch, x: float, y: float, rectangle, circle) -> None:
    """Draws ``swatch`` in the legend cell at (x, y) (top left; 18 pixels high, 24 or 25 wide)."""
    mid = y + _LEGEND_ROW / 2
    colours = [tuple(v / 255 for v in c) for c in swatch.colours]
    edge = (0.35, 0.35, 0.35)
    if swatch.kind == "line":
        ax.add_patch(
            rectangle((x, mid - 2.5), 24, 5, facecolor=colours[0], edgecolor="none", antialiased=False)
        )
    elif swatch.kind == "box":
        ax.add_patch(rectangle((x + 4, mid - 7), 16, 14, facecolor=colours[0], edgecolor=edge, lw=0.6,
                               antialiased=False))  # fmt: skip
    elif swatch.kind == "dot":
        ax.add_patch(
            circle((x + 12, mid), 6.5, facecolor=colours[0], edgecolor=edge, lw=0.6, antialiased=False)
        )
    elif swatch.kind == "scale":  # piecewise linear through the colours, 25 pixel columns: ends exact
        stops = np.array(swatch.colours, dtype=np.float64)
        u = np.linspace(0.0, len(stops) - 1, 25)
        ramp = np.stack([np.interp(u, np.arange(len(stops)), stops[:, k]) for k in range(3)], axis=1)
        ax.imshow(ramp[None].round().astype(np.uint8), extent=(x, x + 25, mid + 5, mid - 5),
                  interpolation="nearest", aspect="auto")  # fmt: skip
    else:
        raise ValueError(f"unknown swatch kind {swatch.kind!r}")


def training_figure(rows: Sequence[dict], title: str = "training", selected: int | None = None) -> np.ndarray:
    """The training curves of metrics ``rows`` (``episode`` and :data:`TRAINING_KEYS`) as one image
    (H, W, 3) uint8: a plot per scale (:data:`TRAINING_PLOTS`, those with data), four to a row, each
    with its title and, above the curves, a legend whose swatches have the curves' exact colours;
    the ``selected`` iteration (the policy the run reports) as a dashed grey line on every plot,
    named in the title."""
    from matplotlib.patches import Patch

    from nirl_mj.inspect.canvas import subplots, to_rgb

    plots = []
    for plot in TRAINING_PLOTS:
        series = []
        for key, colour in plot.series.items():
            points = [(float(r["episode"]), float(r[key])) for r in rows
                      if r.get(key) is not None and np.isfinite(r[key])]  # fmt: skip
            if points:
                series.append((key, colour, np.array(points)))
        if series:
            plots.append((plot.title, series))
    columns = min(4, max(len(plots), 1))
    lines = -(-max(len(plots), 1) // columns)
    fig, axes = subplots(lines, columns, figsize=(15.6, 3.6 * lines), dpi=100, squeeze=False)
    # Fixed margins, room above each plot for its title and two rows of legend (matplotlib's
    # constrained layout would cost a second).
    fig.subplots_adjust(left=0.04, right=0.99, bottom=0.2 / lines, top=1 - 0.36 / lines, wspace=0.2,
                        hspace=0.75)  # fmt: skip
    for ax in axes.flat[len(plots) :]:
        ax.axis("off")
    for ax, (name, series) in zip(axes.flat, plots, strict=False):
        for _, colour, xy in series:
            ax.plot(
                xy[:, 0],
                xy[:, 1],
                color=tuple(v / 255 for v in colour),
                lw=1.6,
                marker="." if len(xy) < 3 else "",
            )
        handles = [Patch(facecolor=tuple(v / 255 for v in c), edgecolor="none", antialiased=False, label=k)
                   for k, c, _ in series]  # fmt: skip
        wide = sum(len(k) for k, _, _ in series) > 36  # two columns would run past the plot's right
        ncol = 1 if wide else 2
        ax.legend(handles=handles, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=ncol, frameon=False,
                  fontsize=9, handlelength=1.2, handleheight=1.0, borderaxespad=0.2)  # fmt: skip
        rows = -(-len(series) // ncol)
        ax.set_title(name, loc="left", fontsize=10, weight="bold", pad=6 + 15 * rows)
        ax.set_xlabel("iteration", fontsize=9)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)
        if selected is not None and selected >= 0:
            ax.axvline(selected, color="0.35", linestyle="--", linewidth=1.0)
    if selected is not None and selected >= 0:
        title += f" (dashed line: the selected policy, iteration {selected})"
    fig.suptitle(title, fontsize=11)
    return to_rgb(fig)
