"""Property tests (hypothesis): any generated input gives a valid result or one clean error.

Task files, ``--set`` and ``--config`` values, and datasets. Every property runs a fixed
(derandomised) set of examples, so CI sees the same cases on every run.
"""

from __future__ import annotations

import dataclasses
import io
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from nirl_mj.data.dataset import DatasetError, load_dataset, save_dataset
from nirl_mj.data.trajectory import Trajectory
from nirl_mj.experiments.demos import ExpertConfig, collect
from nirl_mj.learn.config import LearnerConfig, checked_changes
from nirl_mj.sim import spec

PROPERTY = settings(derandomize=True, deadline=None, max_examples=150,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip

SECTIONS = {
    "arena": spec.ArenaSpec,
    "robot": spec.RobotSpec,
    "sensing": spec.SensingSpec,
    "control": spec.ControlSpec,
}
numbers = st.one_of(
    st.integers(-(10**12), 10**12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, 1, 2, 0.5, 5.0, 20, 100.0, 1e-9, 1e9]),
)
values = st.recursive(
    st.one_of(
        numbers, st.booleans(), st.text(max_size=8), st.sampled_from(["auto", "target", "planar", "box"])
    ),
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=3)
    ),
    max_leaves=8,
)


def near(default):
    """Values like a field's default (scaled numbers, lists of such): the cases validation must weigh."""
    if isinstance(default, bool) or not isinstance(default, int | float | tuple):
        return values
    if isinstance(default, tuple):
        return st.lists(st.floats(-10.0, 200.0), min_size=max(len(default) - 1, 0), max_size=len(default) + 1)
    scaled = st.floats(-1.0, 3.0).map(lambda f: type(default)(f * (default or 1)))
    return st.one_of(scaled, st.just(default))


@st.composite
def task_dicts(draw):
    """A task table: real sections and keys mostly (so validation goes deep), some junk."""
    data = {}
    for section in draw(st.lists(st.sampled_from([*SECTIONS, "junk"]), max_size=4, unique=True)):
        fields = (
            {f.name: f.default for f in dataclasses.fields(SECTIONS[section])} if section in SECTIONS else {}
        )
        key = st.one_of(st.sampled_from(sorted(fields) or ["x"]), st.text(max_size=5))
        keys = draw(st.lists(key, max_size=4, unique=True))
        data[section] = {k: draw(st.one_of(values, near(fields[k])) if k in fields else values) for k in keys}
    if draw(st.booleans()):
        data[draw(st.sampled_from(["name", "description", "other"]))] = draw(values)
    return data


@PROPERTY
@given(task_dicts())
def test_any_task_table_is_a_valid_spec_or_one_spec_error(data):
    try:
        result = spec.from_dict(data, "generated")
    except spec.SpecError as exc:
        assert str(exc).startswith("generated")
        event("refused")
        return
    event("valid")
    assert isinstance(result, spec.TaskSpec)
    assert result.step_budget <= spec.LIMITS["step_budget"]
    assert spec.from_dict(result.to_dict(), "again") == result  # what validates round-trips


SET_KEYS = [f"{s}.{f.name}" for s, cls in SECTIONS.items() for f in dataclasses.fields(cls)]
value_texts = st.one_of(
    st.text(max_size=20),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**10), 10**10).map(str),
    st.lists(st.floats(-5.0, 200.0), max_size=3).map(repr),
    st.sampled_from(["planar", '"tyre"', "auto", "[5, 5]", "{shape='box'}", "true", "1e9", "-0"]),
)


@PROPERTY
@given(st.one_of(st.sampled_from(SET_KEYS), st.text(max_size=12)), value_texts)
def test_any_set_override_is_applied_or_refused_with_a_spec_error(key, value):
    base = spec.load_task("navigate")
    try:
        result = spec.apply_overrides(base, [f"{key}={value}"])
    except spec.SpecError:
        event("refused")
        return
    event("valid")
    assert isinstance(result, spec.TaskSpec)


config_keys = st.one_of(st.sampled_from(sorted(LearnerConfig.field_defaults())), st.text(max_size=10))


config_values = st.one_of(values, *(near(v) for v in LearnerConfig.field_defaults().values()))


@PROPERTY
@given(st.dictionaries(config_keys, config_values, max_size=4), st.sampled_from(["default", "paper"]))
def test_any_config_override_gives_a_learner_config_or_a_value_error(changes, variant):
    try:
        config = LearnerConfig.preset(variant, **checked_changes(changes, "--config", exclude=("variant",)))
    except ValueError:  # SpecError is one too
        event("refused")
        return
    event("valid")
    assert LearnerConfig.from_dict(config.to_dict()) == config


# -- datasets -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def dataset_bytes(tmp_path_factory) -> bytes:
    task = spec.replace(spec.load_task("navigate"), robot={"drive": "planar"}, control={"step_budget": 6})
    path = tmp_path_factory.mktemp("d") / "d.npz"
    save_dataset(path, collect(task, ExpertConfig("rule"), episodes=2, seed=0))
    return path.read_bytes()


def _arrays(blob: bytes) -> dict[str, np.ndarray]:
    with np.load(io.BytesIO(blob), allow_pickle=False) as data:
        return {k: data[k] for k in data.files}


def _loads(tmp_path, blob: bytes) -> list[Trajectory] | None:
    """The dataset in ``blob``, or None after a DatasetError (anything else fails the test)."""
    path = tmp_path / "x.npz"
    path.write_bytes(blob)
    try:
        result = load_dataset(path)
    except DatasetError as exc:
        assert str(path) in str(exc)
        event("refused")
        return None
    event("loaded")
    assert result and all(isinstance(t, Trajectory) for t in result)
    return result


@PROPERTY
@given(st.data())
def test_any_byte_corruption_of_a_dataset_loads_or_gives_a_dataset_error(tmp_path, dataset_bytes, data):
    blob = bytearray(dataset_bytes)
    for _ in range(data.draw(st.integers(1, 8))):
        blob[data.draw(st.integers(0, len(blob) - 1))] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(blob)))
    _loads(tmp_path, bytes(blob[:cut] if data.draw(st.booleans()) else blob))


array_dtypes = st.sampled_from([np.int8, np.int32, np.int64, np.float32, np.float64, np.bool_, np.uint8])


@PROPERTY
@given(st.data())
def test_any_replaced_or_removed_array_loads_or_gives_a_dataset_error(tmp_path, dataset_bytes, data):
    arrays = _arrays(dataset_bytes)
    key = data.draw(st.sampled_from(sorted(arrays)))
    action = data.draw(st.sampled_from(["remove", "replace", "reshape", "values"]))
    if action == "remove":
        del arrays[key]
    elif action == "replace":
        shape = data.draw(st.lists(st.integers(0, 5), max_size=3))
        arrays[key] = np.zeros(shape, dtype=data.draw(array_dtypes))
    elif action == "reshape":
        arrays[key] = arrays[key].reshape(-1)[: data.draw(st.integers(0, arrays[key].size))]
    elif arrays[key].size and arrays[key].dtype.kind in "iuf":
        flat = arrays[key].reshape(-1).copy()
        flat[data.draw(st.integers(0, flat.size - 1))] = data.draw(
            st.sampled_from([-1, 0, 1, 7, 8, 127, 2**31 - 1, np.nan, np.inf])
            if flat.dtype.kind == "f"
            else st.sampled_from([-1, 0, 1, 5, 6, 7, 8, 127])  # fmt: skip
        )
        arrays[key] = flat.reshape(arrays[key].shape)
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as archive:
        for name, array in arrays.items():
            with archive.open(f"{name}.npy", "w") as f:
                np.lib.format.write_array(f, np.asarray(array), allow_pickle=False)
    _loads(tmp_path, out.getvalue())
