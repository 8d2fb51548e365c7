"""Task files: defaults, round trip, and one clear error per kind of bad input."""

import math

import pytest

from nirl_mj.sim import spec
from nirl_mj.sim.spec import SpecError


def test_shipped_tasks_load():
    navigate = spec.load_task("navigate")
    assert navigate.arena.static_obstacles == 20
    assert navigate.control.speed == 2.0
    assert navigate.arena.moving_obstacles == 0
    dynamic = spec.load_task("dynamic")
    assert (dynamic.arena.static_obstacles, dynamic.arena.moving_obstacles) == (10, 10)


def test_name_path_and_object_are_equivalent():
    by_name = spec.load_task("navigate")
    by_path = spec.load_task(spec.TASKS_DIR / "navigate.toml")
    assert by_name == by_path
    assert spec.load_task(by_name) is by_name


def test_to_dict_round_trip_keeps_degrees_in_files():
    s = spec.from_dict(
        {
            "arena": {
                "start_yaw": 90,
                "obstacles": [{"shape": "box", "position": [3, 4], "size": [1, 2], "yaw": 30}],
            }
        }
    )
    assert s.arena.start_yaw == pytest.approx(math.pi / 2)
    assert s.arena.obstacles[0].yaw == pytest.approx(math.radians(30))
    plain = s.to_dict()
    assert plain["arena"]["obstacles"][0]["yaw"] == pytest.approx(30)
    assert spec.from_dict(plain) == s


def test_step_budget_is_three_straight_line_times_by_default():
    s = spec.load_task("navigate")
    # 113.1 m at 1 m per decision, times 3.
    assert s.step_budget == math.ceil(3 * math.hypot(80, 80) / 1.0)
    assert spec.replace(s, control={"step_budget": 7}).step_budget == 7


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"arena": {"static_obstacles": -1}}, "arena.static_obstacles = -1: must be >= 0"),
        ({"control": {"speed": 0}}, "control.speed = 0.0: must be > 0.0"),
        ({"control": {"speed": -2}}, "control.speed = -2.0: must be > 0.0"),
        ({"robot": {"drive": "wheels"}}, "accepted: tyre, rollers, planar"),
        ({"arena": {"colour": "red"}}, "unknown key(s) colour; accepted: size, start"),
        ({"sensors": {}}, "unknown key(s) sensors; accepted: name, description, arena"),
        ({"arena": {"static_obstacles": 2.5}}, "expected a whole number"),
        ({"arena": {"start": [10]}}, "expected a list of 2 numbers"),
        ({"arena": {"start": [150, 10]}}, "must lie inside the arena"),
        ({"arena": {"start_yaw": "north"}}, "accepted: target, random or degrees"),
        ({"arena": {"obstacles": [{"shape": "cylinder", "size": [1, 2]}]}}, "a cylinder takes [radius] > 0"),
        ({"arena": {"obstacles": [{"shape": "cylinder"}]}}, "the default, a box's: give the cylinder's size"),
        ({"arena": {"obstacles": [{"shape": "cone"}]}}, "accepted: box, cylinder, wall"),
        ({"arena": {"obstacle_size": [3, 1]}}, "expected [min, max] with 0 < min <= max"),
        ({"sensing": {"range": 1.0, "danger7_clearance": 2.0}}, "must be < range"),
        ({"control": {"decision_period": 0.505}}, "whole multiple of command_period"),
        ({"arena": {"interior_wall_length": -5.0}}, "interior_wall_length = -5.0: expected a list of 2"),
        ({"arena": {"floor_plan_count": 3}}, 'with floor_plan = "random" there are none'),
    ],
)
def test_bad_values_name_the_field_and_what_is_accepted(data, message):
    with pytest.raises(SpecError) as err:
        spec.from_dict(data, "t.toml")
    assert message in str(err.value)
    assert str(err.value).startswith("t.toml")


def test_a_kind_that_is_no_experiments_is_an_unknown_key_of_a_task(tmp_path):
    path = tmp_path / "t.toml"
    path.write_text('kind = "task"\n')  # not "run it with nirl-mj task --task", which does not exist
    with pytest.raises(SpecError, match=r"unknown key\(s\) kind; accepted: name"):
        spec.load_task(path)


def test_unknown_task_lists_the_shipped_ones(tmp_path):
    with pytest.raises(SpecError, match="navigate"):
        spec.load_task("no-such-task")
    with pytest.raises(SpecError, match="not found"):
        spec.load_task(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[arena\n")
    with pytest.raises(SpecError, match="not valid TOML"):
        spec.load_task(bad)


def test_every_spec_field_is_documented_in_docs_tasks_md():
    import dataclasses
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "TASKS.md").read_text()
    for cls in (
        spec.TaskSpec,
        spec.ArenaSpec,
        spec.ObstacleSpec,
        spec.RobotSpec,
        spec.SensingSpec,
        spec.ControlSpec,
    ):
        for f in dataclasses.fields(cls):
            if dataclasses.is_dataclass(f.type) or f.name in ("arena", "robot", "sensing", "control"):
                assert f"`[{f.name}]`" in text, f"section [{f.name}] is not documented in docs/TASKS.md"
                continue
            assert f"| `{f.name}` |" in text, f"{cls.__name__}.{f.name} is not documented in docs/TASKS.md"


def test_command_line_overrides():
    s = spec.apply_overrides(
        spec.load_task("navigate"), ["control.speed=3", "robot.drive=planar", "arena.start=[5, 5]"]
    )
    assert (s.control.speed, s.robot.drive, s.arena.start) == (3.0, "planar", (5.0, 5.0))
    with pytest.raises(SpecError, match="expected SECTION.KEY=VALUE"):
        spec.apply_overrides(s, ["speed=3"])
    with pytest.raises(SpecError, match="unknown key"):
        spec.apply_overrides(s, ["control.sped=3"])
    with pytest.raises(SpecError, match="must be > 0.0"):
        spec.apply_overrides(s, ["control.speed=0"])
