"""Would a person see data in every view of a recording's layout on open, and could they read it?
Read back from the file.

The viewer opens on the time panel's timeline at its start (the default layout pauses it there,
:mod:`nirl_mj.inspect.blueprint`). A plot or a log shows the rows of its entities on that
timeline; a 3-D or 2-D view shows the latest value at the cursor; a dataframe view the rows of its
query's own timeline (whatever the time panel shows). So a view shows data on open when one of the
entities its query selects holds a component it draws, and that component is static, or (plots,
logs) has rows on the timeline, or (3-D, 2-D, text) has a row at the timeline's start, or
(dataframes) has rows on the query's timeline. Everything is read from the ``.rrd`` (the stored
blueprint, not the code that made it), with ``rerun.chunk.RrdReader``.

The containers are read too (:class:`ContainerSpec`): :func:`tab_views` lists the views under each
top-level tab, and :func:`open_views` estimates the size in pixels of every view that shows on a
screen of a given size (only the open tab of each tab container), from the containers' shares and
the viewer's bars (measured in Rerun 0.41's web viewer).
"""

from __future__ import annotations

import os
import uuid
from collections import defaultdict
from dataclasses import dataclass

import rerun.chunk

DRAWN = {
    "TimeSeries": ("Scalars:scalars",),
    "TextLog": ("TextLog:text",),
    "3D": ("Boxes3D:half_sizes", "Cylinders3D:lengths", "LineStrips3D:strips", "Points3D:positions",
           "Arrows3D:vectors"),
    "2D": ("Image:buffer", "EncodedImage:blob"),
    "TextDocument": ("TextDocument:text",),
    "Dataframe": ("Scalars:scalars", "TextLog:text"),
}  # fmt: skip
"""Components that make something visible in each kind of view (Rerun's class identifiers)."""
_WHOLE_TIMELINE = ("TimeSeries", "TextLog")  # views that show every row, not the latest at the cursor


@dataclass(frozen=True)
class ViewSpec:
    """A view as stored in the blueprint: kind (``3D``, ``TimeSeries``, ...), name, origin,
    entity query (``$origin/**``, ``/training/cost``, ``- /a/b``), its blueprint path
    (``view/<uuid>``) and, for a dataframe view, its query's timeline."""

    kind: str
    name: str
    origin: str
    query: tuple[str, ...]
    id: str = ""
    timeline: str | None = None

    def included(self) -> list[str]:
        """The query's including expressions with ``$origin`` resolved (``/eval/nirl/000/**``)."""
        out = []
        for expression in self.query:
            expression = expression.strip()
            if not expression.startswith("-"):
                out.append(expression.lstrip("+ ").replace("$origin", self.origin.rstrip("/") or ""))
        return out

    def selects(self, entity: str) -> bool:
        """Whether the view's query includes ``entity`` (later expressions override earlier ones)."""
        chosen = False
        for expression in self.query:
            expression = expression.strip()
            include = not expression.startswith("-")
            pattern = expression.lstrip("+- ").replace("$origin", self.origin.rstrip("/") or "")
            if pattern.endswith("/**"):
                base = pattern[:-3] or "/"
                hit = entity == base or entity.startswith(base.rstrip("/") + "/")
            else:
                hit = entity == pattern
            if hit:
                chosen = include
        return chosen


@dataclass(frozen=True)
class ContainerSpec:
    """A container as stored in the blueprint: kind (``tabs``, ``horizontal``, ``vertical``,
    ``grid``), name, its children's blueprint paths (``view/<uuid>``, ``container/<uuid>``), the
    open tab's path and the shares of its columns and rows."""

    kind: str
    name: str
    children: tuple[str, ...]
    active: str | None = None
    column_shares: tuple[float, ...] = ()
    row_shares: tuple[float, ...] = ()


_KINDS = {1: "tabs", 2: "horizontal", 3: "vertical", 4: "grid"}


@dataclass(frozen=True)
class Layout:
    """A recording's stored layout: the time panel's timeline, the views, and the containers
    (by blueprint path) under ``root``."""

    timeline: str | None
    views: tuple[ViewSpec, ...]
    containers: dict[str, ContainerSpec] | None = None
    root: str | None = None

    def node(self, path: str) -> ViewSpec | ContainerSpec | None:
        """The view or container at the blueprint path ``path``."""
        if path.startswith("view/"):
            return next((v for v in self.views if v.id == path), None)
        return (self.containers or {}).get(path)


def _last(column: list) -> object:
    """The last non-null value of a blueprint column (a blueprint row may be re-sent)."""
    values = [v for v in column if v is not None]
    return values[-1] if values else None


def read_layout(path: str | os.PathLike) -> Layout:
    """The layout stored in the recording at ``path`` (its first blueprint)."""
    reader = rerun.chunk.RrdReader(path)
    fields: dict[str, dict[str, object]] = defaultdict(dict)
    for store in reader.blueprints()[:1]:
        for chunk in reader.stream(store=store):
            batch = chunk.to_record_batch()
            for name in batch.schema.names:
                if ":" in name:
                    value = _last(batch.column(name).to_pylist())
                    if value is not None:
                        fields[chunk.entity_path][name] = value
    views, containers = [], {}
    for entity, values in fields.items():
        if "ViewBlueprint:class_identifier" in values:
            query = fields.get(f"{entity}/ViewContents", {}).get("ViewContents:query") or ["$origin/**"]
            timeline = fields.get(f"{entity}/DataframeQuery", {}).get("DataframeQuery:timeline")
            views.append(ViewSpec(
                kind=str(_first(values["ViewBlueprint:class_identifier"])),
                name=str(_first(values.get("ViewBlueprint:display_name", [entity]))),
                origin=str(_first(values.get("ViewBlueprint:space_origin", ["/"]))),
                query=tuple(query),
                id=entity.lstrip("/"),
                timeline=str(_first(timeline)) if timeline else None,
            ))  # fmt: skip
        if "ContainerBlueprint:container_kind" in values:
            active = values.get("ContainerBlueprint:active_tab")
            containers[entity.lstrip("/")] = ContainerSpec(
                kind=_KINDS.get(int(_first(values["ContainerBlueprint:container_kind"])), "?"),
                name=str(_first(values.get("ContainerBlueprint:display_name", [""]))),
                children=tuple(values.get("ContainerBlueprint:contents") or ()),
                active=str(_first(active)) if active else None,
                column_shares=tuple(values.get("ContainerBlueprint:col_shares") or ()),
                row_shares=tuple(values.get("ContainerBlueprint:row_shares") or ()),
            )
    timeline = fields.get("/time_panel", {}).get("TimePanelBlueprint:timeline")
    root = fields.get("/viewport", {}).get("ViewportBlueprint:root_container")
    root_path = f"container/{uuid.UUID(bytes=bytes(_first(root)))}" if root else None
    return Layout(str(_first(timeline)) if timeline else None, tuple(views), containers, root_path)


def _first(value: object) -> object:
    return value[0] if isinstance(value, list) else value


@dataclass
class _Presence:
    """Where a component of an entity has rows: static, on which timelines, from which value on."""

    static: bool = False
    starts: dict[str, int] | None = None


def data_index(path: str | os.PathLike) -> dict[str, dict[str, _Presence]]:
    """Entity -> component -> where it has rows, over the recording's data (not its blueprint)."""
    reader = rerun.chunk.RrdReader(path)
    out: dict[str, dict[str, _Presence]] = defaultdict(dict)
    for store in reader.recordings():
        for chunk in reader.stream(store=store):
            batch = chunk.to_record_batch()
            for name in batch.schema.names:
                if ":" not in name:
                    continue
                presence = out[chunk.entity_path].setdefault(name, _Presence(starts={}))
                if chunk.is_static:
                    presence.static = True
                    continue
                for timeline in chunk.timeline_names:
                    start = _first_time(batch.column(timeline))
                    known = presence.starts.get(timeline)
                    presence.starts[timeline] = start if known is None else min(known, start)
    return out


def _first_time(column) -> int:
    """The smallest value of a time column as an integer (sequence, or nanoseconds)."""
    import pyarrow.compute as pc

    return int(pc.min(column.cast("int64")).as_py())


def views_without_data(path: str | os.PathLike) -> list[str]:
    """Names of the views of the stored layout that would show nothing when the recording is
    opened, sorted; empty when every view shows data. A layout without a time panel timeline counts
    every temporal row as unseen (the viewer would pick a timeline of its own)."""
    layout = read_layout(path)
    data = data_index(path)
    timeline = layout.timeline
    starts = [p.starts[timeline] for comps in data.values() for p in comps.values() if timeline in p.starts]
    opening = min(starts) if starts else None
    empty = []
    for view in layout.views:
        drawn = DRAWN.get(view.kind, ())
        seen = False
        for entity, components in data.items():
            if not view.selects(entity):
                continue
            for name in drawn:
                presence = components.get(name)
                if presence is None:
                    continue
                if view.kind == "Dataframe":  # its own timeline's rows, wherever the cursor is
                    seen |= (view.timeline or timeline) in presence.starts
                    continue
                start = presence.starts.get(timeline) if timeline else None
                if presence.static or (
                    start is not None and (view.kind in _WHOLE_TIMELINE or start <= opening)
                ):
                    seen = True
        if not seen:
            empty.append(f"{view.name} ({view.kind}, {view.origin})")
    return sorted(empty)


def tab_views(layout: Layout) -> dict[str, list[ViewSpec]]:
    """Top-level tab name -> every view under it (open or not), when the layout's root is a tab
    container; else ``{"": all views}``."""
    root = layout.node(layout.root) if layout.root else None
    if not isinstance(root, ContainerSpec) or root.kind != "tabs":
        return {"": list(layout.views)}
    out: dict[str, list[ViewSpec]] = {}
    for child in root.children:
        node = layout.node(child)
        name = node.name if node is not None else child
        out.setdefault(name, []).extend(_views_under(layout, child))
    return out


def _views_under(layout: Layout, path: str) -> list[ViewSpec]:
    node = layout.node(path)
    if isinstance(node, ViewSpec):
        return [node]
    if isinstance(node, ContainerSpec):
        return [v for child in node.children for v in _views_under(layout, child)]
    return []


TOP_BAR = 36  # pixels: the viewer's menu bar
TIME_BAR = 36  # the collapsed time panel
TAB_BAR = 28  # a tab container's row of tabs
TITLE_BAR = 26  # a view's title when it is not a tab (in a horizontal, vertical or grid container)
CHAR_WIDTH = 7.0  # a title's characters (Inter, 12 px: 5-7 px each; the wider bound)
TITLE_CHROME = 100  # a title bar's icon and its help, visibility and maximise buttons


@dataclass(frozen=True)
class OpenView:
    """A view that shows on a screen: its spec, its size in pixels (the drawing area, below its
    title) and the width its title has (the title bar, or its tab)."""

    view: ViewSpec
    width: float
    height: float
    title_room: float


def open_views(
    layout: Layout, width: int = 1600, height: int = 860, tab: str | None = None
) -> list[OpenView]:
    """The views that show when the recording opens in a browser window of ``width`` x ``height``
    pixels (the open tab of every tab container; with ``tab``, that top-level tab instead), with
    estimated sizes: the viewer's bars, tab rows and title bars taken off, the rest split by the
    containers' shares (equal if unset). A tab's title is never cut (a row of tabs scrolls)."""
    if layout.root is None:
        return []
    chosen = {}
    root = layout.node(layout.root)
    if tab is not None and isinstance(root, ContainerSpec):
        named = [c for c in root.children if getattr(layout.node(c), "name", None) == tab]
        if not named:
            raise KeyError(f"no top-level tab {tab!r}")
        chosen[layout.root] = named[0]
    out: list[OpenView] = []
    _place(layout, layout.root, float(width), float(height - TOP_BAR - TIME_BAR), False, out, chosen)
    return out


def _place(layout: Layout, path: str, w: float, h: float, in_tabs: bool, out: list, chosen: dict) -> None:
    node = layout.node(path)
    if isinstance(node, ViewSpec):
        if in_tabs:
            out.append(OpenView(node, w, h, float("inf")))
        else:
            out.append(OpenView(node, w, h - TITLE_BAR, w - TITLE_CHROME))
        return
    if not isinstance(node, ContainerSpec) or not node.children:
        return
    if node.kind == "tabs":
        active = chosen.get(path) or (node.active if node.active in node.children else node.children[0])
        _place(layout, active, w, h - TAB_BAR, True, out, chosen)
        return
    n = len(node.children)
    if node.kind == "grid":
        columns = max(1, round(n**0.5))
        rows = -(-n // columns)
        for child in node.children:
            _place(layout, child, w / columns, h / rows, False, out, chosen)
        return
    shares = node.column_shares if node.kind == "horizontal" else node.row_shares
    shares = tuple(shares) if len(shares) == n else (1.0,) * n
    total = float(sum(shares))
    for child, share in zip(node.children, shares, strict=True):
        if node.kind == "horizontal":
            _place(layout, child, w * share / total, h, False, out, chosen)
        else:
            _place(layout, child, w, h * share / total, False, out, chosen)
