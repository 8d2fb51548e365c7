"""Issue 31: the imitation library's own AIRL and GAIL on Table I's setting, for comparison with ours.

Trains ``imitation.algorithms.adversarial.airl.AIRL`` (or ``gail.GAIL``) of the imitation library
(1.0.1, with the Stable-Baselines3 and Gymnasium 0.29 it pins) on run r of Table I
(tasks/table1.toml: tasks/navigate.toml, 20 static obstacles, 2 m/s) with the inputs our GAIL / AIRL
rows got until 2026-11-30 (phi(s) scaled, tested sampled; Table I's AIRL differs since), then
tests its final PPO policy on run r's 100 test arenas as our Table I cell does, and writes
``docs/results/imitation_crosscheck/<algo>_run<r>.json`` atomically.

It runs in its own virtual environment (the library pins gymnasium 0.29; our package asks for 1.x),
built outside the repository:

    python3 -m venv /work/imitation-venv
    /work/imitation-venv/bin/pip install torch==2.13.0        # the CPU wheel
    /work/imitation-venv/bin/pip install imitation==1.0.1
    /work/imitation-venv/bin/pip install -e . --no-deps
    /work/imitation-venv/bin/pip install "mujoco==3.17.0" "dm-control==1.0.50" \
        "gymnasium==0.29.1" "torch==2.13.0" "numpy==2.4.6"

    /work/imitation-venv/bin/python docs/scripts/imitation_crosscheck.py --algo airl --run 0
    (--steps 50000: decisions; --tests N: the first N test arenas only; --out DIR: elsewhere (a
     result already there is refused unless --overwrite: the default --out is the published one);
     --demo-batch-size, --disc-updates: the library's discriminator batch and steps per round;
     --output-norm none: an ablation without NormalizedRewardNet, written to
     <algo>_run<r>_no-output-norm.json; --model-dir: where the final PPO model is saved)

What it shares with our rows as they were computed then (``nirl_mj.experiments.rl``,
``nirl_mj.experiments.adversarial``):
run r's 30 demonstrations (``OUT/demos/runNNN.npz`` of runs/table1_fair), terminal where the
demonstration ended in a terminal outcome (``nirl_mj.data.transitions``); the observation phi(s)
scaled to [0, 1] (``rl.scaled``); 8 ``NavigationEnv(task, observation="features")`` in one
``DummyVecEnv``, every episode in the next arena of one ``ArenaStream`` of the train domain
(``domain_seed("train", seed, k)``, seed = r); PPO ``MlpPolicy`` with ``rl.SETTINGS["ppo"]`` (a
rollout of 1024 decisions, 128 per environment, minibatch 64, 10 epochs, gamma 0.99, learning rate
3e-4, SB3's other defaults), seeded r; the budget rounded up to whole rollouts as SB3's ``learn``
does (50,000 -> 49 rollouts, 50,176 decisions); the tests: ``run_jobs(...)[method, r].test_seeds``,
driven by ``protocol.evaluate_policy`` with every action sampled from PPO's distribution by a
generator seeded 0 (``rl.load_rl_policy``'s default, as ``experiments.kinds`` loads it).

What it does NOT match (the library's choices, kept on purpose; its ``train_adversarial`` script's
defaults where its constructors leave a choice open):

- the discriminator: ``BasicShapedRewardNet`` (AIRL: g(s, a) one hidden layer of 32 ReLU on
  [phi, one-hot a], h(s) two of 32; discount 0.99) or ``BasicRewardNet`` (GAIL: two hidden layers of
  32 ReLU), inputs normalised by a ``RunningNorm`` and the net wrapped in
  ``NormalizedRewardNet(RunningNorm)`` (the script's defaults; for GAIL the wrapper changes nothing,
  its policy reward bypasses it). Ours: tanh MLPs 64-64, g(s, a) with one output per action, h(s),
  no input or output normalisation.
- the policy's reward: AIRL's is f(s, a, s') = g + gamma h(s') - h(s), normalised by its running mean
  and variance; ours is the logit f - ln pi(a | s), unnormalised. GAIL's is -ln sigmoid(-l) =
  softplus(l) in both.
- the discriminator's training: ``n_disc_updates_per_round`` = 4 Adam steps per rollout (the
  script's default; the class's is 2), each on ``demo_batch_size`` = 1024 expert pairs against 1024
  pairs of the last rollout (``gen_replay_buffer_capacity`` = 1024, the rollout, as the script sets it
  to its rollout size), Adam's default learning rate 1e-3. Ours: 4 epochs of minibatches of 256 over
  the rollout (16 steps), learning rate 3e-4. The library updates the discriminator after PPO's update
  on the rollout, ours before it.
- episode ends: the library marks every learner episode that ended as done, a timeout too (its
  ``TrajectoryAccumulator``; then h(s') = 0); ours only a terminal one (a timeout bootstraps h(s')).
- the policy tested: the final PPO policy (the library keeps no checkpoints); ours tests the
  checkpoint its ``demo_balanced`` selection chose (the JSON records which, from the run's record).
- versions: Stable-Baselines3 2.2.1 and Gymnasium 0.29.1 (the library's pins) against ours'
  2.9.2 and 1.4; ``allow_variable_horizon=True`` (our episodes end at arrival or collision; the
  library refuses variable horizons unless told).

Run it with ``nice -n 19`` on a shared machine; torch uses one thread.
"""

from __future__ import annotations

import argparse
import csv
import importlib.metadata
import json
import math
import platform
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENT = ROOT / "tasks" / "table1.toml"
TABLE1 = ROOT / "runs" / "table1_fair"
OUT = ROOT / "docs" / "results" / "imitation_crosscheck"
ENVS = 8
METHODS = {"airl": "AIRL", "gail": "GAIL"}
EVAL_SEED = 0  # rl.load_rl_policy's default seed, as experiments.kinds._rl loads a cell's policy
PACKAGES = ("imitation", "stable-baselines3", "gymnasium", "torch", "numpy", "mujoco", "dm-control")


class ScaledFeatures(gymnasium.ObservationWrapper):
    """phi(s) as the networks see it (``rl.scaled``), a Box in [0, 1]; Gymnasium 0.29's
    ``TransformObservation`` takes no observation space, so this replaces it."""

    def __init__(self, env: gymnasium.Env, scale: Callable[[np.ndarray], np.ndarray]) -> None:
        super().__init__(env)
        self.scale = scale
        shape = env.observation_space.shape
        self.observation_space = gymnasium.spaces.Box(0.0, 1.0, shape, np.float32)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        return self.scale(observation)


def versions() -> dict[str, str]:
    found = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            found[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            found[name] = "not installed"
    return found


def the_job(method: str, run: int) -> Any:
    """Our Table I cell (method, run): task, seed, demonstrations and test arenas, as run_jobs makes it."""
    from nirl_mj.experiments.definition import load_experiment
    from nirl_mj.experiments.protocol import demos_path, run_jobs

    experiment = load_experiment(EXPERIMENT)
    demos = demos_path(TABLE1, experiment, run)
    if not demos.is_file():
        sys.exit(f"{demos}: no demonstrations for run {run}")
    return run_jobs(experiment, TABLE1, {run: demos})[method, run]


def demonstrations(path: str, scale: Callable[[np.ndarray], np.ndarray]) -> list:
    """Our dataset's trajectories as imitation's ``Trajectory``: obs scaled phi(s_0..s_T), acts, and
    terminal where the episode ended in a terminal outcome (a timeout is a truncation)."""
    from imitation.data.types import Trajectory

    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.data.trajectory import TERMINAL_OUTCOMES, require_discrete

    trajectories = load_dataset(path)
    require_discrete(trajectories, path)
    return [Trajectory(obs=scale(t.features), acts=np.asarray(t.actions, np.int64), infos=None,
                       terminal=t.outcome in TERMINAL_OUTCOMES) for t in trajectories if len(t)]  # fmt: skip


def environment(task: Any, seed: int, scale: Callable[[np.ndarray], np.ndarray]) -> tuple[Any, Any]:
    """``ENVS`` training environments as ``rl._environment`` builds them (non-legacy): one shared
    ArenaStream of the train domain, phi scaled, Monitor reading ``is_success``."""
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    from nirl_mj.experiments.seeds import domain_seed
    from nirl_mj.gym.env import NavigationEnv
    from nirl_mj.gym.wrappers import ArenaSeeds, ArenaStream

    stream = ArenaStream(lambda k: domain_seed("train", seed, k))

    def make() -> gymnasium.Env:
        arenas = ArenaSeeds(NavigationEnv(task, observation="features"), stream=stream, replace_given=True)
        return Monitor(ScaledFeatures(arenas, scale), info_keywords=("is_success",))

    return DummyVecEnv([make] * ENVS), stream


def on_demonstrations(model: Any, path: str, scale: Callable[[np.ndarray], np.ndarray]) -> dict[str, Any]:
    """The policy on the demonstrated states: the greedy action's balanced accuracy (our
    ``demo_balanced`` score), its mean probability of each action, and the expert's action shares."""
    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.data.features import ACTION_NAMES
    from nirl_mj.data.trajectory import stack_pairs
    from nirl_mj.learn.predictability import balanced_accuracy

    phi, actions = stack_pairs(load_dataset(path))
    with torch.no_grad():
        probs = model.policy.get_distribution(torch.as_tensor(scale(phi))).distribution.probs
    shares = np.bincount(np.asarray(actions, int), minlength=len(ACTION_NAMES)) / len(actions)
    mean_probs = probs.mean(dim=0).numpy().round(4).tolist()
    return {
        "demo_balanced": float(balanced_accuracy(actions, probs.argmax(dim=1).numpy())),
        "policy_mean_probs": dict(zip(ACTION_NAMES, mean_probs, strict=True)),
        "expert_action_shares": dict(zip(ACTION_NAMES, shares.round(4).tolist(), strict=True)),
    }


def last_disc_stats(log_dir: Path) -> dict[str, float]:
    """The discriminator's statistics of the last round, from the library's progress.csv."""
    progress = log_dir / "progress.csv"
    rows = list(csv.DictReader(progress.open())) if progress.is_file() else []
    last: dict[str, float] = {}
    for row in rows:
        for key, value in row.items():
            if key and key.startswith("mean/disc/") and value not in ("", None):
                last[key.removeprefix("mean/")] = float(value)
    return last


def ours(method: str, run: int) -> dict:
    """Our Table I cell's result on the same run, as stored (read, not recomputed), with the checkpoint
    its selection chose."""
    cell = TABLE1 / "cells" / f"{method}-run{run:03d}.json"
    out: dict[str, Any] = {"cell": str(cell.relative_to(ROOT))}
    if cell.is_file():
        result = json.loads(cell.read_text())["result"]
        out |= {k: result.get(k) for k in ("success_rate", "collision_rate", "timeout_rate", "spl", "tests")}
    record = TABLE1 / "runs" / method / str(run) / "run.json"
    if record.is_file():
        saved = json.loads(record.read_text())
        out |= {
            "selected_steps": (saved.get("selected") or {}).get("steps"),
            "steps_done": saved.get("steps_done"),
            "config": saved.get("config"),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algo", choices=sorted(METHODS), required=True)
    parser.add_argument("--run", type=int, required=True, help="Table I run r (training seed r)")
    parser.add_argument("--steps", type=int, default=50_000, help="decisions (rounded up to whole rollouts)")
    parser.add_argument("--tests", type=int, default=None, help="the first N test arenas only (smoke tests)")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--overwrite", action="store_true",
                        help="replace a result already in --out (by default it is kept)")  # fmt: skip
    parser.add_argument("--demo-batch-size", type=int, default=1024)
    parser.add_argument("--disc-updates", type=int, default=4, help="n_disc_updates_per_round")
    models = Path(tempfile.gettempdir()) / "imitation_crosscheck_models"
    parser.add_argument("--model-dir", type=Path, default=models,
                        help="where the final PPO model is saved (outside the repository)")  # fmt: skip
    parser.add_argument("--output-norm", choices=("running", "none"), default="running",
                        help="none: the reward net without NormalizedRewardNet (an ablation; AIRL's policy "
                        "reward is then the raw f)")  # fmt: skip
    args = parser.parse_args(argv)
    from nirl_mj.data.atomic import AtomicFile, refuse_existing, write_text

    suffix = "" if args.output_norm == "running" else "_no-output-norm"
    path = args.out / f"{args.algo}_run{args.run}{suffix}.json"
    try:  # before the training, not after it
        refuse_existing(path, args.overwrite, "exists; pass --overwrite to replace it, or give another --out")
    except FileExistsError as exc:
        parser.exit(2, f"imitation_crosscheck: {exc}\n")
    torch.set_num_threads(1)
    start = time.monotonic()

    from imitation.algorithms.adversarial.airl import AIRL
    from imitation.algorithms.adversarial.gail import GAIL
    from imitation.rewards.reward_nets import BasicRewardNet, BasicShapedRewardNet, NormalizedRewardNet
    from imitation.util import logger as imit_logger
    from imitation.util.networks import RunningNorm
    from stable_baselines3 import PPO

    from nirl_mj.experiments.protocol import evaluate_policy
    from nirl_mj.experiments.rl import model_policy, run_config, scaled

    method = METHODS[args.algo]
    job = the_job(method, args.run)
    config = run_config(args.algo, "demo_balanced", ENVS)  # our row's settings: n_steps 1024 / 8
    ppo_settings = {k: v for k, v in config.items() if k not in ("algo", "selection", "envs")}
    rollout = ppo_settings["n_steps"] * ENVS
    rounds = max(1, math.ceil(args.steps / rollout))

    demos = demonstrations(job.demos_path, scaled)
    venv, stream = environment(job.task, job.seed, scaled)
    model = PPO("MlpPolicy", venv, seed=job.seed, device="cpu", verbose=0, **ppo_settings)
    if args.algo == "airl":
        net = BasicShapedRewardNet(
            venv.observation_space,
            venv.action_space,
            normalize_input_layer=RunningNorm,
            discount_factor=ppo_settings["gamma"],
        )
    else:
        net = BasicRewardNet(venv.observation_space, venv.action_space, normalize_input_layer=RunningNorm)
    reward_net = NormalizedRewardNet(net, RunningNorm) if args.output_norm == "running" else net
    log_dir = Path(tempfile.mkdtemp(prefix=f"imitation_crosscheck_{args.algo}_run{args.run}_"))
    trainer_settings = {
        "demo_batch_size": args.demo_batch_size,
        "n_disc_updates_per_round": args.disc_updates,
        "gen_replay_buffer_capacity": rollout,
        "allow_variable_horizon": True,
    }
    try:  # the trainer's log is read for its last round, then removed: the script leaves no folder behind
        trainer = (AIRL if args.algo == "airl" else GAIL)(
            demonstrations=demos, venv=venv, gen_algo=model, reward_net=reward_net, log_dir=log_dir,
            custom_logger=imit_logger.configure(str(log_dir), ["csv"]), **trainer_settings,
        )  # fmt: skip
        trainer.train(total_timesteps=rounds * rollout)
        disc_stats = last_disc_stats(log_dir)
    finally:
        shutil.rmtree(log_dir, ignore_errors=True)
    train_seconds = time.monotonic() - start
    venv.close()

    overlap = set(stream.used) & set(job.test_seeds)  # as protocol.policy_of refuses a cell
    if overlap:
        sys.exit(f"training saw test arenas {sorted(overlap)}: refusing to test")
    seeds = tuple(job.test_seeds[: args.tests] if args.tests else job.test_seeds)
    # our loader's sampled policy on phi(s), as for a discrete PPO run of ours
    sample = model_policy(
        model, {"algo": "ppo", "task": {"control": {"actions": "discrete"}}}, True, EVAL_SEED, True
    )
    taken: list[int] = []

    def policy(phi: np.ndarray) -> int:  # the sampled policy, its actions counted
        taken.append(sample(phi))
        return taken[-1]

    metrics = evaluate_policy(policy, job.task, seeds, f"imitation-{args.algo}")
    from nirl_mj.data.features import ACTION_NAMES

    test_shares = np.bincount(taken, minlength=len(ACTION_NAMES)) / max(len(taken), 1)
    args.model_dir.mkdir(parents=True, exist_ok=True)
    with AtomicFile(args.model_dir / f"{args.algo}_run{args.run}{suffix}.zip", ".zip") as target:
        model.save(target.tmp)  # the temporary ends in .zip: Stable-Baselines3 adds no suffix

    inner = f"{type(net).__name__}(normalize_input_layer=RunningNorm)"
    result = {
        "algo": args.algo,
        "library": f"imitation {importlib.metadata.version('imitation')}: "
        f"{'airl.AIRL' if args.algo == 'airl' else 'gail.GAIL'}",
        "run": args.run,
        "seed": job.seed,
        "task": {
            "name": job.task.name,
            "static_obstacles": job.task.arena.static_obstacles,
            "speed": job.task.control.speed,
        },  # fmt: skip
        "demos": str(Path(job.demos_path).relative_to(ROOT)),
        "demo_pairs": int(sum(len(t.acts) for t in demos)),
        "decisions": int(model.num_timesteps),
        "rounds": rounds,
        "train_arenas": len(stream.used),
        "test_arenas": len(seeds),
        "success_rate": metrics["success_rate"],
        "collision_rate": metrics["collision_rate"],
        "timeout_rate": metrics["timeout_rate"],
        "physics_error_rate": metrics.get("physics_error_rate"),
        "spl": metrics.get("spl"),
        "metrics": metrics,
        "test_action_shares": dict(zip(ACTION_NAMES, test_shares.round(4).tolist(), strict=True)),
        "final_policy_on_demonstrations": on_demonstrations(model, job.demos_path, scaled),
        "discriminator_last_round": disc_stats,
        "settings": {
            "ppo": {"policy": "MlpPolicy", "envs": ENVS, **ppo_settings},
            "trainer": trainer_settings,
            "disc_optimiser": "Adam, torch defaults (lr 1e-3)",
            "reward_net": f"NormalizedRewardNet({inner}, RunningNorm)"
            if args.output_norm == "running"
            else inner,
            "reward_net_modules": str(net),
            "evaluation": f"final PPO policy, actions sampled, numpy generator seeded {EVAL_SEED}",
        },
        "ours_table1": ours(method, args.run),
        "versions": versions(),
        "wall_seconds": {"train": round(train_seconds, 1), "total": round(time.monotonic() - start, 1)},
        "command": " ".join([Path(sys.executable).as_posix(), *sys.argv]),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(path, json.dumps(result, indent=1, default=str) + "\n")
    print(json.dumps({k: result[k] for k in ("algo", "run", "success_rate", "collision_rate", "timeout_rate",
                                              "spl", "wall_seconds")}))  # fmt: skip
    print(f"ours: {json.dumps({k: v for k, v in result['ours_table1'].items() if k != 'config'})}")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
