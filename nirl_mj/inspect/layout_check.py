"""Would a person see data in every view of a recording's layout on open? Read back from the file.

The viewer opens on the time panel's timeline at its start (the default layout pauses it there,
:mod:`nirl_mj.inspect.blueprint`). A plot or a log shows the rows of its entities on that
timeline; a 3-D or 2-D view shows the latest value at the cursor. So a view shows data on open
when one of the entities its query selects holds a component it draws, and that component is
static, or (plots, logs) has rows on the timeline, or (3-D, 2-D, text) has a row at the
timeline's start. Everything is read from the ``.rrd`` (the stored blueprint, not the code that
made it), with ``rerun.chunk.RrdReader``.
"""

from __future__ import annotations

import os
from collections import defaultdict
from dataclasses import dataclass

import rerun.chunk

DRAWN = {
    "TimeSeries": ("Scalars:scalars",),
    "TextLog": ("TextLog:text",),
    "3D": ("Boxes3D:half_sizes", "Cylinders3D:lengths", "LineStrips3D:strips", "Points3D:positions",
           "Arrows3D:vectors"),
    "2D": ("Image:buffer",),
    "TextDocument": ("TextDocument:text",),
}  # fmt: skip
"""Components that make something visible in each kind of view (Rerun's class identifiers)."""
_WHOLE_TIMELINE = ("TimeSeries", "TextLog")  # views that show every row, not the latest at the cursor


@dataclass(frozen=True)
class ViewSpec:
    """A view as stored in the blueprint: kind (``3D``, ``TimeSeries``, ...), name, origin and
    entity query (``$origin/**``, ``/training/cost``, ``- /a/b``)."""

    kind: str
    name: str
    origin: str
    query: tuple[str, ...]

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
class Layout:
    """A recording's stored layout: the time panel's timeline and the views."""

    timeline: str | None
    views: tuple[ViewSpec, ...]


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
    views = []
    for entity, values in fields.items():
        if "ViewBlueprint:class_identifier" in values:
            query = fields.get(f"{entity}/ViewContents", {}).get("ViewContents:query") or ["$origin/**"]
            views.append(ViewSpec(
                kind=str(_first(values["ViewBlueprint:class_identifier"])),
                name=str(_first(values.get("ViewBlueprint:display_name", [entity]))),
                origin=str(_first(values.get("ViewBlueprint:space_origin", ["/"]))),
                query=tuple(query),
            ))  # fmt: skip
    timeline = fields.get("/time_panel", {}).get("TimePanelBlueprint:timeline")
    return Layout(str(_first(timeline)) if timeline else None, tuple(views))


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
                start = presence.starts.get(timeline) if timeline else None
                if presence.static or (
                    start is not None and (view.kind in _WHOLE_TIMELINE or start <= opening)
                ):
                    seen = True
        if not seen:
            empty.append(f"{view.name} ({view.kind}, {view.origin})")
    return sorted(empty)
