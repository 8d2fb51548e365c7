"""The default layout, read back from the file: every view shows data on open, every episode has
its views, series are styled once with colours a reader tells apart; training has a timeline of its
own; every colour drawn is in its tab's legend; a tab shows only its own method's data, with its
real counts; what shows on a 1600 x 860 screen is large enough to read."""

import io
import re

import numpy as np
import pytest
import rerun as rr
import rerun.blueprint as rrb
from PIL import Image
from test_record import read_rrd, tiny_task

from nirl_mj.experts.policies import PolicyAgent, rule_policy
from nirl_mj.inspect.blueprint import ITERATION, TIMELINE, Scene, tile_offsets
from nirl_mj.inspect.layout_check import CHAR_WIDTH, open_views, read_layout, tab_views, views_without_data
from nirl_mj.inspect.recording import record_run
from nirl_mj.inspect.styles import FEATURE_GROUPS, TRAINING_PLOTS
from nirl_mj.learn.reward import RewardModel, reward_feature_names
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import make_env

GROUPS = {"demos": "demonstrations", "eval/nirl": "NIRL", "eval/rule_on_phi_s": "rule on phi(s)"}
"""The fixture's episode groups and the tabs that must name them."""


@pytest.fixture(scope="module")
def run_rrd(tmp_path_factory):
    """A run's recording: 3 demonstrations, 5 iterations of every training scalar, 2 policies of
    2 and 3 test episodes of which the first 2 are kept, r_theta (NIRL's) and the reward map."""
    task = tiny_task()
    env = make_env(task)
    episodes = [run_episode(env, PolicyAgent(rule_policy, "rule"), seed=s) for s in range(3)]
    reward = RewardModel(
        np.random.default_rng(0).normal(size=len(reward_feature_names("extended"))), "extended"
    )
    keys = [k for plot in TRAINING_PLOTS for k in plot.series]
    metrics = [{"episode": i, **{k: 0.1 * i + j for j, k in enumerate(keys)}} for i in range(5)]
    path = tmp_path_factory.mktemp("layout") / "run.rrd"
    record_run(path, episodes, metrics, {"NIRL": episodes[:2], "rule on phi(s)": episodes}, max_paths=2,
               reward=reward, map_arena=(task, episodes[0].arena_seed), focus="eval/nirl/001")  # fmt: skip
    return path


def test_every_view_shows_data_on_open(run_rrd):
    layout = read_layout(run_rrd)
    assert layout.timeline == TIMELINE
    kinds = {v.kind for v in layout.views}
    assert {"3D", "TimeSeries", "TextLog", "2D", "TextDocument", "Dataframe"} <= kinds
    assert views_without_data(run_rrd) == []


def test_every_episode_is_in_the_layout(run_rrd):
    layout = read_layout(run_rrd)
    origins = {v.origin for v in layout.views}
    learner = [f"/demos/{i:03d}" for i in range(3)] + ["/eval/nirl/000", "/eval/nirl/001"]
    other = [f"/eval/rule_on_phi_s/{i:03d}" for i in range(2)]
    for episode in learner + other:
        # its arena (from above and in 3-D), phi(s) by scale and its actions; r_theta of NIRL's
        # reward along the demonstrations and NIRL's own test episodes, not along the rule's
        mine = [v for v in layout.views if v.origin.startswith(episode)]
        assert sum(v.kind == "3D" for v in mine) == 2, episode
        assert {f"{episode}/features/{g.name}" for g in FEATURE_GROUPS} <= origins
        assert f"{episode}/action" in origins
        assert (f"{episode}/reward" in origins) == (episode in learner), episode
    assert not any(o.startswith("/eval/rule_on_phi_s/002") for o in origins)  # beyond max_paths
    chunks = read_rrd(run_rrd)
    assert not any(
        e.startswith("/eval/rule_on_phi_s/") and e.endswith(("/reward", "/reward_path")) for e in chunks
    )
    # A group's view shows all its episodes at once.
    assert {"/demos", "/eval/nirl", "/eval/rule_on_phi_s"} <= origins


def test_training_has_a_timeline_of_its_own(run_rrd):
    """Training scalars only on ``iteration``, nothing else there; the layout shows them where the
    time panel's timeline does not matter (a figure, a table on ``iteration``), never in a plot
    on an episode's ``step``."""
    chunks = read_rrd(run_rrd)
    for entity, parts in chunks.items():
        for chunk in parts:
            if chunk.is_static:
                continue
            if entity.startswith("/training/"):
                assert set(chunk.timeline_names) == {ITERATION}, entity
            else:
                assert ITERATION not in chunk.timeline_names, entity
                assert TIMELINE in chunk.timeline_names, entity
    assert {f"/training/{k}" for plot in TRAINING_PLOTS for k in plot.series} <= set(chunks)
    layout = read_layout(run_rrd)
    training = [v for v in layout.views if any(p.startswith("/training") for p in v.included())]
    assert sorted(v.kind for v in training) == ["2D", "Dataframe"]
    assert [v.timeline for v in training if v.kind == "Dataframe"] == [ITERATION]
    assert not any(v.kind == "TimeSeries" and v.selects(f"/training/{k}") for v in layout.views
                   for plot in TRAINING_PLOTS for k in plot.series)  # fmt: skip


def _rgb(packed: int) -> tuple[int, int, int]:
    return (packed >> 24) & 0xFF, (packed >> 16) & 0xFF, (packed >> 8) & 0xFF


def _colours(chunks: list, skip: tuple[str, ...] = ()) -> set[tuple[int, int, int]]:
    """Every colour that the components ``*:colors`` of ``chunks`` hold (SeriesLines included)."""
    out = set()
    for chunk in chunks:
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if name.endswith(":colors") and not name.startswith(skip):
                for row in batch.column(name).to_pylist():
                    out.update(_rgb(v) for v in np.ravel(row or []).tolist())
    return out


def _image_colours(chunks: list) -> set[tuple[int, int, int]]:
    """The colours of the pixels of an encoded image logged once."""
    blob = chunks[0].to_record_batch().column("EncodedImage:blob").to_pylist()[0][0]
    pixels = np.asarray(Image.open(io.BytesIO(bytes(blob))).convert("RGB")).reshape(-1, 3)
    return {tuple(int(v) for v in p) for p in np.unique(pixels, axis=0)}


def test_every_colour_is_in_its_tabs_legend(run_rrd):
    """Every colour an episode group's entities are drawn in (arena, path, end, label, robot,
    rays, plot lines) is a pixel colour of that group's legend image, and so are the ends of the
    r_theta scale along a path; every training curve's colour is in the training figure."""
    chunks = read_rrd(run_rrd)
    for group in GROUPS:
        entities = [e for e in chunks if e.startswith(f"/{group}/")]
        drawn = _colours([c for e in entities if not e.endswith("/reward_path") for c in chunks[e]])
        legend = _image_colours(chunks[f"/legend/{group}"])
        assert drawn, group
        assert drawn <= legend, (group, drawn - legend)
        for entity in (e for e in entities if e.endswith("/reward_path")):
            scale = _colours(chunks[entity])
            ends = {min(scale, key=lambda c: c[2] - c[0]), max(scale, key=lambda c: c[2] - c[0])}
            assert ends <= legend, entity
    series = _colours([c for e in chunks if e.startswith("/training/") and e != "/training/figure"
                       for c in chunks[e]])  # fmt: skip
    assert len(series) >= 8 and series <= _image_colours(chunks["/training/figure"])


def test_each_tab_shows_only_its_own_method(run_rrd):
    """Tabs along the top, named after their method; each tab's views select only that method's
    entities (its episodes and their legend, or its training, or its reward map)."""
    tabs = tab_views(read_layout(run_rrd))
    own = {title: (f"/{group}", f"/legend/{group}") for group, title in GROUPS.items()}
    own |= {"NIRL training": ("/training",), "NIRL reward map": ("/reward_map",)}
    assert list(tabs) == ["demonstrations", "NIRL training", "NIRL reward map", "NIRL", "rule on phi(s)"]
    for title, views in tabs.items():
        assert views, title
        for view in views:
            for path in view.included():
                assert any(path == p or path.startswith(p + "/") for p in own[title]), (
                    title,
                    view.name,
                    path,
                )


def test_labels_count_the_logged_episodes(run_rrd):
    """A group's view says how many episodes it shows of how many there are, as logged."""
    chunks = read_rrd(run_rrd)
    logged = {g: sum(bool(re.fullmatch(rf"/{g}/\d{{3}}/robot", e)) for e in chunks) for g in GROUPS}
    assert logged == {"demos": 3, "eval/nirl": 2, "eval/rule_on_phi_s": 2}
    names = {v.origin: v.name for v in read_layout(run_rrd).views if v.origin in {f"/{g}" for g in GROUPS}}
    assert names == {
        "/demos": f"all {logged['demos']} demonstrations, from above",
        "/eval/nirl": f"all {logged['eval/nirl']} test episodes, from above",
        "/eval/rule_on_phi_s": f"first {logged['eval/rule_on_phi_s']} of 3 test episodes, from above",
    }


@pytest.mark.parametrize(
    "tab", [None, "demonstrations", "NIRL training", "NIRL reward map", "rule on phi(s)"]
)
def test_a_screen_of_1600_by_860_is_readable(run_rrd, tab):
    """What shows on a 1600 x 860 screen (the opening tabs, or another top-level tab): a handful of
    views, each large enough to read, each title within its bar or tab."""
    layout = read_layout(run_rrd)
    shown = open_views(layout, 1600, 860, tab)
    assert 1 <= len(shown) <= 9
    if tab is None:  # it opens on the focused episode's group, with that episode's tab
        assert {v.view.origin for v in shown} >= {"/eval/nirl", "/eval/nirl/001"}
    for v in shown:
        least = {"TimeSeries": (400, 100), "TextLog": (400, 90), "TextDocument": (300, 200)}.get(
            v.view.kind, (450, 230)
        )
        assert v.width >= least[0] and v.height >= least[1], (v.view.name, v.width, v.height)
        assert len(v.view.name) * CHAR_WIDTH <= v.title_room, (v.view.name, v.title_room)


def test_the_check_sees_an_empty_view(tmp_path):
    """Scalars on ``iteration`` only, with the viewer opening on ``step``: the plot stays empty; so
    does a 3-D view whose data starts after the timeline's start, and a table on a timeline with
    no rows; a table on ``iteration`` shows them."""
    path = tmp_path / "bad.rrd"
    rec = rr.RecordingStream("nirl-mj-test")
    rec.save(path)
    for i in range(3):
        rec.reset_time()
        rec.set_time("iteration", sequence=i)
        rec.log("training/cost", rr.Scalars(0.6))
        rec.reset_time()
        rec.set_time("step", sequence=i)
        rec.log("shown/value", rr.Scalars(1.0))
        if i:
            rec.log("late/point", rr.Points3D([(0, 0, 0)]))
    table = rrb.archetypes.DataframeQuery
    rec.send_blueprint(rrb.Blueprint(
        rrb.Horizontal(rrb.TimeSeriesView(origin="/training", name="cost"),
                       rrb.TimeSeriesView(origin="/shown", name="shown"),
                       rrb.Spatial3DView(origin="/late", name="late"),
                       rrb.DataframeView(origin="/training", name="table", query=table(timeline="iteration")),
                       rrb.DataframeView(origin="/training", name="wrong", query=table(timeline="time"))),
        rrb.TimePanel(timeline="step"),
    ))  # fmt: skip
    rec.flush()
    rec.disconnect()
    assert views_without_data(path) == ["cost (TimeSeries, /training)", "late (3D, /late)",
                                        "wrong (Dataframe, /training)"]  # fmt: skip
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


def test_the_training_figure_marks_the_selected_iteration():
    """The recording's training figure draws the reported policy's iteration as a dashed grey line
    (the report's figures do the same): more than 40 pixels of that grey per plot beyond what the
    unmarked figure holds."""
    from nirl_mj.inspect.styles import TRAINING_KEYS, training_figure

    rows = [{"episode": i, **{k: float(np.sin(i + j)) for j, k in enumerate(TRAINING_KEYS)}}
            for i in range(20)]  # fmt: skip
    plain, marked = training_figure(rows, "t"), training_figure(rows, "t", selected=7)
    grey = [int(np.all(image == 89, axis=-1).sum()) for image in (plain, marked)]
    plots = sum(1 for plot in TRAINING_PLOTS if any(k in TRAINING_KEYS for k in plot.series))
    assert grey[1] - grey[0] > 40 * plots  # a dashed line of at least 40 pixels on every plot
