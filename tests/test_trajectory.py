"""Trajectory, recorder and the dataset file: round trip, corruption, atomic writes."""

import os
from pathlib import Path

import numpy as np
import pytest
from helpers import run_dataset_doc

from nirl_mj import make_env
from nirl_mj.data.dataset import DatasetError, load_dataset, save_dataset
from nirl_mj.data.features import FEATURE_NAMES
from nirl_mj.data.outcomes import summarise
from nirl_mj.data.trajectory import Trajectory, TrajectoryRecorder, stack_pairs
from nirl_mj.sim import spec

ROOT = Path(__file__).resolve().parents[1]


def make_traj(t: int, rng: np.random.Generator, **meta) -> Trajectory:
    """A valid random trajectory of ``t`` decisions."""
    features = np.zeros((t + 1, 16), np.float32)
    features[:, 0:7] = rng.integers(0, 8, (t + 1, 7))
    features[:, 7] = rng.integers(1, 10, t + 1)
    features[:, 8] = rng.integers(0, 2, t + 1)
    features[:, 9:16] = rng.integers(0, 2, (t + 1, 7))
    defaults = dict(
        arena_seed=int(rng.integers(0, 2**32)),
        task=spec.load_task("navigate").to_dict(),
        speed=2.0,
        outcome="target",
        demonstrator="planner",
    )
    return Trajectory(
        features=features,
        actions=rng.integers(0, 6, t).astype(np.int8),
        ranges=rng.uniform(0.0, 5.0, (t + 1, 9)).astype(np.float32),
        poses=rng.normal(size=(t + 1, 3)),
        times=np.arange(t + 1) * 0.5,
        **{**defaults, **meta},
    )


@pytest.fixture
def trajs():
    rng = np.random.default_rng(0)
    other_task = spec.replace(spec.load_task("navigate"), control={"speed": 1.0}).to_dict()
    return [
        make_traj(7, rng, arena_seed=2**32 - 1),
        make_traj(0, rng, outcome="collision", demonstrator="human", arena_seed=0),
        make_traj(12, rng, outcome="timeout", task=other_task, speed=1.0, demonstrator="noisy-planner"),
        make_traj(3, rng, outcome="physics_error", demonstrator="sensor"),
    ]


def assert_same(a: Trajectory, b: Trajectory) -> None:
    for name in ("features", "actions", "ranges", "poses", "times"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype, name
        np.testing.assert_array_equal(x, y, err_msg=name)
    for name in ("arena_seed", "task", "speed", "outcome", "demonstrator"):
        assert getattr(a, name) == getattr(b, name), name
        assert type(getattr(a, name)) is type(getattr(b, name)), name


# -- Trajectory ----------------------------------------------------------------------


def test_trajectory_helpers(trajs):
    t = trajs[0]
    assert len(t) == 7
    phi, a = t.pairs()
    assert phi.shape == (7, 16) and a.shape == (7,)
    np.testing.assert_array_equal(phi, t.features[:-1])
    assert t.success and not trajs[1].success
    assert len(trajs[1]) == 0 and trajs[1].pairs()[0].shape == (0, 16)
    phi_all, a_all = stack_pairs(trajs)
    assert phi_all.shape == (22, 16) and a_all.shape == (22,) and a_all.dtype == np.int8
    with pytest.raises(ValueError):
        t.features[0, 0] = 1.0  # read-only


@pytest.mark.parametrize(
    "field, value",
    [
        ("features", np.zeros((5, 16))),
        ("features", np.zeros((4, 15))),
        ("ranges", np.zeros((4, 8))),
        ("poses", np.zeros((4, 2))),
        ("times", np.zeros(3)),
        ("actions", np.zeros((3, 1))),
        # discrete actions are checked as given, before the cast to int8 would wrap or cut them
        ("actions", np.array([0, 256, 1])),
        ("actions", np.array([0, 2.7, 1])),
        ("actions", np.array([0, np.nan, 1])),
        ("actions", np.array([True, False, True])),
    ],
)
def test_trajectory_shape_errors_name_the_field(field, value):
    good = dict(
        features=np.zeros((4, 16)),
        actions=np.zeros(3, np.int8),
        ranges=np.zeros((4, 9)),
        poses=np.zeros((4, 3)),
        times=np.zeros(4),
        arena_seed=1,
        task={},
        speed=2.0,
        outcome="target",
        demonstrator="planner",
    )
    Trajectory(**good)
    with pytest.raises(ValueError, match=rf"Trajectory\.{field}"):
        Trajectory(**{**good, field: value})


def test_trajectory_metadata_errors(trajs):
    import dataclasses

    with pytest.raises(ValueError, match="outcome"):
        dataclasses.replace(trajs[0], outcome="arrived")
    with pytest.raises(ValueError, match="actions"):
        dataclasses.replace(trajs[0], actions=np.full(7, 6))
    with pytest.raises(ValueError, match="speed"):
        dataclasses.replace(trajs[0], speed=0.0)
    with pytest.raises(ValueError, match="arena_seed"):
        dataclasses.replace(trajs[0], arena_seed=-1)


# -- round trip ----------------------------------------------------------------------


def test_round_trip_is_exact(tmp_path, trajs):
    path = save_dataset(tmp_path / "demos.npz", trajs)
    loaded = load_dataset(path)
    assert len(loaded) == len(trajs)
    for a, b in zip(trajs, loaded, strict=True):
        assert_same(a, b)
    with np.load(path, allow_pickle=False) as z:
        assert len(z["tasks"]) == 2  # distinct task specs stored once
        assert z["arena_seed"].dtype == np.int64


def test_round_trip_64_bit_seed(tmp_path, trajs):
    import dataclasses

    big = dataclasses.replace(trajs[0], arena_seed=2**64 - 1)
    path = save_dataset(tmp_path / "d.npz", [big, trajs[1]])
    loaded = load_dataset(path)
    assert loaded[0].arena_seed == 2**64 - 1 and loaded[1].arena_seed == 0


def test_path_is_used_as_given(tmp_path, trajs):
    save_dataset(tmp_path / "demos.dat", trajs)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demos.dat"]
    assert len(load_dataset(tmp_path / "demos.dat")) == 4


def test_documented_numpy_reader_works(tmp_path, trajs, capsys):
    namespace = run_dataset_doc(save_dataset(tmp_path / "demos.npz", trajs))
    np.testing.assert_array_equal(namespace["phi"], trajs[0].features)
    np.testing.assert_array_equal(namespace["t"].features, trajs[0].features)  # the quick start's
    np.testing.assert_array_equal(namespace["actions"], trajs[0].actions)
    np.testing.assert_array_equal(namespace["pairs_phi"], stack_pairs(trajs)[0])
    assert "target planner 2.0" in capsys.readouterr().out


# -- saving --------------------------------------------------------------------------


def test_empty_list_refused(tmp_path):
    with pytest.raises(ValueError, match="empty"):
        save_dataset(tmp_path / "d.npz", [])
    assert not (tmp_path / "d.npz").exists()


def test_overwrite_refused_without_flag(tmp_path, trajs):
    path = save_dataset(tmp_path / "d.npz", trajs)
    before = path.read_bytes()
    with pytest.raises(FileExistsError, match="overwrite=True"):
        save_dataset(path, trajs[:1])
    assert path.read_bytes() == before
    save_dataset(path, trajs[:1], overwrite=True)
    assert len(load_dataset(path)) == 1
    assert os.listdir(tmp_path) == ["d.npz"]


@pytest.mark.parametrize("existing", [False, True])
def test_interrupted_write_leaves_no_partial_file(tmp_path, trajs, monkeypatch, existing):
    path = tmp_path / "d.npz"
    if existing:
        save_dataset(path, trajs[:1])
    before = path.read_bytes() if existing else None

    def interrupted(file, **arrays):
        file.write(b"PK\x03\x04 partial zip data")
        raise KeyboardInterrupt("simulated interruption")

    monkeypatch.setattr(np, "savez_compressed", interrupted)
    with pytest.raises(KeyboardInterrupt):
        save_dataset(path, trajs, overwrite=True)
    monkeypatch.undo()
    assert os.listdir(tmp_path) == (["d.npz"] if existing else [])
    if existing:
        assert path.read_bytes() == before
        assert len(load_dataset(path)) == 1


def test_an_interrupted_atomic_write_keeps_the_old_file_and_leaves_nothing_beside_it(tmp_path, monkeypatch):
    """The writers of run files (checkpoints, policies) fill a temporary file, not the target."""
    from nirl_mj.data.atomic import write_npz

    path = tmp_path / "a.npz"
    write_npz(path, {"x": np.arange(3)})
    before = path.read_bytes()

    def interrupted(file, **arrays):
        file.write(b"PK\x03\x04 partial zip data")
        raise KeyboardInterrupt("simulated interruption")

    monkeypatch.setattr(np, "savez", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_npz(path, {"x": np.arange(5)})
    assert os.listdir(tmp_path) == ["a.npz"] and path.read_bytes() == before


def test_an_atomic_write_flushes_its_temporary_file_before_the_rename_and_the_directory_after(
    tmp_path, monkeypatch
):
    """Else a crash soon after the rename may leave the new name on an empty or partial file."""
    from nirl_mj.data import atomic

    events = []
    fsync, replace = os.fsync, os.replace

    def recorded_fsync(fd):
        events.append(("fsync", os.readlink(f"/proc/self/fd/{fd}")))
        return fsync(fd)

    def recorded_replace(src, dst):
        events.append(("replace", str(src), str(dst)))
        return replace(src, dst)

    monkeypatch.setattr(atomic.os, "fsync", recorded_fsync)
    monkeypatch.setattr(atomic.os, "replace", recorded_replace)
    folder = tmp_path.resolve()  # as /proc names the descriptors' files
    atomic.write_text(folder / "a.txt", "x")
    monkeypatch.undo()
    assert [e[0] for e in events] == ["fsync", "replace", "fsync"], events
    tmp = Path(events[1][1])
    assert tmp.parent == folder and tmp.name.startswith(".a.txt.") and not tmp.exists()
    target = str(folder / "a.txt")
    assert events == [("fsync", str(tmp)), ("replace", str(tmp), target), ("fsync", str(folder))]


def test_atomic_writes_get_the_permissions_open_would_give(tmp_path, trajs):
    from nirl_mj.data.atomic import write_text

    mask = os.umask(0o022)
    try:
        (tmp_path / "plain.txt").write_text("x")
        write_text(tmp_path / "atomic.txt", "x")
        save_dataset(tmp_path / "d.npz", trajs[:1])
    finally:
        os.umask(mask)
    expected = (tmp_path / "plain.txt").stat().st_mode & 0o777
    assert expected == 0o644
    assert (tmp_path / "atomic.txt").stat().st_mode & 0o777 == expected  # not mkstemp's private 0600
    assert (tmp_path / "d.npz").stat().st_mode & 0o777 == expected


def test_save_refuses_what_load_would_reject(tmp_path, trajs):
    import dataclasses

    feats = trajs[0].features.copy()
    feats[0, 0] = 8  # danger 8
    with pytest.raises(DatasetError, match="refusing to save.*danger"):
        save_dataset(tmp_path / "d.npz", [dataclasses.replace(trajs[0], features=feats)])
    assert not (tmp_path / "d.npz").exists()


# -- corruption ----------------------------------------------------------------------


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _set(key, fn):
    def mutate(a):
        a[key] = fn(a[key].copy())
        return a

    return mutate


def _drop(key):
    def mutate(a):
        del a[key]
        return a

    return mutate


def _features_at(col, value):
    def fn(f):
        f[3, col] = value
        return f

    return _set("features", fn)


def _empty(a):
    a["lengths"] = a["lengths"][:0]
    for key in ("features", "ranges", "poses"):
        a[key] = a[key][:0]
    for key in ("actions", "times", "arena_seed", "speed", "outcome", "demonstrator", "task_index"):
        a[key] = a[key][:0]
    return a


def _set_index(key, index, value):
    def fn(arr):
        arr[index] = value
        return arr

    return _set(key, fn)


CORRUPTIONS = {
    "version 99": (
        _set("version", lambda v: np.array(99)),
        r"unsupported dataset version 99.*version\(s\) 1",
    ),
    "other layout": (
        _set("feature_names", lambda n: n[::-1].copy()),
        r"feature layout .* differs",
    ),
    "danger 8": (_features_at(2, 8.0), r"danger level D out of range.*D_S3.*8\.0"),
    "danger 2.5": (_features_at(2, 2.5), r"danger level D out of range"),
    "V 0": (_features_at(7, 0.0), r"target sector V out of range"),
    "I 2": (_features_at(8, 2.0), r"target-detected flag I out of range"),
    "U -1": (_features_at(12, -1.0), r"wall flag U out of range"),
    "NaN": (_set_index("poses", (4, 1), np.nan), r"non-finite value \(NaN or inf\) in 'poses' at row 4"),
    "inf": (_set_index("ranges", (0, 1), np.inf), r"non-finite value \(NaN or inf\) in 'ranges'"),
    "action 6": (_set_index("actions", 2, 6), r"action out of range: actions\[2\] = 6"),
    "lengths vs rows": (_set_index("lengths", 0, 8), r"inconsistent lengths: 'actions' has 22 rows but sum"),
    "lengths vs states": (
        _set("features", lambda f: f[:-1].copy()),
        r"inconsistent lengths: 'features' has 25 rows",
    ),
    "per-trajectory count": (_set("speed", lambda s: s[:-1].copy()), r"inconsistent lengths: 'speed' has 3"),
    "missing key": (_drop("ranges"), r"missing key\(s\) ranges"),
    "wrong dtype": (_set("actions", lambda a: a.astype(np.int64)), r"wrong dtype for 'actions': int64"),
    "wrong shape": (_set("features", lambda f: f[:, :15].copy()), r"wrong shape for 'features'"),
    "unknown outcome": (_set("outcome", lambda o: np.array(["target", "won", "x", "y"])), r"unknown outcome"),
    "bad task index": (_set_index("task_index", 1, 5), r"task_index out of range"),
    "bad task json": (
        _set("tasks", lambda t: np.array(["{not json", t[1]])),
        r"tasks\[0\] is not valid JSON",
    ),
    "times backwards": (_set_index("times", 2, -1.0), r"'times' decrease"),
    "times not from 0": (_set_index("times", 0, 0.5), r"'times' of trajectory 0 start at 0\.5 s"),
    "speed 0": (_set_index("speed", 0, 0.0), r"speed out of range"),
    "empty": (_empty, r"empty dataset"),
    "no format": (_drop("format"), r"not an nirl-mj dataset: no 'format'"),
    "other format": (_set("format", lambda f: np.array("something-else")), r"format is 'something-else'"),
}


@pytest.mark.parametrize("name", list(CORRUPTIONS))
def test_corruption_is_reported(tmp_path, trajs, name):
    good = save_dataset(tmp_path / "good.npz", trajs)
    mutate, pattern = CORRUPTIONS[name]
    bad = tmp_path / "bad.npz"
    with open(bad, "wb") as f:
        np.savez_compressed(f, **mutate(_arrays(good)))
    with pytest.raises(DatasetError, match=pattern) as info:
        load_dataset(bad)
    assert str(bad) in str(info.value)


def test_each_corruption_has_its_own_message(tmp_path, trajs):
    good = save_dataset(tmp_path / "good.npz", trajs)
    messages = {}
    for name, (mutate, _) in CORRUPTIONS.items():
        bad = tmp_path / "bad.npz"
        with open(bad, "wb") as f:
            np.savez_compressed(f, **mutate(_arrays(good)))
        with pytest.raises(DatasetError) as info:
            load_dataset(bad)
        messages[name] = str(info.value)
    # Same-kind corruptions share a message prefix; different kinds never a message.
    assert len(set(messages.values())) == len(messages)


def test_missing_file(tmp_path):
    with pytest.raises(DatasetError, match="no such file"):
        load_dataset(tmp_path / "nope.npz")


def test_truncated_file(tmp_path, trajs):
    good = save_dataset(tmp_path / "good.npz", trajs)
    data = good.read_bytes()
    for cut in (len(data) // 2, len(data) - 10, 10, 0):
        bad = tmp_path / "bad.npz"
        bad.write_bytes(data[:cut])
        with pytest.raises(DatasetError, match="not an NPZ dataset file.*truncated"):
            load_dataset(bad)


def test_not_a_zip(tmp_path):
    bad = tmp_path / "notes.npz"
    bad.write_text("just some text\n" * 10)
    with pytest.raises(DatasetError, match="not an NPZ dataset file"):
        load_dataset(bad)
    np.save(tmp_path / "one.npy", np.arange(3))
    with pytest.raises(DatasetError, match="single .npy array"):
        load_dataset(tmp_path / "one.npy")


def test_foreign_npz(tmp_path):
    bad = tmp_path / "foreign.npz"
    np.savez(bad, weights=np.arange(3.0))
    with pytest.raises(DatasetError, match=r"not an nirl-mj dataset: no 'format' entry.*weights"):
        load_dataset(bad)


def test_pickled_entry_refused(tmp_path, trajs):
    good = save_dataset(tmp_path / "good.npz", trajs)
    a = _arrays(good)
    a["tasks"] = np.array([{"a": 1}, {"b": 2}], dtype=object)
    bad = tmp_path / "bad.npz"
    np.savez(bad, **a)
    with pytest.raises(DatasetError, match="pickled"):
        load_dataset(bad)


def test_feature_names_stored(tmp_path, trajs):
    path = save_dataset(tmp_path / "d.npz", trajs)
    with np.load(path, allow_pickle=False) as z:
        assert tuple(z["feature_names"].tolist()) == FEATURE_NAMES
        assert str(z["format"]) == "nirl-mj-demos" and int(z["version"]) == 1


# -- summary -------------------------------------------------------------------------


def test_summarise(trajs):
    s = summarise(trajs)
    assert s["episodes"] == 4
    assert s["success_rate"] == s["collision_rate"] == s["timeout_rate"] == s["physics_error_rate"] == 0.25
    assert (s["mean_steps"], s["min_steps"], s["max_steps"]) == (5.5, 0, 12)
    counts = np.bincount(stack_pairs(trajs)[1], minlength=6)
    assert list(s["action_counts"].values()) == counts.tolist()
    assert sum(s["action_fractions"].values()) == pytest.approx(1.0)
    assert s["demonstrators"] == {"human": 1, "noisy-planner": 1, "planner": 1, "sensor": 1}
    assert s["speeds"] == {1.0: 1, 2.0: 3}
    assert s["tasks"] == 2
    assert summarise([])["episodes"] == 0


# -- recorder ------------------------------------------------------------------------


def test_recorder_on_a_real_rollout(tmp_path):
    task = spec.replace(spec.load_task("navigate"), control={"step_budget": 5}, robot={"drive": "planar"})
    env = make_env(task, seed=3)
    rec = TrajectoryRecorder(task.control.decision_period)
    ts = env.reset()
    rec.start(ts.observation)
    actions = [0, 1, 3, 0, 2]
    k = 0
    while not ts.last():
        ts = env.step(actions[k])
        rec.step(actions[k], ts.observation)
        k += 1
    from nirl_mj.sim.task import Outcome

    traj = rec.finish(Outcome(int(ts.observation["outcome"][0])), 3, task, task.control.speed, "planner")
    t = len(traj)
    assert t == k == int(ts.observation["steps"][0])
    assert traj.features.shape == (t + 1, 16) and traj.features.dtype == np.float32
    assert traj.actions.shape == (t,) and traj.actions.dtype == np.int8
    assert traj.ranges.shape == (t + 1, 9) and traj.ranges.dtype == np.float32
    assert traj.poses.shape == (t + 1, 3) and traj.poses.dtype == np.float64
    np.testing.assert_allclose(traj.times, np.arange(t + 1) * 0.5)
    np.testing.assert_array_equal(traj.actions, actions[:t])
    np.testing.assert_array_equal(traj.features[-1], ts.observation["features"])
    np.testing.assert_array_equal(traj.poses[-1], ts.observation["pose"])
    assert traj.outcome in ("timeout", "collision", "target")
    assert traj.task == task.to_dict() and traj.speed == 2.0
    assert not np.array_equal(traj.poses[0], traj.poses[-1])  # the robot moved
    assert len(rec) == 0 and not rec.started  # reusable
    loaded = load_dataset(save_dataset(tmp_path / "r.npz", [traj]))
    assert_same(traj, loaded[0])


def test_recorder_misuse():
    rec = TrajectoryRecorder(0.5)
    obs = {"features": np.zeros(16), "ranges": np.zeros(9), "pose": np.zeros(3)}
    with pytest.raises(RuntimeError, match="start"):
        rec.step(0, obs)
    rec.start(obs)
    with pytest.raises(ValueError, match="action"):
        rec.step(6, obs)
    with pytest.raises(ValueError, match="decision_period"):
        TrajectoryRecorder(0.0)


def test_one_outcome_rate_function_for_summaries_and_evaluations(trajs):
    from nirl_mj.data.outcomes import metrics_of, outcome_rates

    rates = outcome_rates(["target", "target", "collision", "timeout", "target"])
    assert rates == {
        "success_rate": 0.6,
        "collision_rate": 0.2,
        "timeout_rate": 0.2,
        "physics_error_rate": 0.0,
    }
    assert outcome_rates([]) == dict.fromkeys(rates, 0.0)
    expected = outcome_rates(t.outcome for t in trajs)
    assert {k: summarise(trajs)[k] for k in expected} == expected
    metrics = metrics_of(trajs)
    assert {k: metrics[k] for k in expected} == expected and metrics["tests"] == 4
