"""The ``nirl-mj`` command: parse arguments (``parser``), call the library and print (``commands``).
Nothing imports this package."""

from __future__ import annotations

import os
import shlex
import sys

from nirl_mj.cli.parser import build_parser
from nirl_mj.data.dataset import DatasetError
from nirl_mj.data.rundir import RunError
from nirl_mj.sim.layout import ArenaGenerationError
from nirl_mj.sim.spec import SpecError

__all__ = ["build_parser", "main"]

CLEAN_ERRORS = (SpecError, ArenaGenerationError, DatasetError, RunError, OSError, RuntimeError, ValueError)
"""Errors that are the user's input or environment: one ``error:`` line and exit code 2, no traceback
(OSError covers FileExistsError: a run or file that would be overwritten)."""


GYM_EXTRA = ("gymnasium", "stable_baselines3", "minari", "h5py")
"""The optional extra's packages (``rl``, ``export``, ``eval`` of an RL run, ``train --demos minari:``)."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``nirl-mj`` console script; returns the exit status."""
    given = list(sys.argv[1:] if argv is None else argv)
    args, unknown = build_parser().parse_known_args(given)
    if unknown:  # the command's own usage, not the top level's (argparse's default with subcommands)
        args.command_parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    try:
        return args.func(args)
    except BrokenPipeError:
        # the reader of our output left (``nirl-mj inspect D.npz | head``): stop quietly, as Unix
        # tools do; stdout goes to /dev/null so that the interpreter's final flush does not complain
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except CLEAN_ERRORS as exc:
        print(f"nirl-mj {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:
        if (exc.name or "").partition(".")[0] not in GYM_EXTRA:
            raise
        print(f"nirl-mj {args.command}: error: this needs the optional extra nirl-mj[gym] (no module "
              f"{exc.name!r}): pip install -e '.[gym]'", file=sys.stderr)  # fmt: skip
        return 2
    except KeyboardInterrupt:
        # {again}: the command as given, with --resume (a main job resumes only with its own flags)
        again = "nirl-mj " + shlex.join([*(a for a in given if a != "--resume"), "--resume"])
        kept = (
            args.interrupted.format(**vars(args), again=again)
            if hasattr(args, "interrupted")
            else "nothing was written"
        )
        print(f"nirl-mj {args.command}: interrupted; {kept}", file=sys.stderr)
        return 130
