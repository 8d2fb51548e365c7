"""The layout a recording opens with (a Rerun blueprint): one screen at a time, the rest a click away.

Timelines. An episode's states and decisions are on :data:`TIMELINE` (``step``, the decision
index) and ``time`` (simulated seconds); the training scalars only on :data:`ITERATION`
(``iteration``, the learner's iteration), so that moving the cursor over an episode never moves
one over the training curves. Rerun shows one timeline at a time and a view cannot choose its
own (rerun-io/rerun#6828), so the layout shows training where the timeline does not matter: a
figure of the curves (a static image) and a table of their values per iteration (a dataframe
view, which queries ``iteration`` whatever the time panel shows). The time panel opens on
``step`` (``iteration`` in a recording of training only), paused at its start.

Tabs along the top, one per part of the recording (:func:`default_blueprint`), each named after
its method: ``demonstrations``; ``<method> training`` (the curves, the values) and ``<method>
reward map`` for the method whose reward was learned; a tab per tested method (``NIRL``,
``always forward``, ...) holding only its own test episodes. An episode group's tab
(:func:`group_tab`): left, all its recorded episodes at once from above (the paper's Fig. 5,
live: :func:`tile_offsets`), named with the real counts (``first 10 of 100 test episodes``), and
under them the colour legend of everything drawn in the tab (an image, ``legend/<group>``); right,
a tab per episode (:func:`episode_tab`): its arena from above or in 3-D, its actions, and phi(s)
by scale and r_theta in plots without in-plot legends (the legend image names their colours).

Cameras are placed before the viewer knows a view's size in pixels; they assume the views of a
1600 x 860 screen (width/height about 1.0 for an episode, 1.15 for a group) and so leave a margin
in wider ones.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import rerun.blueprint as rrb

from nirl_mj.data.features import ACTION_NAMES
from nirl_mj.inspect.styles import FEATURE_GROUPS

TIMELINE = "step"
"""The timeline the viewer opens on: an episode's decision index (``time`` runs beside it)."""
ITERATION = "iteration"
"""The training scalars' timeline: the learner's iteration (never on :data:`TIMELINE`)."""
TILE_GAP = 10.0  # m between neighbouring arenas of a group view
_EPISODE_ASPECT = 1.0  # width/height of an episode's 3-D views in the layout, roughly
_GROUP_ASPECT = 1.15  # of a group's view
_FOV = math.radians(55.0)  # Rerun's default vertical field of view of a 3-D view
_GROUP_TABS = 12  # groups beyond these are left out of the layout (still in the file)
OUTCOME_WORDS = {"target": "arrived", "collision": "collision", "timeout": "timeout",
                 "physics_error": "physics error"}  # fmt: skip
"""An episode's outcome as its labels say it."""


class Scene(NamedTuple):
    """An episode as the layout sees it: entity path (``demos/007``), arena size (w, h) metres,
    whether r_theta was logged along it, and its outcome."""

    path: str
    size: tuple[float, float]
    reward: bool
    outcome: str = "target"


class Group(NamedTuple):
    """A group of episodes (``demos``, ``eval/nirl``) as its tab names it: ``title`` (the tab:
    ``demonstrations``, ``NIRL``), ``noun`` (``demonstrations``, ``test episodes``) and ``total``,
    how many episodes there are of which the recording holds the first ones (None: all)."""

    path: str
    title: str
    noun: str = "episodes"
    total: int | None = None


def counted(group: Group, recorded: int) -> str:
    """``all 30 demonstrations`` or ``first 10 of 100 test episodes``: what a group's tab holds."""
    total = recorded if group.total is None else group.total
    if recorded >= total:
        return f"all {recorded} {group.noun}"
    return f"first {recorded} of {total} {group.noun}"


def groups_of(scenes: Sequence[Scene]) -> dict[str, list[Scene]]:
    """Scenes by group (``demos``, ``eval/nirl``: the path without its last part), in order."""
    out: dict[str, list[Scene]] = {}
    for scene in scenes:
        out.setdefault(scene.path.rsplit("/", 1)[0], []).append(scene)
    return out


def tile_offsets(scenes: Sequence[Scene]) -> dict[str, tuple[float, float]]:
    """Where each episode sits in its group's view (x, y metres): the group's arenas on a grid with
    about as many columns as the view holds best (sqrt(1.15 N)), rows going south so that the
    episodes read left to right, top to bottom."""
    out = {}
    for group in groups_of(scenes).values():
        columns = max(1, round(math.sqrt(_GROUP_ASPECT * len(group))))
        pitch = (max(s.size[0] for s in group) + TILE_GAP, max(s.size[1] for s in group) + TILE_GAP)
        for index, scene in enumerate(group):
            row, column = divmod(index, columns)
            out[scene.path] = (column * pitch[0], -row * pitch[1])
    return out


def _looking_down(low: tuple[float, float], high: tuple[float, float], aspect: float) -> rrb.EyeControls3D:
    """A camera straight above the rectangle ``low``-``high`` (metres), north up, far enough for
    the rectangle to fill a view of width/height ``aspect``."""
    cx, cy = (low[0] + high[0]) / 2, (low[1] + high[1]) / 2
    half = max(high[1] - low[1], (high[0] - low[0]) / aspect) / 2
    height = 1.08 * half / math.tan(_FOV / 2)
    return rrb.EyeControls3D(position=(cx, cy, height), look_target=(cx, cy, 0.0), eye_up=(0.0, 1.0, 0.0))


def _looking_north(size: tuple[float, float]) -> rrb.EyeControls3D:
    """A camera south of the arena, 45 degrees down onto its centre, the whole arena in sight in a
    view of the layout's width/height (the arena's diagonal is the widest part seen)."""
    w, h = size
    reach = 0.8 * math.hypot(w, h) / 2 / (_EPISODE_ASPECT * math.tan(_FOV / 2))
    angle = math.radians(45.0)
    return rrb.EyeControls3D(
        position=(w / 2, h / 2 - reach * math.cos(angle), reach * math.sin(angle)),
        look_target=(w / 2, h / 2, 0.0),
        eye_up=(0.0, 0.0, 1.0),
    )


def _plot(origin: str, name: str) -> rrb.TimeSeriesView:
    """A time series view without an in-plot legend (it would cover the curves): the tab's legend
    image names the colours, and hovering a curve names it."""
    return rrb.TimeSeriesView(origin=origin, name=name, plot_legend=rrb.PlotLegend(visible=False))


_ACTION_COLUMNS = rrb.TextLogColumns(timeline_columns=[TIMELINE], text_log_columns=["body"])
"""The actions' log: the decision and the action (not the entity path or a level)."""


def episode_tab(scene: Scene, method: str = "NIRL") -> rrb.Container:
    """One episode: its arena from above and in 3-D (tabs) above its actions, beside phi(s) by
    scale and r_theta of ``method``'s learned reward."""
    p = f"/{scene.path}"
    space = rrb.Vertical(
        rrb.Tabs(
            rrb.Spatial3DView(origin=p, name="from above",
                              eye_controls=_looking_down((0.0, 0.0), scene.size, _EPISODE_ASPECT)),
            rrb.Spatial3DView(origin=p, name="3-D, from the south", eye_controls=_looking_north(scene.size)),
        ),
        rrb.TextLogView(origin=f"{p}/action", name="actions", columns=_ACTION_COLUMNS),
        row_shares=[4, 1],
    )  # fmt: skip
    plots: list[Any] = [_plot(f"{p}/features/{g.name}", g.title) for g in FEATURE_GROUPS]
    shares = [3 if len(g.colours) > 1 else 2 for g in FEATURE_GROUPS]
    if scene.reward:
        plots.append(_plot(f"{p}/reward", f"r_theta ({method}'s learned reward)"))
        shares.append(2)
    plots_column = rrb.Vertical(*plots, row_shares=shares)
    return rrb.Horizontal(space, plots_column, column_shares=[5, 4], name=scene.path.rsplit("/", 1)[-1])


def legend_entity(group: str) -> str:
    """Where a group's colour legend (an image) is logged: ``legend/<group>``."""
    return f"legend/{group}"


_NOT_IN_GROUP_VIEW = ("end/label", "arena/start_target")
"""An episode's labelled entities that a group's view of many arenas leaves out."""


def group_tab(group: Group, scenes: Sequence[Scene], active: int = 0, method: str = "NIRL") -> rrb.Container:
    """A group's episodes: all at once from above, named with the counts, above the legend; next to
    them a tab per episode (``active`` open). The group's view leaves out each episode's labelled
    start and target and its end's label (:data:`_NOT_IN_GROUP_VIEW`): they would crowd the small
    arenas; the arena's own label names the outcome, the paths show where start and target are."""
    offsets = tile_offsets(scenes)
    low = (min(offsets[s.path][0] for s in scenes), min(offsets[s.path][1] for s in scenes))
    high = (max(offsets[s.path][0] + s.size[0] for s in scenes),
            max(offsets[s.path][1] + s.size[1] for s in scenes))  # fmt: skip
    overview = rrb.Spatial3DView(
        origin=f"/{group.path}",
        contents=["$origin/**", *[f"- /{s.path}/{part}" for s in scenes for part in _NOT_IN_GROUP_VIEW]],
        name=f"{counted(group, len(scenes))}, from above",
        eye_controls=_looking_down(low, high, _GROUP_ASPECT),
    )
    legend = rrb.Spatial2DView(origin=f"/{legend_entity(group.path)}", name="colours")
    left = rrb.Vertical(overview, legend, row_shares=[3, 2])
    episodes = rrb.Tabs(*[episode_tab(s, method) for s in scenes], active_tab=active)
    return rrb.Horizontal(left, episodes, column_shares=[1, 2], name=group.title)


TRAINING_FIGURE = "training/figure"
"""The training curves as one static image (``styles.training_figure``)."""


def training_tab(method: str = "NIRL") -> rrb.Container:
    """The training curves (a figure) and, a tab away, their values per iteration (a table on
    :data:`ITERATION`)."""
    return rrb.Tabs(
        rrb.Spatial2DView(origin=f"/{TRAINING_FIGURE}", name="curves"),
        rrb.DataframeView(
            origin="/training",
            contents=["$origin/**", f"- /{TRAINING_FIGURE}"],
            name="values per iteration",
            query=rrb.archetypes.DataframeQuery(timeline=ITERATION),
        ),
        name=f"{method} training",
    )


def reward_map_tab(method: str = "NIRL") -> rrb.Container:
    """The recovered reward map: all bearings and actions, one image per action (tabs), beside the
    explanation of what and which colours they show."""
    images = rrb.Tabs(
        rrb.Spatial2DView(origin="/reward_map/grid", name="all bearings and actions"),
        *[rrb.Spatial2DView(origin=f"/reward_map/{a}", name=a) for a in ACTION_NAMES],
    )
    about = rrb.TextDocumentView(origin="/reward_map/info", name="about the map")
    return rrb.Horizontal(images, about, column_shares=[3, 1], name=f"{method} reward map")


def default_blueprint(
    scenes: Sequence[Scene],
    training: bool = False,
    reward_map: bool = False,
    focus: str | None = None,
    groups: Mapping[str, Group] | None = None,
    method: str = "NIRL",
) -> rrb.Blueprint:
    """The layout a recording opens with (module docstring): a tab per episode group of ``scenes``
    (named by ``groups``, else by their paths), ``method``'s training and reward map tabs when
    ``training`` and ``reward_map``. The tabs of the episode ``focus`` (an entity path) are open,
    or with ``focus`` ``"training"`` or ``"reward_map"`` that tab; else those of the first group's
    first episode."""
    groups = dict(groups or {})
    by_group = list(groups_of(scenes).items())[:_GROUP_TABS]
    where = [(g, i) for g, (_, s) in enumerate(by_group) for i, scene in enumerate(s) if scene.path == focus]
    chosen, episode = where[0] if where else (0, 0)
    tabs: list[Any] = []
    active = 0
    extras = [
        (name, tab)
        for name, tab, wanted in (
            ("training", training_tab(method), training),
            ("reward_map", reward_map_tab(method), reward_map),
        )
        if wanted
    ]
    placed: dict[str, int] = {}

    def add_extras() -> None:
        for name, tab in extras:
            placed[name] = len(tabs)
            tabs.append(tab)
        extras.clear()

    for k, (path, members) in enumerate(by_group):
        if k == chosen:
            active = len(tabs)
        group = groups.get(path, Group(path, path))
        tabs.append(group_tab(group, members, episode if k == chosen else 0, method))
        if path == "demos":  # the learner's own tabs follow what it learned from
            add_extras()
    add_extras()
    active = placed.get(focus or "", active)
    root = rrb.Tabs(*tabs, active_tab=active) if tabs else rrb.Spatial3DView()
    return rrb.Blueprint(
        root,
        rrb.TimePanel(timeline=TIMELINE if scenes else ITERATION, play_state="paused", state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )
