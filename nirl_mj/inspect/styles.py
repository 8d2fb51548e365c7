"""How recorded series look and which share a plot: colours, names and groups by scale.

One table serves both the recording (:mod:`nirl_mj.inspect.recording` logs each series' colour and
name once, as static ``SeriesLines``) and the layout (:mod:`nirl_mj.inspect.blueprint` gives each
group its own plot), so a plot never mixes a series climbing to 60 with one that stays below 1.
Colours are Tableau 10, which a reader tells apart also in small plots.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

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
    FeatureGroup("danger", "danger D (0 clear .. 7 contact)", slice(0, 7), SENSOR_COLOURS),
    FeatureGroup("target", "target sector V (1..9)", slice(7, 8), (CYAN,)),
    FeatureGroup("flags", "flags I (target seen), U (wall)", slice(8, 16), (GREY, *SENSOR_COLOURS)),
)
"""phi(s) split by scale: the seven danger levels, the target's sector, and the eight 0/1 flags."""


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
