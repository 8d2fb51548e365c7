"""The learner's config: the shared loop's, one per reward step, presets as data, flat on disk."""

import dataclasses
import json
from pathlib import Path

import pytest

from nirl_mj.learn.config import (
    PRESETS,
    STEP_CONFIGS,
    LearnerConfig,
    LoopConfig,
    MaxMarginConfig,
    RelativeEntropyConfig,
    _owners,
    checked_changes,
)

LEGACY = Path(__file__).parent / "data" / "legacy_run_aa67077" / "run.json"


def test_a_flat_record_written_before_the_split_loads_and_writes_back_the_same():
    flat = json.loads(LEGACY.read_text())["config"]
    config = LearnerConfig.from_dict(flat)
    assert flat["epsilon"] == float("-inf") and config.loop.epsilon is None  # no stop, in strict JSON
    assert {key: config.to_dict()[key] for key in flat} == {**flat, "epsilon": None}
    defaults = LearnerConfig().to_dict()  # settings added since take their defaults
    assert {k: v for k, v in config.to_dict().items() if k not in flat} == {
        k: v for k, v in defaults.items() if k not in flat
    }
    assert isinstance(config.step, MaxMarginConfig) and config.loop.method == "nirl"


def test_every_setting_has_one_owner_and_the_step_follows_the_method():
    names = [f for cls in (LoopConfig, *STEP_CONFIGS.values()) for f in cls.__dataclass_fields__]
    assert len(names) == len(set(names))

    @dataclasses.dataclass(frozen=True)
    class Clash:  # a new step's config reusing NIRL's field name: refused, both classes named
        mmp_steps: int = 1

    with pytest.raises(TypeError, match="'mmp_steps' is a field of both MaxMarginConfig and Clash"):
        _owners({**STEP_CONFIGS, "clash": Clash})
    config = LearnerConfig.preset("default", method="re", re_horizon=8, mmp_steps=3)
    assert isinstance(config.step, RelativeEntropyConfig) and config.step.re_horizon == 8
    assert config.steps["nirl"].mmp_steps == 3  # kept for the step that does not run
    assert config.replace(re_horizon=4).step.re_horizon == 4 and config.step.re_horizon == 8


def test_presets_are_data_applied_over_the_defaults():
    paper = LearnerConfig.preset("paper", episodes=3)
    assert paper.loop.variant == "paper" and paper.loop.episodes == 3
    for key, value in PRESETS["paper"].items():
        if key != "episodes":
            assert paper.to_dict()[key] == value
    assert LearnerConfig.preset().to_dict() == {**LearnerConfig().to_dict(), "variant": "default"}
    with pytest.raises(ValueError, match="unknown variant 'x'; accepted: default, paper"):
        LearnerConfig.preset("x")


def test_bad_settings_are_refused_with_the_field_and_what_it_accepts():
    with pytest.raises(ValueError, match="unknown learner setting.*nope"):
        LearnerConfig.from_dict({"nope": 1})
    with pytest.raises(ValueError, match="unknown method 'gail'; accepted: nirl, al, re, scirl"):
        LearnerConfig.preset(method="gail")
    assert checked_changes({"gamma": 1, "episodes": 3}, "--config") == {"gamma": 1.0, "episodes": 3}
    with pytest.raises(ValueError, match=r"--config.episodes = 'abc': expected a int"):
        checked_changes({"episodes": "abc"}, "--config")
    with pytest.raises(ValueError, match="unknown learner setting 'variant'"):
        checked_changes({"variant": "paper"}, "--config", exclude=("variant",))


def test_a_record_without_the_newer_fields_loads_as_it_was_trained():
    from nirl_mj.learn.config import RECORD_FALLBACKS

    flat = LearnerConfig.preset("default").to_dict()
    old = {k: v for k, v in flat.items() if k not in RECORD_FALLBACKS}
    loaded = LearnerConfig.from_record(old).to_dict()
    assert {k: loaded[k] for k in RECORD_FALLBACKS} == RECORD_FALLBACKS
    assert LearnerConfig.from_record(flat) == LearnerConfig.preset("default")  # a full record is itself
