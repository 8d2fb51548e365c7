"""The layout a recording opens with (a Rerun blueprint), chosen so that every view shows data
without a click.

Rerun shows one timeline at a time and the blueprint cannot give a view a timeline of its own, so
everything the layout shows lives on one timeline, :data:`TIMELINE` (``step``): an episode's states
and decisions at their decision index, the training scalars at their iteration (they are on
``episode`` too). The time panel opens on it, paused at its start, rather than following to the
end of the longest episode.

Left, a tab per episode group (``demos``, ``eval/<policy>``): every episode of the group at once
from above (the paper's Fig. 5, live: :func:`tile_offsets` places the arenas side by side), and a
tab per episode with its arena in 3-D and from above, phi(s) in three plots by scale, r_theta and
the actions, so the plots follow the chosen episode. Right, the training curves in a grid (a plot
per scale, :data:`nirl_mj.inspect.styles.TRAINING_PLOTS`) above the reward map.

Cameras are placed before the viewer knows a view's size in pixels; they assume the narrowest
views of a 16:9 screen (width/height about 0.75 for an episode, 0.55 for a group) and so leave a
margin in wider ones.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import rerun.blueprint as rrb

from nirl_mj.data.features import ACTION_NAMES
from nirl_mj.inspect.styles import FEATURE_GROUPS, TRAINING_PLOTS

TIMELINE = "step"
"""The timeline the viewer opens on; every view of the default layout has data there."""
TILE_GAP = 10.0  # m between neighbouring arenas of a group view
_EPISODE_ASPECT = 0.75  # width/height of an episode's 3-D views in the layout, roughly
_GROUP_ASPECT = 0.55  # of a group's view
_FOV = math.radians(55.0)  # Rerun's default vertical field of view of a 3-D view
_GROUP_TABS = 12  # groups beyond these are left out of the layout (still in the file)


class Scene(NamedTuple):
    """An episode as the layout sees it: entity path (``demos/007``), arena size (w, h) metres,
    and whether r_theta was logged along it."""

    path: str
    size: tuple[float, float]
    reward: bool


def groups_of(scenes: Sequence[Scene]) -> dict[str, list[Scene]]:
    """Scenes by group (``demos``, ``eval/nirl``: the path without its last part), in order."""
    out: dict[str, list[Scene]] = {}
    for scene in scenes:
        out.setdefault(scene.path.rsplit("/", 1)[0], []).append(scene)
    return out


def tile_offsets(scenes: Sequence[Scene]) -> dict[str, tuple[float, float]]:
    """Where each episode sits in its group's view (x, y metres): the group's arenas on a grid with
    about as many columns as a tall view holds best (sqrt(0.55 N)), rows going south so that the
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


def _plot(
    origin: str, name: str, contents: Sequence[str] | None = None, legend: bool = True
) -> rrb.TimeSeriesView:
    """A time series view; the legend sits top left, where curves that settle leave room."""
    return rrb.TimeSeriesView(
        origin=origin,
        name=name,
        contents=list(contents) if contents is not None else "$origin/**",
        plot_legend=rrb.PlotLegend(corner="LeftTop", visible=legend),
    )


def episode_tab(scene: Scene) -> rrb.Container:
    """One episode: its arena in 3-D and from above, beside phi(s) by scale, r_theta and the actions."""
    p = f"/{scene.path}"
    space = rrb.Vertical(
        rrb.Spatial3DView(origin=p, name=f"{scene.path} 3-D", eye_controls=_looking_north(scene.size)),
        rrb.Spatial3DView(origin=p, name=f"{scene.path} from above",
                          eye_controls=_looking_down((0.0, 0.0), scene.size, _EPISODE_ASPECT)),
        rrb.TextLogView(origin=f"{p}/action", name="actions"),
        row_shares=[4, 4, 2],
    )  # fmt: skip
    plots: list[Any] = [
        _plot(f"{p}/features/{g.name}", g.title, legend=len(g.colours) > 1) for g in FEATURE_GROUPS
    ]
    shares = [len(g.colours) if len(g.colours) > 1 else 2 for g in FEATURE_GROUPS]  # room for the legends
    if scene.reward:
        plots.append(_plot(f"{p}/reward", "r_theta(s_t, a_t)", legend=False))
        shares.append(2)
    return rrb.Horizontal(space, rrb.Vertical(*plots, row_shares=shares), name=scene.path.rsplit("/", 1)[-1])


def group_tab(group: str, scenes: Sequence[Scene], active: int = 0) -> rrb.Container:
    """A group's episodes: all at once from above, next to a tab per episode (``active`` open)."""
    offsets = tile_offsets(scenes)
    low = (min(offsets[s.path][0] for s in scenes), min(offsets[s.path][1] for s in scenes))
    high = (max(offsets[s.path][0] + s.size[0] for s in scenes),
            max(offsets[s.path][1] + s.size[1] for s in scenes))  # fmt: skip
    overview = rrb.Spatial3DView(origin=f"/{group}", name=f"{group}: all {len(scenes)} episodes",
                                 eye_controls=_looking_down(low, high, _GROUP_ASPECT))  # fmt: skip
    episodes = rrb.Tabs(*[episode_tab(s) for s in scenes], active_tab=active)
    return rrb.Horizontal(overview, episodes, column_shares=[2, 3], name=group)


def training_grid(keys: Sequence[str]) -> rrb.Container | None:
    """The training curves of ``keys`` (logged keys), a plot per scale, two plots per row."""
    plots = []
    for plot in TRAINING_PLOTS:
        present = [k for k in plot.series if k in keys]
        if present:
            contents = [f"/training/{k}" for k in present]
            plots.append(_plot("/training", plot.title, contents, legend=len(present) > 1))
    return rrb.Grid(*plots, grid_columns=2, name="training") if plots else None


def reward_map_tabs() -> rrb.Container:
    """The recovered reward map: all bearings and actions, one image per action, the explanation."""
    return rrb.Tabs(
        rrb.Spatial2DView(origin="/reward_map/grid", name="reward map"),
        *[rrb.Spatial2DView(origin=f"/reward_map/{a}", name=f"r_theta {a}") for a in ACTION_NAMES],
        rrb.TextDocumentView(origin="/reward_map/info", name="about the map"),
    )


def default_blueprint(
    scenes: Sequence[Scene],
    training_keys: Sequence[str] = (),
    reward_map: bool = False,
    focus: str | None = None,
) -> rrb.Blueprint:
    """The layout a recording opens with (module docstring): the episodes of ``scenes`` by group,
    the training curves of ``training_keys`` and, if logged, the reward map. The tabs of the
    episode ``focus`` (an entity path) are open, else those of the first group's first episode."""
    columns: list[Any] = []
    groups = list(groups_of(scenes).items())[:_GROUP_TABS]
    if groups:
        where = [
            (g, i) for g, (_, s) in enumerate(groups) for i, scene in enumerate(s) if scene.path == focus
        ]
        group, episode = where[0] if where else (0, 0)
        tabs = [group_tab(g, s, episode if k == group else 0) for k, (g, s) in enumerate(groups)]
        columns.append(rrb.Tabs(*tabs, active_tab=group))
    right = [c for c in (training_grid(training_keys), reward_map_tabs() if reward_map else None) if c]
    if right:
        columns.append(rrb.Vertical(*right, row_shares=[3, 2][: len(right)]))
    root = rrb.Horizontal(*columns, column_shares=[3, 2][: len(columns)]) if columns else rrb.Spatial3DView()
    return rrb.Blueprint(
        root,
        rrb.TimePanel(timeline=TIMELINE, play_state="paused", state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )
