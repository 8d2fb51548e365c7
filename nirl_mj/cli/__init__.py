"""The ``nirl-mj`` command: parse arguments (``parser``), call the library and print (``commands``).
Nothing imports this package."""

from __future__ import annotations

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


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``nirl-mj`` console script; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except CLEAN_ERRORS as exc:
        print(f"nirl-mj {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        kept = (
            args.interrupted.format(**vars(args)) if hasattr(args, "interrupted") else "nothing was written"
        )
        print(f"nirl-mj {args.command}: interrupted; {kept}", file=sys.stderr)
        return 130
