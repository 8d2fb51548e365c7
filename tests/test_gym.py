"""The Gymnasium environments (nirl_mj.gym): ids, spaces, seeding, episode ends, render, errors."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")  # the optional extra nirl-mj[gym]

import nirl_mj  # noqa: E402  (registers the ids)
from nirl_mj.gym.registration import env_id, task_names  # noqa: E402
from nirl_mj.sim.episode import run_episode  # noqa: E402
from nirl_mj.sim.observations import NAMES  # noqa: E402
from nirl_mj.sim.spec import SpecError  # noqa: E402

SMALL = ["arena.size=[24.0, 24.0]", "arena.start=[4.0, 4.0]", "arena.target=[20.0, 20.0]",
         "arena.static_obstacles=3", "arena.clear_radius=3.0", 'robot.drive="planar"']  # fmt: skip


def test_every_shipped_task_file_has_an_id_and_experiment_files_none():
    assert task_names() == ["dynamic", "navigate", "structured"]
    ids = {k for k in gymnasium.registry if k.startswith("nirl_mj/")}
    assert ids == {"nirl_mj/Dynamic-v0", "nirl_mj/Navigate-v0", "nirl_mj/Structured-v0"}
    assert env_id("table1_nirl") == "nirl_mj/Table1Nirl-v0"


def test_both_checkers_pass_on_the_full_dict_without_a_warning():
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gymnasium.make("nirl_mj/Navigate-v0")
    assert set(env.observation_space.spaces) == set(NAMES)
    for name, box in env.observation_space.spaces.items():
        assert np.all(np.isfinite(box.low)) and np.all(np.isfinite(box.high)), name
        assert box.shape and len(box.shape) == 1, name
    assert env.action_space == gymnasium.spaces.Discrete(6)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an infinite bound, a 0-d array, ...: a failure
        check_env(env.unwrapped)
        sb3_check_env(env.unwrapped)
    env.close()


def test_reset_with_a_seed_draws_the_arena_of_that_arena_seed():
    env = gymnasium.make("nirl_mj/Navigate-v0", set=SMALL)
    first, _ = env.reset(seed=11)
    again, _ = env.reset(seed=11)
    other, _ = env.reset(seed=12)
    for key in NAMES:
        np.testing.assert_array_equal(first[key], again[key])
    assert not np.array_equal(first["rays"], other["rays"])
    # The same arena as run_episode's for arena seed 11, through the dm_env underneath.
    dm = nirl_mj.make_env(env.unwrapped.task_spec)
    seen = []
    run_episode(dm, _Stop(), 11, on_step=lambda i, ts, a: seen.append(ts.observation))
    for key in NAMES:
        np.testing.assert_array_equal(first[key], seen[0][key], err_msg=key)


class _Stop:
    kind = "stop"

    def reset(self, env, timestep):
        pass

    def act(self, timestep):
        return 0 if timestep.observation["steps"][0] < 1 else 5


def test_the_budget_truncates_and_an_arrival_terminates_with_is_success():
    env = gymnasium.make("nirl_mj/Navigate-v0", set=[*SMALL, "control.step_budget=2"])
    env.reset(seed=0)
    _, _, terminated, truncated, info = env.step(0)
    assert (terminated, truncated, info["outcome"], info["is_success"]) == (False, False, "running", False)
    _, _, terminated, truncated, info = env.step(0)
    assert (terminated, truncated, info["outcome"], info["is_success"]) == (False, True, "timeout", False)

    near = ["arena.static_obstacles=0", "arena.start=[10.0, 10.0]", "arena.target=[12.5, 10.0]"]
    env = gymnasium.make("nirl_mj/Navigate-v0", set=[*SMALL, *near])
    env.reset(seed=0)
    ends = [env.step(0)[2:] for _ in range(2)]
    assert ends[-1][0] is True and ends[-1][1] is False
    assert ends[-1][2]["outcome"] == "target" and ends[-1][2]["is_success"] is True


def test_the_spec_says_the_task_s_own_step_budget_and_adds_no_time_limit():
    """`env.spec.max_episode_steps` is the budget of the task as resolved (it follows `set=`), with no
    TimeLimit wrapper of a registered value that `task=` could contradict; an environment made again
    from that spec truncates at the same decision."""
    env = gymnasium.make("nirl_mj/Navigate-v0")
    assert env.spec.max_episode_steps == 340 == env.unwrapped.task_spec.step_budget
    env = gymnasium.make("nirl_mj/Navigate-v0", set=[*SMALL, "control.step_budget=2"])
    assert env.spec.max_episode_steps == 2 and "TimeLimit" not in str(env)
    again = gymnasium.make(env.spec)
    again.reset(seed=0)
    assert [again.step(0)[3] for _ in range(2)] == [False, True]


def test_render_gives_frames_at_one_per_decision():
    quick = ["control.decision_period=0.25", "control.max_accel=10.0"]
    env = gymnasium.make(
        "nirl_mj/Navigate-v0", set=[*SMALL, *quick], render_mode="rgb_array", width=64, height=48
    )
    assert env.metadata["render_fps"] == 4.0
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (48, 64, 3) and frame.dtype == np.uint8 and frame.std() > 0


def test_one_observation_alone_is_its_box_and_close_twice_is_harmless():
    env = gymnasium.make("nirl_mj/Dynamic-v0", observation="features")
    assert env.observation_space.shape == (16,)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (16,) and env.observation_space.contains(obs)
    env.close()
    env.close()


def test_async_vector_environments_step():
    envs = gymnasium.make_vec("nirl_mj/Navigate-v0", num_envs=2, vectorization_mode="async", set=SMALL)
    obs, _ = envs.reset(seed=3)
    assert obs["features"].shape == (2, 16)
    obs, reward, terminated, truncated, info = envs.step(np.array([0, 1]))
    assert reward.shape == (2,) and list(info["outcome"]) == ["running", "running"]
    envs.close()


def test_bad_input_is_a_clear_error():
    with pytest.raises(gymnasium.error.Error, match="Did you mean: `Navigate`"):
        gymnasium.make("nirl_mj/Navigat-v0")
    env = gymnasium.make("nirl_mj/Navigate-v0", set=SMALL)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action must be one integer in 0\.\.5"):
        env.step(2.5)
    with pytest.raises(ValueError, match="accepted: one of or a list of features"):
        gymnasium.make("nirl_mj/Navigate-v0", observation="phi")
    with pytest.raises(ValueError, match="no_such_task"):
        gymnasium.make("nirl_mj/Navigate-v0", task="no_such_task")
    for size in ({"width": 0}, {"height": "480"}, {"width": 1920, "height": 1080}):
        with pytest.raises(ValueError, match=r"accepted: a whole number of pixels in 1\.\.(1280|960)"):
            gymnasium.make("nirl_mj/Navigate-v0", render_mode="rgb_array", **size)


def test_rendering_in_a_worker_forked_after_the_parent_rendered_is_refused_not_hung():
    import multiprocessing

    env = gymnasium.make("nirl_mj/Navigate-v0", set=SMALL, render_mode="rgb_array", width=64, height=48)
    env.reset(seed=0)
    env.render()

    def child(queue):
        worker = gymnasium.make("nirl_mj/Navigate-v0", set=SMALL, render_mode="rgb_array", width=64, height=8)
        worker.reset(seed=0)
        try:
            worker.render()
            queue.put("rendered")
        except RuntimeError as exc:
            queue.put(str(exc))

    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    process = context.Process(target=child, args=(queue,))
    process.start()
    answer = queue.get(timeout=120)
    process.join(timeout=60)
    assert "start the workers with spawn" in answer


def test_the_core_package_imports_and_runs_without_gymnasium():
    code = (
        "import sys; sys.modules['gymnasium'] = None\n"
        "import nirl_mj, nirl_mj.cli\n"
        "assert 'nirl_mj.gym.registration' not in sys.modules\n"
        "assert nirl_mj.cli.main(['rollout', '--episodes', '1', '--quiet', '--set', "
        "'arena.static_obstacles=0', '--set', 'control.step_budget=2']) == 0\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    # What needs the extra says so, in one line.
    code = ("import sys; sys.modules['gymnasium'] = None\nimport nirl_mj.cli\n"
            "sys.exit(nirl_mj.cli.main(['rl', '--steps', '8', '--out', sys.argv[1]]))")  # fmt: skip
    done = subprocess.run([sys.executable, "-c", code, "/nonexistent/rl"], capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "nirl-mj rl: error: this needs the optional extra nirl-mj[gym] (no module 'gymnasium'): "
        "pip install -e '.[gym]'"
    ]


def _gym_actions(env, policy, seed: int) -> tuple[list[int], str]:
    obs, info = env.reset(seed=seed)
    actions = []
    while True:
        actions.append(policy(obs))
        obs, _, terminated, truncated, info = env.step(actions[-1])
        if terminated or truncated:
            return actions, info["outcome"]


@pytest.mark.parametrize("kind", ["sensor", "rule", "planner"])
def test_experts_as_policies_drive_as_they_do_in_run_episode(kind):
    from nirl_mj.experts import make_expert
    from nirl_mj.gym.policies import ExpertPolicy, reference_policy

    env = gymnasium.make("nirl_mj/Navigate-v0", set=SMALL)
    policy = reference_policy(kind) if kind == "rule" else ExpertPolicy(kind, env=env)
    dm = nirl_mj.make_env(env.unwrapped.task_spec)
    for seed in (5, 6):  # two episodes: the expert is reset between them
        actions, outcome = _gym_actions(env, policy, seed)
        expected = run_episode(dm, make_expert(kind), seed)
        assert actions == expected.actions.tolist() and outcome == expected.outcome


def test_policies_refuse_what_they_cannot_read():
    from nirl_mj.gym.policies import ExpertPolicy, reference_policy

    with pytest.raises(ValueError, match="give env="):
        ExpertPolicy("planner")
    with pytest.raises(ValueError, match="accepted: planner, sensor"):
        ExpertPolicy("oracle")
    with pytest.raises(ValueError, match="full Dict observation"):
        ExpertPolicy("sensor")(np.zeros(16, np.float32))
    assert reference_policy("forward")(np.zeros(16, np.float32)) == 0


# -- continuous actions ---------------------------------------------------------------------------


def test_continuous_actions_are_a_bounded_twist_through_the_wheel_controller():
    import math

    from nirl_mj.sim import spec

    with pytest.raises(spec.SpecError, match="accepted: discrete, continuous"):
        spec.apply_overrides(spec.load_task("navigate"), ['control.actions="sideways"'])
    assert "actions" not in spec.load_task("navigate").to_dict()["control"]  # records unchanged
    task = spec.apply_overrides(spec.load_task("navigate"), [*SMALL, "arena.static_obstacles=0",
                                                              'control.actions="continuous"'])  # fmt: skip
    env = nirl_mj.make_env(task, seed=0)
    bounds = env.action_spec()
    assert bounds.shape == (2,) and bounds.maximum.tolist() == [2.0, pytest.approx(math.pi / 3 / 0.5)]
    start = env.reset().observation["pose"].copy()
    for _ in range(3):
        ts = env.step(np.array([0.0, bounds.maximum[1]]))  # on the spot, left at full rate
    turned = math.degrees(ts.observation["pose"][2] - start[2])
    assert 150 < turned <= 180  # 60 degrees a decision, less the wheels' acceleration ramp
    assert np.hypot(*(ts.observation["pose"][:2] - start[:2])) < 0.05
    with pytest.raises(ValueError, match=r"out of range: accepted \(forward speed m/s in \[-2, 2\]"):
        env.step(np.array([2.5, 0.0]))
    with pytest.raises(ValueError, match="two finite numbers"):
        env.step(3)
    # the episode loop records a continuous task's actions as float32 shares (a discrete choice as its twin)
    recorded = run_episode(env, _Stop(), 0).actions
    assert recorded.dtype == np.float32 and recorded[:2].tolist() == [[1.0, 0.0], [-1.0, 0.0]]


def test_the_rule_and_ppo_drive_with_continuous_actions(tmp_path, monkeypatch):
    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path))  # SB3's own logger: its folder here, not in /tmp
    from nirl_mj.gym.policies import reference_policy

    sb3 = pytest.importorskip("stable_baselines3")

    gym_set = [*SMALL, 'control.actions="continuous"']
    env = gymnasium.make("nirl_mj/Navigate-v0", set=[*gym_set, "arena.static_obstacles=0"])
    assert env.action_space == gymnasium.spaces.Box(-1.0, 1.0, (2,), np.float32)  # normalised (issue 33)
    assert env.unwrapped.action_scale == pytest.approx([2.0, 2.0943951])  # m/s, rad/s of an action of 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # both checkers, no warning
        from gymnasium.utils.env_checker import check_env
        from stable_baselines3.common.env_checker import check_env as sb3_check

        check_env(env.unwrapped)
        sb3_check(env.unwrapped)
    _, outcome = _gym_actions(env, reference_policy("rule", env=env), 0)
    assert outcome == "target"
    env.reset(seed=2)
    beyond = env.step(np.array([3.0, -7.0], np.float32))  # clipped to [1, -1]: full speed, full right turn
    assert (
        env.unwrapped.twist([3.0, -7.0]).tolist() == pytest.approx([2.0, -2.0943951])
        and env.observation_space.contains(beyond[0])  # the step ran, and its observation is in range
    )

    model = sb3.PPO("MultiInputPolicy", gymnasium.make("nirl_mj/Navigate-v0", set=gym_set), n_steps=64,
                    batch_size=32, n_epochs=1, seed=0, device="cpu")  # fmt: skip
    model.learn(64)
    action, _ = model.predict(env.reset(seed=1)[0], deterministic=True)
    assert action.shape == (2,) and env.action_space.contains(action.astype(np.float32))


# -- the edges a user hit (issue 33), each written as the user called it ------------------------------


def test_stepping_after_the_end_says_to_reset_instead_of_a_type_error():
    env = gymnasium.make("nirl_mj/Navigate-v0", set=[*SMALL, "control.step_budget=1"]).unwrapped
    with pytest.raises(RuntimeError, match=r"step\(\) before reset\(\): call reset\(\) first"):
        env.step(0)
    env.reset(seed=0)
    assert env.step(0)[3] is True  # truncated by the budget
    with pytest.raises(RuntimeError, match=r"after the episode ended .*: call reset\(\) first"):
        env.step(0)
    env.reset(seed=1)
    env.step(0)  # a new episode steps again


def test_the_readme_example_task_path_works_from_another_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    env = gymnasium.make("nirl_mj/Navigate-v0", task="tasks/dynamic.toml", set=["control.speed=3"])
    assert env.unwrapped.task_spec.arena.moving_obstacles > 0 and env.unwrapped.task_spec.control.speed == 3.0
    with pytest.raises(SpecError, match="task file not found: tasks/nowhere.toml"):
        gymnasium.make("nirl_mj/Navigate-v0", task="tasks/nowhere.toml")


def test_an_expert_drives_a_vector_environment_as_it_drives_each_one():
    """issue 33: experts failed on a batched (vector-env) observation."""
    from nirl_mj.experts import make_expert
    from nirl_mj.gym.policies import ExpertPolicy

    envs = gymnasium.make_vec("nirl_mj/Navigate-v0", num_envs=2, vectorization_mode="sync", set=SMALL)
    policy = ExpertPolicy("sensor")
    obs, _ = envs.reset(seed=[5, 6])
    taken = [[], []]
    for _ in range(6):
        actions = policy(obs)
        assert actions.shape == (2,)
        for i in range(2):
            taken[i].append(int(actions[i]))
        obs, *_ = envs.step(actions)
    dm = nirl_mj.make_env(envs.envs[0].unwrapped.task_spec)
    for i, seed in enumerate((5, 6)):
        assert taken[i] == run_episode(dm, make_expert("sensor"), seed).actions.tolist()[:6]
    with pytest.raises(ValueError, match="one ExpertPolicy per environment"):
        ExpertPolicy("planner", env=envs.envs[0])(obs)
    with pytest.raises(ValueError, match="one ExpertPolicy per environment"):  # given the vector env itself
        ExpertPolicy("planner", env=envs)
    # the vector environment given: its task's kind of actions (continuous: float32 shares for a batch)
    assert ExpertPolicy("sensor", env=envs)(envs.reset(seed=[5, 6])[0]).dtype.kind == "i"
    continuous = gymnasium.make_vec("nirl_mj/Navigate-v0", num_envs=2, vectorization_mode="sync",
                                    set=[*SMALL, "control.actions=continuous"])  # fmt: skip
    shares = ExpertPolicy("sensor", env=continuous)(continuous.reset(seed=[5, 6])[0])
    assert shares.shape == (2, 2) and shares.dtype == np.float32
    continuous.step(shares)
    from nirl_mj.gym.policies import reference_policy

    batch = continuous.reset(seed=[5, 6])[0]
    rule = reference_policy("rule", env=continuous)(batch)  # a batch: one action per environment
    assert rule.shape == (2, 2) and np.array_equal(rule[1], reference_policy("rule", env=continuous)(
        {k: v[1] for k, v in batch.items()}))  # fmt: skip


def test_an_environment_pickles_as_a_fresh_one_of_the_same_task():
    """issue 33: the env could not be pickled."""
    import pickle

    env = gymnasium.make("nirl_mj/Navigate-v0", set=[*SMALL, "control.speed=1.5"], observation="features")
    first, _ = env.reset(seed=3)
    env.step(0)
    copy = pickle.loads(pickle.dumps(env))
    assert copy.unwrapped.task_spec == env.unwrapped.task_spec
    # the spec gymnasium.make gave (its id and the task's step budget) survives the trip
    assert copy.unwrapped.spec == env.unwrapped.spec and copy.unwrapped.spec.id == "nirl_mj/Navigate-v0"
    again, _ = copy.reset(seed=3)
    assert np.array_equal(first, again) and copy.observation_space == env.observation_space


def test_a_discrete_action_on_a_continuous_environment_names_the_expert_option():
    env = gymnasium.make("nirl_mj/Navigate-v0", set=[*SMALL, "control.actions=continuous"])
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"a discrete action \(ExpertPolicy and reference_policy answer with "
                                         r"shares when given env=this environment\)"):  # fmt: skip
        env.step(0)
    with pytest.raises(ValueError, match=r"expected two finite numbers in \[-1, 1\]$"):
        env.step([0.5, 0.1, 0.2])
    env.close()
