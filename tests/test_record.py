"""Rerun recordings, read back: entity paths, timelines, row counts and values against the episode."""

import json
from pathlib import Path

import numpy as np
import pytest
import rerun.chunk

from nirl_mj.cli import main
from nirl_mj.data.features import ACTION_NAMES
from nirl_mj.experts.policies import PolicyAgent, rule_policy
from nirl_mj.inspect.recording import Recording, layout_of, moving_positions, record_run
from nirl_mj.learn.reward import RewardModel, reward_feature_names
from nirl_mj.sim import spec as specs
from nirl_mj.sim.episode import run_episode
from nirl_mj.sim.task import make_env


def tiny_task(moving: int = 2) -> specs.TaskSpec:
    """A 30 m arena with 3 static and ``moving`` moving obstacles, planar drive: episodes of ~30 decisions."""
    return specs.replace(
        specs.load_task("navigate"),
        arena={"size": [30.0, 30.0], "start": [5.0, 5.0], "target": [25.0, 25.0], "static_obstacles": 3,
               "moving_obstacles": moving, "moving_speed": [0.5, 1.0]},
        robot={"drive": "planar"},
    )  # fmt: skip


def read_rrd(path: Path) -> dict[str, list]:
    """Chunks of the recording in ``path`` by entity path."""
    out: dict[str, list] = {}
    for chunk in rerun.chunk.RrdReader(path).store().stream():
        out.setdefault(chunk.entity_path, []).append(chunk)
    return out


def column(chunks: list, name: str, timeline: str = "step") -> list:
    """The temporal rows of component column ``name`` over ``chunks``, ordered by ``timeline``."""
    rows = []
    for chunk in chunks:
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        rows += zip(batch.column(timeline).to_pylist(), batch.column(name).to_pylist(), strict=True)
    return [value for _, value in sorted(rows, key=lambda r: r[0])]


@pytest.fixture(scope="module")
def episode():
    task = tiny_task()
    trajectory = run_episode(make_env(task), PolicyAgent(rule_policy, "rule"), seed=3)
    assert len(trajectory) > 5
    return task, trajectory


def test_the_target_is_drawn_with_the_tasks_radius(tmp_path):
    task = specs.replace(tiny_task(moving=0), arena={"target_radius": 2.0})
    trajectory = run_episode(make_env(task), PolicyAgent(rule_policy, "rule"), seed=3)
    chunks = read_rrd(record_run(tmp_path / "run.rrd", [trajectory], [], {}))
    [chunk] = chunks["/demos/000/arena/start_target"]
    assert chunk.to_record_batch().column("Points3D:radii").to_pylist() == [[0.5, 2.0]]  # start, target


def test_run_recording_matches_the_episode(tmp_path, episode):
    task, trajectory = episode
    theta = np.random.default_rng(0).normal(size=len(reward_feature_names("extended")))
    reward = RewardModel(theta, "extended")
    metrics = [{"episode": i, "margin": 1.0 / (i + 1), "cost": 2.0, "dw1": 0.1, "success_rate": 0.5}
               for i in range(4)]  # fmt: skip
    path = record_run(tmp_path / "run.rrd", [trajectory], metrics, {"NIRL (default)": [trajectory]},
                      reward=reward, map_arena=(task, trajectory.arena_seed))  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.rrd"]  # no temporary file left
    chunks = read_rrd(path)
    n = len(trajectory) + 1
    for prefix in ("/demos/000", "/eval/nirl_default/000"):
        for name in ("arena/obstacles", "arena/cylinders", "arena/border", "arena/start_target", "path",
                     "robot/footprint", "robot/heading", "robot/marker", "reward_path", "label",
                     "end", "end/label"):  # fmt: skip
            assert all(c.is_static for c in chunks[f"{prefix}/{name}"]), name
        states = (
            "robot",
            "robot/rays",
            "features/danger",
            "features/target",
            "features/flags",
            "arena/moving",
        )
        for name, rows in [(name, n) for name in states] + [("action", n - 1), ("reward", n - 1)]:
            temporal = [c for c in chunks[f"{prefix}/{name}"] if not c.is_static]
            assert sum(c.num_rows for c in temporal) == rows, name
            assert all(set(c.timeline_names) == {"step", "time"} for c in temporal), name
        translation = np.array([r[0] for r in column(chunks[f"{prefix}/robot"], "Transform3D:translation")])
        np.testing.assert_allclose(translation[:, :2], trajectory.poses[:, :2], atol=1e-4)
        times = column(chunks[f"{prefix}/robot"], "time")
        assert [t.total_seconds() for t in times] == pytest.approx(trajectory.times.tolist())
        # phi(s) in three entities by scale: D (7), V, then I and U (8).
        parts = [
            np.array(column(chunks[f"{prefix}/features/{g}"], "Scalars:scalars"))
            for g in ("danger", "target", "flags")
        ]
        assert [p.shape[1] for p in parts] == [7, 1, 8]
        np.testing.assert_array_equal(np.hstack(parts), trajectory.features)
        actions = [r[0] for r in column(chunks[f"{prefix}/action"], "TextLog:text")]
        assert actions == [ACTION_NAMES[a] for a in trajectory.actions]
        rewards = np.array([r[0] for r in column(chunks[f"{prefix}/reward"], "Scalars:scalars")])
        np.testing.assert_allclose(rewards, reward.reward(*trajectory.pairs()))
        rays = column(chunks[f"{prefix}/robot/rays"], "LineStrips3D:strips")
        assert all(len(r) == 9 for r in rays)
        # A ray is as long as the sensor's clearance plus the robot's radius.
        lengths = np.array([[np.hypot(*np.subtract(s[1], s[0])[:2]) for s in r] for r in rays])
        np.testing.assert_allclose(lengths, trajectory.ranges + 0.225, atol=1e-3)
        centres = column(chunks[f"{prefix}/arena/moving"], "Cylinders3D:centers")
        layout = layout_of(trajectory)
        np.testing.assert_allclose(
            np.array(centres[0])[:, :2], [(o.x, o.y) for o in layout.moving], atol=1e-4
        )
        assert not np.allclose(centres[0], centres[-1])  # they move
        # The end: a dot where the robot stopped, labelled with the outcome; the arena's label too.
        end = chunks[f"{prefix}/end"][0].to_record_batch()
        np.testing.assert_allclose(end.column("Points3D:positions").to_pylist()[0][0][:2],
                                   trajectory.poses[-1, :2], atol=1e-4)  # fmt: skip
        word = {"target": "arrived", "physics_error": "physics error"}.get(
            trajectory.outcome, trajectory.outcome
        )
        end_label = chunks[f"{prefix}/end/label"][0].to_record_batch()
        assert end_label.column("Points3D:labels").to_pylist() == [[word]]
        assert np.hypot(*np.subtract(end_label.column("Points3D:positions").to_pylist()[0][0][:2],
                                     trajectory.poses[-1, :2])) < 5.0  # fmt: skip
        label = chunks[f"{prefix}/label"][0].to_record_batch().column("Points3D:labels").to_pylist()
        assert label == [[f"000 {word}"]]
    margin = chunks["/training/margin"]
    temporal = [c for c in margin if not c.is_static]
    assert sum(c.num_rows for c in temporal) == 4
    # Only on ``iteration``: never on an episode's ``step`` or ``time``.
    assert all(set(c.timeline_names) == {"iteration"} for c in temporal)
    assert column(margin, "Scalars:scalars", "iteration") == [[1.0], [0.5], [1.0 / 3], [0.25]]
    assert chunks["/training/figure"][0].is_static
    for name in (*ACTION_NAMES, "grid", "values", "info"):
        assert chunks[f"/reward_map/{name}"][0].is_static, name
    assert len(rerun.chunk.RrdReader(path).blueprints()) == 1


def test_moving_obstacles_are_where_the_task_moved_them():
    env = make_env(tiny_task(moving=3))
    env.random_state.seed(1)  # an arena where an obstacle bounces off a wall within 12 decisions
    timestep = env.reset()
    layout, arena = env.task.layout, env.task.root_entity
    seen, times = [arena.moving_positions], [0.0]
    for _ in range(12):
        timestep = env.step(rule_policy(timestep.observation["features"]))
        assert not timestep.last()
        seen.append(arena.moving_positions)
        times.append(env.physics.data.time)
    start = np.array([(o.vx, o.vy) for o in layout.moving])
    assert np.any(np.sign(start) != np.sign(arena.moving_velocities))  # the bounce is covered
    np.testing.assert_allclose(moving_positions(layout, np.array(times)), np.array(seen), atol=1e-9)


def test_recording_is_atomic(tmp_path, episode):
    _, trajectory = episode
    with pytest.raises(RuntimeError, match="boom"), Recording(tmp_path / "x.rrd") as recording:
        recording.episode("demos/000", trajectory)
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_a_recording_without_overwrite_never_replaces_a_file_that_appeared_meanwhile(tmp_path, episode):
    """The commands check --rerun's path at start and write it at the end: a file another process put
    there in between is kept, and the recording refused, unless --overwrite."""
    _, trajectory = episode
    path = tmp_path / "x.rrd"
    with pytest.raises(FileExistsError, match="pass --overwrite"):
        with Recording(path, overwrite=False) as recording:
            recording.episode("demos/000", trajectory)
            path.write_bytes(b"someone else's")
    assert path.read_bytes() == b"someone else's" and sorted(tmp_path.iterdir()) == [path]
    with Recording(path, overwrite=True) as recording:  # asked to, it replaces it
        recording.episode("demos/000", trajectory)
    assert path.read_bytes() != b"someone else's"


def test_train_and_eval_write_recordings(tmp_path, capsys):
    task = tmp_path / "tiny.toml"
    task.write_text('[arena]\nsize = [30.0, 30.0]\nstart = [5.0, 5.0]\ntarget = [25.0, 25.0]\n'
                    'static_obstacles = 3\n[robot]\ndrive = "planar"\n'
                    '[control]\nstep_budget = 12\n')  # fmt: skip
    demos, run = tmp_path / "demos.npz", tmp_path / "run"
    assert main(["demos", "--task", str(task), "--expert", "rule", "--episodes", "2", "--out", str(demos),
                 "--workers", "1", "--quiet"]) == 0  # fmt: skip
    train = ["train", "--task", str(task), "--demos", str(demos), "--out", str(run), "--episodes", "2",
             "--quiet", "--config", "validation_arenas=2",
             "--rerun", str(run / "train.rrd")]  # fmt: skip
    assert main(train) == 0  # the recording may go into the run directory train makes
    chunks = read_rrd(run / "train.rrd")
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert sum(c.num_rows for c in chunks["/training/margin"] if not c.is_static) == len(rows) == 2
    assert "/demos/001/reward" in chunks and "/reward_map/grid" in chunks
    evaluation = ["eval", "--run", str(run), "--tests", "2", "--quiet", "--rerun", str(tmp_path / "eval.rrd")]
    assert main(evaluation) == 0
    chunks = read_rrd(tmp_path / "eval.rrd")
    assert {"/eval/nirl/000/reward", "/eval/nirl/001/robot", "/reward_map/forward"} <= set(chunks)
    assert "/eval/nirl/002/robot" not in chunks
    # An existing recording is kept unless --overwrite.
    before = (tmp_path / "eval.rrd").read_bytes()
    capsys.readouterr()
    assert main(evaluation) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (tmp_path / "eval.rrd").read_bytes() == before
