"""A tiny NIRL run, end to end, learns something always-forward cannot do.

The arena is small and has a cylinder on the straight line from start to target
(plus two random obstacles), so "always forward" never arrives. Measured with
the inner learner of 2026-11-24 (Q-learning, 32 hidden units, gamma 0.9, 3-step
targets): at 30 iterations, 2 of 4 training seeds (0, 1) beat it on their own
training arenas (45 and 35 % against 0 %); seeds 2 and 3 stopped colliding but
still time out (at 20 iterations seed 0 scored 0 %: the longer discount learns
more slowly on this arena). The test uses seed 0.
"""

from nirl_mj.data.dataset import save_dataset
from nirl_mj.experiments.demos import ExpertConfig, collect
from nirl_mj.experiments.evaluation import evaluate
from nirl_mj.experiments.seeds import domain_seeds
from nirl_mj.experiments.training import load_policy, train
from nirl_mj.experts.policies import always_forward
from nirl_mj.learn.config import LearnerConfig
from nirl_mj.sim import spec
from nirl_mj.sim.task import make_env

BLOCKED = spec.replace(
    spec.load_task("navigate"),
    arena={
        "size": [24.0, 24.0], "start": [4.0, 4.0], "target": [20.0, 20.0], "static_obstacles": 2,
        "clear_radius": 3.0, "obstacle_size": [0.5, 1.5],
        "obstacles": [{"shape": "cylinder", "position": [12.0, 12.0], "size": [2.0]}],
    },
    robot={"drive": "planar"},
)  # fmt: skip


def test_tiny_nirl_run_beats_always_forward_on_its_own_arenas(tmp_path):
    demos = tmp_path / "demos.npz"
    save_dataset(demos, collect(BLOCKED, ExpertConfig("sensor"), episodes=8, seed=0))
    config = LearnerConfig.preset(
        "default",
        episodes=30,
        trajectories_per_episode=10,
        validation_arenas=10,
        validate_every=2,
        replay_episodes=5,
    )
    train(tmp_path / "run", BLOCKED, demos, config, seed=0)
    policy, record = load_policy(tmp_path / "run")
    own = record["train_seeds"][:20]
    assert own == domain_seeds("train", 0, 20)
    env = make_env(BLOCKED)
    nirl = evaluate(env, policy, own)[0]
    forward = evaluate(env, always_forward, own)[0]
    assert forward["success_rate"] == 0.0
    assert nirl["success_rate"] >= 0.2, nirl
