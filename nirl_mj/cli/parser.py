"""The ``nirl-mj`` argument parser: every command, its options and its choices (from the registries)."""

from __future__ import annotations

import argparse
from collections.abc import Callable

from nirl_mj.cli import commands as c
from nirl_mj.experiments.executors import EXECUTORS
from nirl_mj.experiments.rl import ALGOS, DEFAULT_STEPS, SELECTIONS
from nirl_mj.experiments.seeds import SEED_LIMIT
from nirl_mj.experiments.subjects import REFERENCES
from nirl_mj.experts import EXPERT_KINDS
from nirl_mj.experts.policies import POLICIES
from nirl_mj.inspect.video import MONTAGE_SNAPSHOTS, PATHS_ARENAS
from nirl_mj.learn.config import VARIANTS
from nirl_mj.sim.rollouts import BACKENDS, DEVICES
from nirl_mj.sim.spec import DRIVES

DESCRIPTION = "Neural inverse reinforcement learning (NIRL) for a Festo Robotino simulated in MuJoCo."


def _number(kind: Callable, low: float, high: float, accepted: str) -> Callable[[str], float]:
    """An argparse type: ``kind(text)`` within [low, high], else an error naming what is accepted."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {accepted}, got {text!r}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"expected {accepted}, got {text}")
        return value

    return parse


_positive_int = _number(int, 1, float("inf"), "a whole number >= 1")
_probability = _number(float, 0.0, 1.0, "a probability in [0, 1]")
_seed = _number(int, 0, SEED_LIMIT - 1, "a seed, a whole number in 0 .. 2^32 - 1")
_workers = _number(int, 1, 1024, "a number of processes in 1 .. 1024")


def _demo_count(text: str) -> int:
    """``run --demos``: how many demonstrations the main job records (where ``train``, ``rl`` and
    ``eval`` take a dataset's path under the same name)."""
    try:
        return _positive_int(text)
    except argparse.ArgumentTypeError as error:
        raise argparse.ArgumentTypeError(
            f"{error}: the main job records its own demonstrations and --demos counts them; to learn "
            "from a dataset, nirl-mj train --demos PATH (then nirl-mj eval --run)"
        ) from None


OVERWRITE_RERUN = (
    "overwrite=an existing --rerun file (a run in --out is continued with --resume, never replaced)"
)
"""``run`` and ``train``: ``--overwrite`` reaches only the recording; their run is resumed, not replaced."""


def _command(sub, name: str, func: Callable, help: str, *common: str, task: str | None = "navigate"):
    """A subcommand with its function and shared options: --task (None when not given: the command
    uses what ``task`` describes as its default; ``task`` None: no task options) with --set;
    ``common`` from json, quiet, overwrite[=WHAT], rerun=WHAT, backend=WHAT."""
    parser = sub.add_parser(name, help=help)
    parser.set_defaults(func=func, command_parser=parser)
    if task is not None:
        parser.add_argument(
            "--task", default=None, help=f"task name under tasks/ or a .toml path (default: {task})"
        )
        parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                            help="override a task value, e.g. control.speed=3 (repeatable)")  # fmt: skip
    for option in common:
        key, _, what = option.partition("=")
        if key == "json":
            parser.add_argument("--json", action="store_true", help="print a JSON summary as the last line")
        elif key == "backend":
            resumed = "; a resumed training: the run's" if name == "train" else ""
            worlds = "the learner's trajectories per iteration, 10 by default" if name == "train" else "64"
            parser.add_argument(
                "--backend",
                choices=BACKENDS,
                default=None,
                help=f"where {what} run: cpu, the dm_control task (default{resumed}), or warp, many "
                "worlds at once on MuJoCo Warp (nirl-mj[warp])",
            )
            parser.add_argument(
                "--worlds",
                type=_positive_int,
                default=None,
                help=f"with --backend warp: worlds stepped at once (default: {worlds}{resumed})",
            )
            parser.add_argument("--device", choices=DEVICES, default=None,
                                help="with --backend warp: Warp's device (default: cuda)")  # fmt: skip
        elif key == "quiet":
            parser.add_argument("--quiet", action="store_true", help="no progress bar")
        elif key == "overwrite":
            parser.add_argument(
                "--overwrite", action="store_true", help=f"replace {what or 'existing output files'}"
            )
        elif key == "rerun":
            parser.add_argument(
                "--rerun", default=None, metavar="FILE.rrd", help=f"also write a Rerun recording: {what}"
            )
    return parser


def _experiment_command(sub, name: str, default: str, help: str) -> None:
    """The options of ``compare``, ``sweep`` and ``suite`` (docs/EXPERIMENTS.md)."""
    p = _command(sub, name, c.cmd_experiment, help, "json", "quiet", task=None)
    p.add_argument("--task", default=default, metavar="SPEC",
                   help=f"experiment file or its name under tasks/ (default: {default})")  # fmt: skip
    p.add_argument("--quick", action="store_true", help="the spec's [quick] values: a smoke run")
    p.add_argument("--runs", type=_positive_int, default=None, metavar="N",
                   help="runs 0..N-1 instead of the spec's `runs`: compute or extend to N, or with "
                   "--report the table of the first N (not part of an experiment's identity)")  # fmt: skip
    p.add_argument(
        "--out",
        default=None,
        help="output directory (default: runs/NAME[-quick]); rerunning into "
        "it resumes the same experiment, another one is refused",
    )
    p.add_argument("--executor", choices=EXECUTORS, default="local",
                   help="where cells run: this process, local processes (default), or Ray")  # fmt: skip
    p.add_argument("--workers", type=_workers, default=None,
                   help="local processes or local Ray CPUs (default: all cores)")  # fmt: skip
    p.add_argument("--address", default=None, help="with --executor ray: an existing cluster's address")
    p.add_argument(
        "--retries", type=int, default=2, metavar="N", help="further attempts of a failing cell (default: 2)"
    )
    p.add_argument(
        "--report",
        action="store_true",
        help="run nothing: write the tables from the cells finished so "
        "far (a partial report of a long or interrupted experiment; while the experiment runs, they are "
        "printed, not written: one writer per output)",
    )
    p.add_argument("--check", action="store_true",
                   help="run and write nothing: check the file (its [quick] table too) and print what it "
                   "would run, and what --out holds")  # fmt: skip
    if name in ("compare", "suite"):
        p.add_argument("--only", default=None, metavar="NAMES",
                       help="comma-separated methods: compute only their cells; the tables show the "
                       "others' finished cells (not part of an experiment's identity)")  # fmt: skip
    if name == "suite":
        p.add_argument("--points", default=None, metavar="VALUES",
                       help="comma-separated values of the training axis: compute only their cells; the "
                       "tables show the others' finished cells (not part of the identity)")  # fmt: skip
        p.add_argument("--restore", default=None, metavar="DIR",
                       help="first take the finished cells of a published suite (DIR holds NAME.csv and "
                       "NAME.experiment.json, as docs/results/suites, or is a suite's output directory; with "
                       "--only, those methods' only), then compute the rest: for an output directory lost "
                       "with its machine, or one whose methods changed")  # fmt: skip
    if name == "compare":
        p.add_argument("--reuse", default=None, metavar="OLD",
                       help="first copy the cells an earlier output directory OLD finished as the same "
                       "computation (same method settings, demonstrations and test arenas)")  # fmt: skip


# fmt: off
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="nirl-mj", description=DESCRIPTION)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    iterations = dict(type=_positive_int, default=None, help="learner iterations (default: the variant's)")

    p = _command(sub, "run", c.cmd_run, "the main job: demonstrations, NIRL, held-out evaluation next to the "
                 "references, report", "json", "quiet", OVERWRITE_RERUN,
                 "rerun=a copy of RUN_DIR/run.rrd (always written)")
    p.set_defaults(interrupted="finished stages are kept: continue with {again}")
    p.add_argument("--out", default="runs/main", help="run directory (default: runs/main)")
    p.add_argument("--resume", action="store_true", help="continue a run in --out, skipping finished stages")
    p.add_argument("--seed", type=_seed, default=0,
                   help="seed of the demonstrations, the training and the test arenas (default: 0)")
    p.add_argument("--variant", choices=VARIANTS, default="default", help="NIRL's preset (default: default)")
    p.add_argument("--demos", type=_demo_count, default=30, metavar="N",
                   help="demonstrations to record (default: 30; a dataset: nirl-mj train --demos PATH)")
    p.add_argument("--expert", choices=EXPERT_KINDS, default="sensor", help="demonstrator (default: sensor)")
    p.add_argument("--episodes", **iterations)
    p.add_argument("--tests", type=_positive_int, default=100, help="held-out test arenas (default: 100)")
    p.add_argument("--workers", type=_workers, default=None,
                   help="processes for demonstrations, training and evaluation (default: all cores)")

    p = _command(sub, "rollout", c.cmd_rollout, "roll out a reference policy on fresh arenas and print each "
                 "episode's outcome", "json", "quiet")  # fmt: skip
    p.add_argument("--episodes", type=_positive_int, default=10, help="episodes to drive (default: 10)")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the arenas (default: 0)")
    p.add_argument("--policy", choices=sorted(POLICIES), default="rule", help="the policy (default: rule)")

    p = _command(sub, "demos", c.cmd_demos, "record expert demonstrations to a dataset file", "json", "quiet",
                 "overwrite", "rerun=the demonstrations")  # fmt: skip
    p.add_argument("--episodes", type=_positive_int, default=30, help="episodes to record (default: 30)")
    p.add_argument("--expert", choices=EXPERT_KINDS, default="sensor",
                   help="the demonstrator, docs/EXPERTS.md (default: sensor)")  # fmt: skip
    # None when not given: they configure --expert noisy only, and are refused with another expert
    p.add_argument("--base", choices=[k for k in EXPERT_KINDS if k != "noisy"], default=None,
                   help="noisy: the expert it perturbs (default: sensor)")  # fmt: skip
    p.add_argument("--slip", type=_probability, default=None,
                   help="noisy: probability an action slips (default: 0.1)")  # fmt: skip
    p.add_argument("--random-action", type=_probability, default=None,
                   help="noisy: probability of a random action (default: 0.05)")  # fmt: skip
    p.add_argument("--seed", type=_seed, default=0, help="seed of the arenas (default: 0)")
    p.add_argument("--out", required=True, help="dataset path (.npz)")
    p.add_argument("--workers", type=_workers, default=None, help="processes (default: all cores)")
    p.set_defaults(interrupted="finished episodes are kept beside {out} until it is written: the same "
                   "command records only the rest")  # fmt: skip

    p = _command(sub, "teleop", c.cmd_teleop, "drive the robot from the keyboard in MuJoCo's viewer and "
                 "record "
                 "the episodes", "overwrite")
    p.add_argument("--episodes", type=_positive_int, default=30, help="episodes to drive (default: 30)")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the arenas (default: 0)")
    p.add_argument("--out", required=True, help="dataset path (.npz)")

    p = _command(sub, "train", c.cmd_train, "train NIRL on demonstrations (resumable)", "quiet",
                 OVERWRITE_RERUN,
                 "backend=rollouts, validation and selection episodes",
                 "rerun=training scalars per iteration, demonstrations with r_theta, reward map",
                 task="navigate; with --resume the run's own")  # fmt: skip
    p.add_argument("--demos", help="dataset from `nirl-mj demos` (.npz), or minari:ID (a local Minari "
                   "dataset)")  # fmt: skip
    p.add_argument("--out", required=True, help="run directory")
    p.set_defaults(interrupted="finished iterations are kept: continue with "
                               "nirl-mj train --out {out} --resume")
    p.add_argument("--variant", choices=VARIANTS, default=None, help="learner preset (default: default)")
    p.add_argument("--episodes", **iterations)
    p.add_argument("--seed", type=_seed, default=None, help="training seed (default: 0)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    p.add_argument("--config", action="append", default=[], metavar="KEY=VALUE",
                   help="override a learner setting, e.g. reward_source=progress")  # fmt: skip

    p = _command(sub, "rl", c.cmd_rl, "Stable-Baselines3 on phi(s): PPO/DQN on the task's reward (the RL "
                 "reference), or GAIL/AIRL (PPO on a discriminator's reward, from --demos) "
                 "(needs nirl-mj[gym]; resumable)", "quiet", "overwrite")
    p.set_defaults(interrupted="checkpoints are kept: continue with nirl-mj rl --out {out} --resume")
    p.add_argument("--algo", choices=ALGOS, default=None, help="default: ppo; a resume: the run's")
    p.add_argument("--demos", help="gail and airl: the demonstrations to imitate (a dataset path; a resume: "
                   "the run's)")  # fmt: skip
    p.add_argument("--steps", type=_positive_int, default=None,
                   help=f"decisions in all (default: {DEFAULT_STEPS}; a resume: the run's, "
                        "or more), rounded up to whole rollouts of 1024 for PPO, GAIL and AIRL")  # fmt: skip
    p.add_argument("--selection", choices=SELECTIONS, default=None,
                   help="how the checkpoint handed to tests is chosen (default: demo_balanced for gail and "
                        "airl, training_success for ppo and dqn; last: none; a resume: the run's)")
    p.add_argument("--envs", type=_positive_int, default=None,
                   help="environments sharing each rollout, in turn (default: 1; a resume: the run's)")
    p.add_argument("--train-drive", choices=DRIVES, default=None,
                   help="the drive of the training episodes (default: the task's; a resume: the run's); "
                        "validation and tests drive the task's")
    p.add_argument("--seed", type=_seed, default=None,
                   help="training seed (network, arenas; default: 0; a resume: the run's)")  # fmt: skip
    p.add_argument("--out", required=True, help="run directory (evaluate it with nirl-mj eval --run)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out: a stopped run is "
                   "replayed from its seed to its last checkpoint and ends as if uninterrupted; with a "
                   "larger --steps, it goes on from its saved model")  # fmt: skip

    p = _command(sub, "eval", c.cmd_eval, "evaluate a trained run's policy on held-out arenas", "json",
                 "quiet", "overwrite=an existing --rerun file, and the same evaluation in RUN/eval.json",
                 "backend=the test episodes",
                 "rerun=every test episode (with r_theta and the reward map for --run)",
                 task="the run's own; with --policy navigate")  # fmt: skip
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--run", help="run directory")
    who.add_argument("--policy", choices=REFERENCES, help="a reference policy instead of a run")
    p.add_argument("--demos", help="with --policy: demonstrations (cloned by bc; their arenas are held out)")
    p.add_argument("--train-seed", type=_seed, default=None,
                   help="with --policy bc: its training seed (default: 0)")  # fmt: skip
    p.add_argument("--tests", type=_positive_int, default=100, help="held-out test arenas (default: 100)")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the test arenas")
    p.add_argument("--which", default=None, metavar="selected|last|N",
                   help="with --run: the selected policy (default), the last, or iteration N's")  # fmt: skip

    p = _command(sub, "render", c.cmd_render, "render an episode of a run's (or a reference) policy "
                 "offscreen: "
                 "MP4, PNG montages", "overwrite", task="the run's own; with --policy navigate")
    who = p.add_mutually_exclusive_group(required=True)
    who.add_argument("--run", help="run directory: its policy on its held-out test arenas")
    who.add_argument("--policy", choices=sorted(POLICIES), help="a reference policy instead of a run")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the test arenas (as for eval)")
    p.add_argument("--episode", type=int, default=0, help="which test arena (0 = eval's first)")
    p.add_argument("--which", default=None,
                   help="with --run: selected (default), last or an iteration number")  # fmt: skip
    p.add_argument("--out", help="MP4 video of the episode")
    p.add_argument("--montage", metavar="FILE.png", help="strip of snapshots of the episode (Fig. 8)")
    p.add_argument("--snapshots", type=_positive_int, default=None,
                   help=f"frames in --montage, at least 2 (default: {MONTAGE_SNAPSHOTS})")  # fmt: skip
    p.add_argument("--paths", metavar="FILE.png", help="whole paths in several test arenas (Fig. 5)")
    p.add_argument("--arenas", type=_positive_int, default=None,
                   help=f"arenas in --paths (default: {PATHS_ARENAS})")  # fmt: skip
    p.add_argument(
        "--camera", default="top", help="top (whole arena, default), follow (12 m above the robot) or chase"
    )
    p.add_argument("--width", type=_positive_int, default=640, help="pixels (even, <= 1280)")
    p.add_argument("--height", type=_positive_int, default=480, help="pixels (even, <= 960)")
    p.add_argument("--fps", type=_number(float, 1e-9, float("inf"), "a frame rate > 0"), default=10.0,
                   help="video frames per second of simulated time; plays at real time")  # fmt: skip
    p.add_argument("--overlay", action=argparse.BooleanOptionalAction, default=True,
                   help="draw time, step, action and danger levels onto the video")  # fmt: skip

    _experiment_command(sub, "compare", "tasks/table1.toml",
                        "the paper's Table I protocol: every method, R runs of T tests, next to the paper")
    _experiment_command(
        sub, "sweep", "tasks/fig6.toml", "Fig. 6: success against obstacles and speed (CSV and line plot)"
    )
    _experiment_command(sub, "suite", "tasks/suites/demos.toml", "the comparison along an axis "
                        "(demonstrations, demonstrator, obstacles, speed, moving, family): tidy CSV, curves")

    p = _command(sub, "leaderboard", c.cmd_leaderboard, "merge output directories of compare or suite "
                 "(the same protocol and test arenas) into one ranked table and plot", "overwrite", task=None)
    p.add_argument("dirs", nargs="+", metavar="DIR", help="output directories of nirl-mj compare or suite")
    p.add_argument("--out", default="runs/leaderboard", help="where to write it (default: runs/leaderboard)")

    p = _command(sub, "export", c.cmd_export, "write a dataset as a Minari dataset (replayed in the "
                 "environment: full observations, rewards, episode ends; needs nirl-mj[gym])", "quiet",
                 "overwrite", task=None)
    p.add_argument("path", help="dataset file (.npz)")
    p.add_argument("--to", choices=["minari"], required=True, help="the format to write")
    p.add_argument("--id", required=True, metavar="ID",
                   help="Minari dataset id, e.g. nirl_mj/navigate/sensor-v0 (stored under "
                   "$MINARI_DATASETS_PATH, default ~/.minari/datasets)")  # fmt: skip

    p = _command(
        sub, "inspect", c.cmd_inspect, "validate a dataset file and print its summary", "json", task=None
    )
    p.add_argument("path", help="dataset file (.npz), or minari:ID: a local Minari dataset (nirl-mj export)")
    p = _command(
        sub, "task", c.cmd_task, "validate a task file and print the resolved spec as JSON", task=None
    )
    p.add_argument("task", help="task name under tasks/ or a .toml path")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override a task value, e.g. arena.floor_plan=pockets (repeatable)")  # fmt: skip
    return parser
# fmt: on
