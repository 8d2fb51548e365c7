"""Restores a compare experiment's finished cells from its published results, so that an output
directory lost with its machine is resumed instead of recomputed.

    python docs/scripts/restore_cells.py TASK OUT SOURCE [--runs A-B] [--extend N]
        [--rename NEW=OLD ...] [--skip NAMES]
    (SOURCE: a published results folder such as docs/results/table1_extended, which holds the
    experiment's experiment.json and results.json)

OUT is opened (or created) as ``nirl-mj compare --task TASK --out OUT`` opens it, which makes its
demonstrations if they are missing; then the cells are taken by
``nirl_mj.experiments.reuse.restore_published`` (the rules of ``compare --reuse``: the same identity
in the shared keys, the same definition or learner settings, the same test arenas per run). A
restored cell records ``restored_from`` and has no ``seconds`` and no training run. Resume with the
same compare command afterwards: it computes only the cells left.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from nirl_mj.data.lock import DirectoryLock, LockedError
from nirl_mj.experiments.compare import cell_id
from nirl_mj.experiments.definition import ExperimentError, load_experiment
from nirl_mj.experiments.protocol import Execution, prepare
from nirl_mj.experiments.reuse import restore_published


def run_range(text: str) -> range:
    """``"A-B"`` (both included) or ``"A"`` as a range of run indices."""
    first, _, last = text.partition("-")
    try:
        return range(int(first), int(last or first) + 1)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--runs {text!r}: give A-B or A (run indices)") from None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("task", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("source", type=Path)
    parser.add_argument("--runs", type=run_range, help="A-B: only these runs (default: every run)")
    parser.add_argument("--extend", type=int, default=None, metavar="N",
                        help="open OUT with runs 0..N-1, as `compare --runs N` does (fewer runs, to try a "
                        "method; or rows run beyond the file's `runs`)")  # fmt: skip
    parser.add_argument("--rename", action="append", default=[], metavar="NEW=OLD",
                        help="take NEW's cells from SOURCE's method OLD (same learner settings)")  # fmt: skip
    parser.add_argument("--skip", default="", metavar="NAMES",
                        help="comma-separated methods to compute again (not taken)")  # fmt: skip
    args = parser.parse_args()
    bad = [pair for pair in args.rename if "=" not in pair]
    if bad:
        parser.error(f"--rename {bad[0]}: give NEW=OLD (method names)")
    rename = dict(pair.split("=", 1) for pair in args.rename)
    try:
        experiment = load_experiment(args.task, kind="compare")
        if args.extend is not None:
            if args.extend < 1:
                raise ExperimentError(f"--extend {args.extend}: give a number of runs >= 1")
            experiment = dataclasses.replace(experiment, runs=args.extend)
        skip = {n.strip() for n in args.skip.split(",") if n.strip()}
        if unknown := sorted(skip - {m.name for m in experiment.methods}):
            raise ExperimentError(f"--skip {', '.join(unknown)}: not a method of {experiment.name}")
        with DirectoryLock(args.out, experiment.kind):  # the lock a compare on OUT holds
            out, jobs = prepare(experiment, args.out, Execution(), print)
            jobs = {key: job for key, job in jobs.items() if key[0] not in skip}
            restore_published(args.source, experiment, out, jobs, cell_id, rename, args.runs)
    except (ExperimentError, LockedError) as exc:
        parser.exit(2, f"restore_cells: {exc}\n")


if __name__ == "__main__":
    main()
