"""Task specifications: the only module that reads task files.

A task file is TOML with four tables, ``[arena]``, ``[robot]``, ``[sensing]`` and
``[control]``, plus optional ``[[arena.obstacles]]`` entries listing obstacles
explicitly. Every key is optional; an unknown key, a wrong type or a value out
of range raises :class:`SpecError` naming the file, the field and what is
accepted. Lengths are metres, speeds m/s, times seconds; angles are degrees in
the file and radians in the spec objects.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nirl_mj.data import dataset
from nirl_mj.data.assignments import parse_assignment
from nirl_mj.sim.drive import WHEEL_DISTANCE
from nirl_mj.sim.floorplans import FAMILIES, slot_counts

TASKS_DIR = Path(__file__).resolve().parents[2] / "tasks"

LIMITS: dict[str, float] = {
    "arena_side": 1000.0,  # metres per side of the arena
    "grid_cells": 16_000_000,  # occupancy-grid cells, (width / grid_resolution) * (height / grid_resolution)
    "obstacles": 1000,  # static + interior walls + moving + listed obstacles + a floor plan's most
    "max_tries": 10_000,  # layout attempts
    "decision_period": 10.0,  # seconds
    "commands_per_decision": 10_000,  # decision_period / command_period
    "physics_steps_per_decision": 100_000,  # decision_period / physics_timestep
    "step_budget": 100_000,  # decisions per episode (explicit or computed)
}
"""Bounds on counts and sizes, so that no task file can hang the program or exhaust memory
(docs/TASKS.md, "Limits"). Every one is far above what the paper's tasks use."""


class SpecError(ValueError):
    """A task file or spec value is invalid; the message names field and accepted values."""


def _check(low: float | None = None, high: float | None = None, *, open_low: bool = False):
    """Field metadata: numeric bounds (inclusive unless ``open_low``)."""
    return {"low": low, "high": high, "open_low": open_low}


def _choices(*values: str):
    return {"choices": values}


# Fields added after datasets and run records were written: left out of to_dict() at their
# default, so the task records of earlier settings (and the digest of tests/test_digest.py)
# stay byte-identical.
_OMIT_DEFAULT = {"omit_default": True}

DRIVES: tuple[str, ...] = ("tyre", "rollers", "planar")
"""The robot's drive fidelities (``nirl_mj.sim.robot``): tyre wheels, roller wheels, a planar base."""


@dataclass(frozen=True)
class ObstacleSpec:
    """One explicitly placed obstacle.

    ``size`` is (half-length x, half-length y) for a box or a wall segment and
    (radius,) for a cylinder, metres; ``yaw`` is radians counter-clockwise.
    """

    shape: str = field(default="box", metadata=_choices("box", "cylinder", "wall"))
    position: tuple[float, float] = (50.0, 50.0)
    size: tuple[float, ...] = (1.0, 1.0)
    yaw: float = field(default=0.0, metadata={"degrees": True})


@dataclass(frozen=True)
class ArenaSpec:
    """Procedural arena: border walls, a floor plan, static, wall-segment and moving obstacles."""

    size: tuple[float, float] = (100.0, 100.0)
    start: tuple[float, float] = (10.0, 10.0)
    target: tuple[float, float] = (90.0, 90.0)
    target_radius: float = field(default=1.0, metadata=_check(0.0, open_low=True))
    start_yaw: str | float = field(
        default="target", metadata={"keywords": ("target", "random"), "degrees": True}
    )
    clear_radius: float = field(default=4.0, metadata=_check(0.0))
    wall_height: float = field(default=1.0, metadata=_check(0.1))
    wall_thickness: float = field(default=0.5, metadata=_check(0.05))
    static_obstacles: int = field(default=20, metadata=_check(0))
    obstacle_size: tuple[float, float] = (1.0, 4.0)
    cylinder_fraction: float = field(default=0.5, metadata=_check(0.0, 1.0))
    obstacle_height: float = field(default=1.0, metadata=_check(0.1))
    interior_walls: int = field(default=0, metadata=_check(0))
    interior_wall_length: tuple[float, float] = (5.0, 20.0)
    moving_obstacles: int = field(default=0, metadata=_check(0))
    moving_speed: tuple[float, float] = (0.2, 1.0)
    moving_radius: tuple[float, float] = (0.5, 1.5)
    grid_resolution: float = field(default=0.25, metadata=_check(0.01, 5.0))
    path_margin: float = field(default=0.1, metadata=_check(0.0))
    max_tries: int = field(default=50, metadata=_check(1))
    obstacles: tuple[ObstacleSpec, ...] = ()
    floor_plan: str = field(default="random", metadata={**_choices(*FAMILIES), **_OMIT_DEFAULT})
    floor_plan_count: int = field(default=0, metadata={**_check(0), **_OMIT_DEFAULT})


@dataclass(frozen=True)
class RobotSpec:
    """Which physics model drives the robot and how its range sensors are sampled."""

    drive: str = field(default="tyre", metadata=_choices(*DRIVES))
    rays_per_sensor: int = field(default=5, metadata=_check(1, 64))


@dataclass(frozen=True)
class SensingSpec:
    """Range sensing and quantisation into danger levels.

    ``range`` is measured from the robot's outline (metres). Clearance below
    ``danger7_clearance`` is danger 7; clearances between it and ``range`` map
    linearly onto levels 6..1; nothing within range is 0.

    ``guide`` is what phi's sector V points at: ``"target"`` (the paper) or ``"memory"``: the
    target, except while the robot's memory of its own rays says it is stuck, when V holds the
    sector of that memory's escape waypoint (:class:`nirl_mj.sim.memory.RayMemory`, the sensor
    expert's escape). A departure from the paper, for floor plans with dead ends.
    """

    range: float = field(default=5.0, metadata=_check(0.0, open_low=True))
    danger7_clearance: float = field(default=1.0, metadata=_check(0.0, open_low=True))
    guide: str = field(default="target", metadata={**_choices("target", "memory"), **_OMIT_DEFAULT})


@dataclass(frozen=True)
class ControlSpec:
    """Timing and speed of the actions; ``actions`` says which kind (six discrete or a continuous
    twist)."""

    speed: float = field(default=2.0, metadata=_check(0.0, 5.0, open_low=True))
    decision_period: float = field(default=0.5, metadata=_check(0.0, open_low=True))
    command_period: float = field(default=0.01, metadata=_check(0.0, open_low=True))
    physics_timestep: str | float = field(
        default="auto", metadata={"keywords": ("auto",), **_check(0.0, 0.05, open_low=True)}
    )
    max_accel: float = field(default=4.0, metadata=_check(0.0, open_low=True))
    step_budget: int = field(default=0, metadata=_check(0))
    budget_factor: float = field(default=3.0, metadata=_check(1.0))
    # "continuous": a bounded (forward speed m/s, yaw rate rad/s) per decision (docs/TASKS.md)
    actions: str = field(default="discrete", metadata={**_choices("discrete", "continuous"), **_OMIT_DEFAULT})


@dataclass(frozen=True)
class TaskSpec:
    """A whole task: what ``make_env`` builds. ``name`` is informational."""

    name: str = "custom"
    description: str = ""
    arena: ArenaSpec = ArenaSpec()
    robot: RobotSpec = RobotSpec()
    sensing: SensingSpec = SensingSpec()
    control: ControlSpec = ControlSpec()

    @property
    def step_budget(self) -> int:
        """Decisions per episode before a timeout: explicit, or ``budget_factor`` times
        the straight start-to-target distance divided by the distance of one decision."""
        if self.control.step_budget:
            return self.control.step_budget
        dx = self.arena.target[0] - self.arena.start[0]
        dy = self.arena.target[1] - self.arena.start[1]
        per_step = self.control.speed * self.control.decision_period
        return math.ceil(self.control.budget_factor * math.hypot(dx, dy) / per_step)

    @property
    def physics_timestep(self) -> float:
        """MuJoCo's timestep in seconds: ``control.physics_timestep``, or for ``"auto"``
        0.01 with tyre or planar wheels up to 2 m/s, else 0.005. Measured: at 0.01 a
        tyre robot matches planar as closely as at 0.005 up to 2 m/s (end pose within
        0.3 %), but overshoots 60-degree turns at 3 m/s (78 degrees) and rollers slip
        (30-degree turns come out at 24)."""
        if self.control.physics_timestep != "auto":
            return float(self.control.physics_timestep)
        coarse = self.robot.drive in ("tyre", "planar") and self.control.speed <= 2.0
        return 0.01 if coarse else 0.005

    def to_dict(self) -> dict[str, Any]:
        """A TOML-compatible dict (angles in degrees) that :func:`from_dict` reads back."""
        return _to_plain(self)


def _to_plain(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj):
        out = {}
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            if f.metadata.get("omit_default") and value == f.default:
                continue
            if f.metadata.get("degrees") and isinstance(value, float):
                value = math.degrees(value)
            out[f.name] = _to_plain(value)
        return out
    if isinstance(obj, tuple):
        return [_to_plain(v) for v in obj]
    return obj


def _convert(cls: type, data: Any, where: str) -> Any:
    """Builds dataclass ``cls`` from a plain dict, validating every field."""
    if not isinstance(data, dict):
        raise SpecError(f"{where}: expected a table, got {type(data).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise SpecError(f"{where}: unknown key(s) {', '.join(unknown)}; accepted: {', '.join(fields)}")
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for name, value in data.items():
        kwargs[name] = _convert_field(fields[name], hints[name], value, f"{where}.{name}")
    obj = cls(**kwargs)
    _check_object(obj, where)
    return obj


def _convert_field(f: dataclasses.Field, hint: Any, value: Any, where: str) -> Any:
    meta = f.metadata
    if "keywords" in meta:
        keywords = meta["keywords"]
        if isinstance(value, str) and value in keywords:
            return value
        if isinstance(value, str) or isinstance(value, bool):
            number = "degrees" if meta.get("degrees") else "a number"
            raise SpecError(f"{where} = {value!r}: accepted: {', '.join(keywords)} or {number}")
        hint = float
    value = _convert_type(hint, value, where)
    if meta.get("degrees"):
        value = math.radians(value)
    if "choices" in meta and value not in meta["choices"]:
        raise SpecError(f"{where} = {value!r}: accepted: {', '.join(meta['choices'])}")
    low, high = meta.get("low"), meta.get("high")
    if low is not None and (value < low or (meta.get("open_low") and value == low)):
        op = ">" if meta.get("open_low") else ">="
        raise SpecError(f"{where} = {value!r}: must be {op} {low}")
    if high is not None and value > high:
        raise SpecError(f"{where} = {value!r}: must be <= {high}")
    return value


def _convert_type(hint: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if dataclasses.is_dataclass(hint):
        return _convert(hint, value, where)
    if origin is tuple:
        args = typing.get_args(hint)
        if not isinstance(value, list | tuple):
            shape = "a list" if args[-1] is Ellipsis else f"a list of {len(args)} numbers"
            raise SpecError(f"{where} = {value!r}: expected {shape}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert_type(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise SpecError(f"{where} = {value!r}: expected a list of {len(args)} numbers")
        return tuple(
            _convert_type(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True))
        )
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise SpecError(f"{where} = {value!r}: expected a number")
        if not math.isfinite(value):
            raise SpecError(f"{where} = {value!r}: expected a finite number")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SpecError(f"{where} = {value!r}: expected a whole number")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise SpecError(f"{where} = {value!r}: expected a string")
        return value
    raise SpecError(f"{where}: unsupported field type {hint}")


def _check_range_pair(pair: tuple[float, float], where: str, positive: bool = True) -> None:
    lo, hi = pair
    if lo > hi or (positive and lo <= 0):
        raise SpecError(f"{where} = {list(pair)}: expected [min, max] with 0 < min <= max")


def _check_object(obj: Any, where: str) -> None:
    """Cross-field checks that a single field's bounds cannot express."""
    if isinstance(obj, ObstacleSpec):
        n = 1 if obj.shape == "cylinder" else 2
        if len(obj.size) != n or any(s <= 0 for s in obj.size):
            what = "[radius]" if n == 1 else "[half_x, half_y]"
            is_default = obj.size == ObstacleSpec().size
            default = " (the default, a box's: give the cylinder's size)" if is_default else ""
            raise SpecError(f"{where}.size = {list(obj.size)}{default}: a {obj.shape} takes {what} > 0")
    elif isinstance(obj, ArenaSpec):
        _check_arena(obj, where)
        for name in ("obstacle_size", "interior_wall_length", "moving_radius"):
            _check_range_pair(getattr(obj, name), f"{where}.{name}")
        _check_range_pair(obj.moving_speed, f"{where}.moving_speed")
    elif isinstance(obj, SensingSpec):
        if obj.danger7_clearance >= obj.range:
            raise SpecError(
                f"{where}.danger7_clearance = {obj.danger7_clearance}: must be < range ({obj.range})"
            )
    elif isinstance(obj, TaskSpec):
        _check_timing(obj, where)


def _over(value: float, limit: str, where: str, what: str) -> None:
    if value > LIMITS[limit]:
        unit = f" {what}" if what else ""
        raise SpecError(f"{where} = {value:g}: at most {LIMITS[limit]:g}{unit} (docs/TASKS.md, Limits)")


def _check_arena(obj: ArenaSpec, where: str) -> None:
    w, h = obj.size
    if w <= 0 or h <= 0:
        raise SpecError(f"{where}.size = {list(obj.size)}: both sides must be > 0")
    _over(max(w, h), "arena_side", f"{where}.size", "metres per side")
    _over(
        (w / obj.grid_resolution) * (h / obj.grid_resolution),
        "grid_cells",
        f"{where}.size / grid_resolution (cells)",
        "occupancy-grid cells; raise grid_resolution",
    )
    count = obj.static_obstacles + obj.interior_walls + obj.moving_obstacles + len(obj.obstacles)
    count += sum(slot_counts(obj).values())
    _over(
        count,
        "obstacles",
        f"{where}: static_obstacles + interior_walls + moving_obstacles + obstacles + floor plan's most",
        "",
    )
    _over(obj.max_tries, "max_tries", f"{where}.max_tries", "attempts")
    for name in ("start", "target"):
        x, y = getattr(obj, name)
        if not (0 < x < w and 0 < y < h):
            raise SpecError(f"{where}.{name} = {[x, y]}: must lie inside the arena {list(obj.size)}")
    gap = math.dist(obj.start, obj.target)
    if gap <= obj.target_radius:
        raise SpecError(
            f"{where}.start = {list(obj.start)} is within target_radius ({obj.target_radius} m) of "
            f"target = {list(obj.target)}: an episode would start at its goal"
        )
    if obj.floor_plan == "random" and obj.floor_plan_count:
        raise SpecError(f"{where}.floor_plan_count = {obj.floor_plan_count}: counts the structures of a "
                        'floor plan; with floor_plan = "random" there are none: leave it out or name a '
                        "family")  # fmt: skip
    for i, obstacle in enumerate(obj.obstacles):
        x, y = obstacle.position
        if not (0 <= x <= w and 0 <= y <= h):
            raise SpecError(
                f"{where}.obstacles[{i}].position = {[x, y]}: must lie inside the arena {list(obj.size)}"
            )


def _check_timing(obj: TaskSpec, where: str) -> None:
    """Periods that nest, bounded work per decision, and turns that fit a decision."""
    control = obj.control
    _over(control.decision_period, "decision_period", f"{where}.control.decision_period", "seconds")
    _over(control.decision_period / control.command_period, "commands_per_decision",
          f"{where}.control.decision_period / command_period", "commands per decision")  # fmt: skip
    _over(control.decision_period / obj.physics_timestep, "physics_steps_per_decision",
          f"{where}.control.decision_period / physics_timestep", "physics steps per decision")  # fmt: skip
    for name, period, base_name, base in (
        ("decision_period", control.decision_period, "command_period", control.command_period),
        ("command_period", control.command_period, "physics_timestep", obj.physics_timestep),
    ):
        ratio = period / base
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise SpecError(
                f"{where}.control.{name} = {period}: must be a whole multiple of {base_name} ({base})"
            )
    # The sharpest action turns 60 degrees within one decision (a triangular yaw-rate profile at the
    # largest yaw acceleration max_accel allows: sim/drive.py action_profile).
    need = 4.0 * math.radians(60.0) / control.decision_period**2 * WHEEL_DISTANCE
    if control.max_accel < need:
        raise SpecError(
            f"{where}.control.max_accel = {control.max_accel:g}: a 60-degree turn in one decision "
            f"({control.decision_period:g} s) needs max_accel >= {need:.3f} m/s^2"
        )
    _over(obj.step_budget, "step_budget", f"{where}: step budget (control.step_budget, or computed from the "
          "start-target distance, speed, decision_period and budget_factor)", "decisions")  # fmt: skip


def from_dict(data: dict[str, Any], source: str = "<dict>") -> TaskSpec:
    """Validates a plain dict (as read from TOML) into a :class:`TaskSpec`."""
    return _convert(TaskSpec, data, source)


EXPERIMENT_KINDS = ("compare", "sweep", "suite")
"""The ``kind`` of an experiment file (``nirl_mj.experiments.definition.KINDS``); a task file has none."""


def load_task(task: str | Path | TaskSpec = "navigate") -> TaskSpec:
    """Returns the spec for a task name under ``tasks/``, a TOML path (a relative one not found
    from the working directory is looked up in the checkout: ``"tasks/dynamic.toml"`` works from
    anywhere), or a spec object."""
    if isinstance(task, TaskSpec):
        return task
    path = shipped_path(task)
    if path.suffix != ".toml":
        named = TASKS_DIR / f"{task}.toml"
        if not named.is_file():
            available = sorted(p.stem for p in TASKS_DIR.glob("*.toml") if "kind" not in _quiet_toml(p))
            raise SpecError(
                f"unknown task {str(task)!r}: give a path to a .toml file or one of: {', '.join(available)}"
            )
        path = named
    data = read_toml(path, "task file", SpecError)
    if "kind" in data and data["kind"] in EXPERIMENT_KINDS:  # an experiment file that names its task
        raise SpecError(f"{path} is an experiment (kind = {data['kind']!r}), not a task: run it with "
                        f"`nirl-mj {data['kind']} --task {path}`; its task is its `task = ...`")  # fmt: skip
    data.setdefault("name", path.stem)
    return from_dict(data, str(path))


def _quiet_toml(path: Path) -> dict[str, Any]:
    """A TOML file's contents, or {} if it cannot be read (for a list of names, never an error)."""
    try:
        return tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return {}


def shipped_path(path: str | Path) -> Path:
    """``path``, or for a relative ``.toml`` path not found from the working directory the checkout's
    file of that path: ``"tasks/dynamic.toml"`` works from any directory, as the docs write it."""
    path = Path(path)
    if path.suffix == ".toml" and not path.is_absolute() and not path.exists():
        shipped = TASKS_DIR.parent / path
        path = shipped if shipped.is_file() else path
    return path


def read_toml(path: Path, what: str, error: type[Exception]) -> dict[str, Any]:
    """The TOML file at ``path`` as a dict; ``error`` names the file if it is missing or invalid."""
    if path.is_dir():
        raise error(f"{what} {path} is a directory; give a .toml file")
    if not path.is_file():
        raise error(f"{what} not found: {path}")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise error(
            f"{path}: not a UTF-8 text file ({exc.reason} at byte {exc.start}); TOML files are UTF-8"
        ) from None
    except OSError as exc:
        raise error(f"{what} {path} cannot be read: {exc.strerror or exc}") from None


def replace(spec: TaskSpec, **sections: dict[str, Any]) -> TaskSpec:
    """Returns ``spec`` with fields of its sections overridden and validated, e.g.
    ``replace(spec, control={"speed": 3.0})``."""
    data = spec.to_dict()
    for section, values in sections.items():
        if section not in data or not isinstance(data[section], dict):
            raise SpecError(f"unknown section {section!r}; accepted: arena, robot, sensing, control")
        data[section] = {**data[section], **values}
    return from_dict(data, f"{spec.name} (overridden)")


def apply_overrides(spec: TaskSpec, assignments: list[str]) -> TaskSpec:
    """Applies command-line overrides ``SECTION.KEY=VALUE`` (VALUE in TOML syntax, e.g.
    ``control.speed=3`` or ``arena.start=[5, 5]``) and validates the result."""
    sections: dict[str, dict[str, Any]] = {}
    for text in assignments:
        key, parsed = parse_assignment(text) or ("", None)
        section, dot, field_name = key.partition(".")
        if not dot or not field_name:
            raise SpecError(f"override {text!r}: expected SECTION.KEY=VALUE, e.g. control.speed=3")
        sections.setdefault(section, {})[field_name] = parsed
    return replace(spec, **sections) if sections else spec


dataset.TASK_RULES.append(from_dict)  # a dataset's task records obey the task file's rules
