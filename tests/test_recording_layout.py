"""The default layout, read back from the file: every view shows data on open, every episode has
its views, series are styled once with colours a reader tells apart."""

import numpy as np
import pytest
import rerun as rr
import rerun.blueprint as rrb
from test_record import read_rrd, tiny_task

from nirl_mj.experts.policies import PolicyAgent, rule_policy
from nirl_mj.inspect.blueprint import TIMELINE, Scene, tile_offsets
from nirl_mj.inspect.layout_check import read_layout, views_without_data
from nirl_mj.inspect.recording import record_run
from nirl_mj.inspect.styles import FEATURE_GROUPS, TRAINING_PLOTS
from nirl_mj.learn.reward import RewardModel, reward_feature_names
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import make_env


@pytest.fixture(scope="module")
def run_rrd(tmp_path_factory):
    """A run's recording: 3 demonstrations, 5 iterations of every training scalar, 2 policies of
    2 and 3 test episodes, r_theta and the reward map."""
    task = tiny_task()
    env = make_env(task)
    episodes = [run_episode(env, PolicyAgent(rule_policy, "rule"), seed=s) for s in range(3)]
    reward = RewardModel(
        np.random.default_rng(0).normal(size=len(reward_feature_names("extended"))), "extended"
    )
    keys = [k for plot in TRAINING_PLOTS for k in plot.series]
    metrics = [{"episode": i, **{k: 0.1 * i + j for j, k in enumerate(keys)}} for i in range(5)]
    path = tmp_path_factory.mktemp("layout") / "run.rrd"
    record_run(path, episodes, metrics, {"NIRL": episodes[:2], "rule on phi(s)": episodes}, reward=reward,
               map_arena=(task, episodes[0].arena_seed), focus="eval/nirl/001")  # fmt: skip
    return path


def test_every_view_shows_data_on_open(run_rrd):
    layout = read_layout(run_rrd)
    assert layout.timeline == TIMELINE
    kinds = {v.kind for v in layout.views}
    assert {"3D", "TimeSeries", "TextLog", "2D", "TextDocument"} <= kinds
    assert views_without_data(run_rrd) == []


def test_every_episode_is_in_the_layout(run_rrd):
    layout = read_layout(run_rrd)
    origins = {v.origin for v in layout.views}
    episodes = [f"/demos/{i:03d}" for i in range(3)] + ["/eval/nirl/000", "/eval/nirl/001"]
    episodes += [f"/eval/rule_on_phi_s/{i:03d}" for i in range(3)]
    for episode in episodes:
        # its arena (3-D and from above), phi(s) by scale, r_theta and its actions
        mine = [v for v in layout.views if v.origin.startswith(episode)]
        assert sum(v.kind == "3D" for v in mine) == 2, episode
        assert {f"{episode}/features/{g.name}" for g in FEATURE_GROUPS} | {f"{episode}/reward"} <= origins
        assert f"{episode}/action" in origins
    # A group's view shows all its episodes at once.
    assert {"/demos", "/eval/nirl", "/eval/rule_on_phi_s"} <= origins


def test_training_series_are_styled_once_in_distinct_colours(run_rrd):
    chunks = read_rrd(run_rrd)
    for plot in TRAINING_PLOTS:
        colours = []
        for key, colour in plot.series.items():
            static = [c for c in chunks[f"/training/{key}"] if c.is_static]
            assert len(static) == 1, key
            batch = static[0].to_record_batch()
            assert batch.column("SeriesLines:names").to_pylist() == [[key]]
            packed = batch.column("SeriesLines:colors").to_pylist()[0][0]
            assert packed == (colour[0] << 24) | (colour[1] << 16) | (colour[2] << 8) | 0xFF
            colours.append(colour)
        assert len(set(colours)) == len(colours), plot.title
    for group in FEATURE_GROUPS:
        assert len(set(group.colours)) == len(group.colours) == group.index.stop - group.index.start


def test_the_check_sees_an_empty_view(tmp_path):
    """Scalars on ``episode`` only, with the viewer opening on ``step``: the plot stays empty; so does
    a 3-D view whose data starts after the timeline's start."""
    path = tmp_path / "bad.rrd"
    rec = rr.RecordingStream("nirl-mj-test")
    rec.save(path)
    for i in range(3):
        rec.reset_time()
        rec.set_time("episode", sequence=i)
        rec.log("training/cost", rr.Scalars(0.6))
        rec.set_time("step", sequence=i)
        rec.log("shown/value", rr.Scalars(1.0))
        if i:
            rec.log("late/point", rr.Points3D([(0, 0, 0)]))
    rec.send_blueprint(rrb.Blueprint(
        rrb.Horizontal(rrb.TimeSeriesView(origin="/training", name="cost"),
                       rrb.TimeSeriesView(origin="/shown", name="shown"),
                       rrb.Spatial3DView(origin="/late", name="late")),
        rrb.TimePanel(timeline="step"),
    ))  # fmt: skip
    rec.flush()
    rec.disconnect()
    assert views_without_data(path) == ["cost (TimeSeries, /training)", "late (3D, /late)"]
    assert read_layout(path).timeline == "step"


def test_tiles_do_not_overlap_and_read_left_to_right():
    scenes = [Scene(f"demos/{i:03d}", (100.0, 100.0), False) for i in range(30)]
    scenes += [Scene(f"eval/nirl/{i:03d}", (30.0, 30.0), True) for i in range(10)]
    offsets = tile_offsets(scenes)
    for group, size in (("demos", 100.0), ("eval/nirl", 30.0)):
        mine = [offsets[s.path] for s in scenes if s.path.startswith(group)]
        xy = np.array(mine)
        gaps = np.abs(xy[:, None, :] - xy[None, :, :]).max(axis=2) + np.eye(len(mine)) * 1e9
        assert gaps.min() >= size  # squares of side ``size`` never overlap
        assert mine[0] == (0.0, 0.0) and mine[1][0] > 0 and mine[-1][1] < 0  # east, then rows southwards
