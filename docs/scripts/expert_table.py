"""docs/EXPERTS.md's "Measured" table: each demonstrator's success and predictability, stored.

Each row is one ``nirl-mj demos`` command (seed 0, ``tasks/navigate.toml`` unless its settings
say otherwise); the three 30-demonstration rows are also read by ``nirl-mj inspect`` (MAP
pretreatment's relabelled pairs, eq. 10). Every command's JSON line is kept in
``DIR/ROW.json`` with the date and commit it ran at; a row already there is not run again (rerun
to resume), and ``--render`` prints the table, then the relabelled pairs, from the stored files
alone (``render_docs.py``'s ``experts`` block calls :func:`render`).

    python docs/scripts/expert_table.py --out docs/results/experts      # ~3 min on 2 cores
    python docs/scripts/expert_table.py --render docs/results/experts
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from datetime import UTC, datetime
from pathlib import Path

from nirl_mj.data.atomic import write_text

ROOT = Path(__file__).resolve().parents[2]
NIRL_MJ = [sys.executable, "-m", "nirl_mj.cli"]

# (file name, expert as the table shows it, setting as the table shows it, episodes, extra demos arguments)
ROWS: tuple[tuple[str, str, str, int, tuple[str, ...]], ...] = (
    ("planner_2", "planner", "2 m/s", 200, ("--expert", "planner")),
    ("planner_1", "planner", "1 m/s (`--set control.speed=1`)", 100,
     ("--expert", "planner", "--set", "control.speed=1")),
    ("planner_3", "planner", "3 m/s", 100, ("--expert", "planner", "--set", "control.speed=3")),
    ("planner_dynamic", "planner", "`--task dynamic`", 100, ("--expert", "planner", "--task", "dynamic")),
    ("sensor_2", "sensor", "2 m/s", 200, ("--expert", "sensor")),
    ("sensor_1", "sensor", "1 m/s", 100, ("--expert", "sensor", "--set", "control.speed=1")),
    ("sensor_3", "sensor", "3 m/s", 100, ("--expert", "sensor", "--set", "control.speed=3")),
    ("sensor_dynamic", "sensor", "`--task dynamic`", 100, ("--expert", "sensor", "--task", "dynamic")),
    ("planner_30", "planner", "2 m/s, 30 demonstrations", 30, ("--expert", "planner")),
    ("sensor_30", "sensor", "2 m/s, 30 demonstrations", 30, ("--expert", "sensor")),
    ("noisy_30", "noisy (sensor, slip 0.1, random 0.05)", "2 m/s, 30 demonstrations", 30,
     ("--expert", "noisy")),
)  # fmt: skip
INSPECTED = ("planner_30", "sensor_30", "noisy_30")
"""Rows whose dataset ``nirl-mj inspect`` reads too (MAP pretreatment's relabelled pairs)."""


def _json_line(command: list[str]) -> dict:
    """The last line of ``command``'s output, a JSON object; the command's error if it failed."""
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"error: {' '.join(command)} failed:\n{done.stderr.strip()}")
    try:
        return json.loads((done.stdout.strip().splitlines() or [""])[-1])
    except json.JSONDecodeError:
        raise SystemExit(f"error: {' '.join(command)} printed no JSON line last") from None


def _commit() -> str:
    """The checkout's commit, ``+uncommitted`` when its tracked files differ from it."""
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                           capture_output=True, text=True).stdout.strip()  # fmt: skip
    return head.stdout.strip() + ("+uncommitted" if dirty else "") if head.returncode == 0 else "unknown"


def measure(folder: Path) -> None:
    """Runs every row not yet stored in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, _, _, episodes, extra in ROWS:
        path = folder / f"{name}.json"
        if path.exists():
            continue
        with tempfile.TemporaryDirectory() as tmp:
            dataset = str(Path(tmp) / "demos.npz")
            command = ["demos", "--episodes", str(episodes), "--seed", "0", *extra]
            command += ["--out", dataset, "--json"]
            demos = _json_line([*NIRL_MJ, *command, "--quiet"])
            demos.pop("out", None)  # the temporary dataset's path
            row = {"command": "nirl-mj " + " ".join(command[:-2] + ["X.npz", "--json"]), "demos": demos,
                   "date": f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC", "commit": _commit()}  # fmt: skip
            if name in INSPECTED:
                row["inspect"] = _json_line([*NIRL_MJ, "inspect", dataset, "--json"])
        write_text(path, json.dumps(row, indent=1) + "\n")
        print(f"{name}: success {row['demos']['success_rate']:.0%}", flush=True)


def _percent(x: float) -> str:
    return f"{100 * x:.0f} %"


def render(folder: str | Path) -> str:
    """The Markdown table of the rows stored in ``folder`` (a row not yet measured is refused)."""
    folder = Path(folder)
    lines = [
        "| expert | setting | arenas | success | collision | timeout | forward share | "
        "predictability (balanced acc.) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, expert, setting, _, _ in ROWS:
        path = folder / f"{name}.json"
        if not path.exists():
            raise FileNotFoundError(
                f"{path}: not measured yet (python docs/scripts/expert_table.py --out {folder})"
            )
        d = json.loads(path.read_text(encoding="utf-8"))["demos"]
        n = d["episodes"]
        collisions, timeouts = round(d["collision_rate"] * n), round(d["timeout_rate"] * n)
        lines.append(
            f"| {expert} | {setting} | {n} | {_percent(d['success_rate'])} | {collisions} | {timeouts} | "
            f"{_percent(d['action_fractions']['forward'])} | "
            f"{d['predictability']['balanced_accuracy']:.2f} |"
        )
    return "\n".join(lines)


def map_relabelled(folder: str | Path) -> dict[str, tuple[int, int]]:
    """``row: (pairs MAP pretreatment relabels, pairs)`` of the inspected rows."""
    found = {}
    for name in INSPECTED:
        d = json.loads((Path(folder) / f"{name}.json").read_text(encoding="utf-8"))
        found[name] = (d["inspect"]["map_pairs_changed"], d["demos"]["pairs"])
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="measure the rows not yet stored in this folder")
    parser.add_argument("--render", type=Path, help="print the table from this folder's stored rows")
    args = parser.parse_args()
    if not (args.out or args.render):
        parser.error("give --out DIR (measure) or --render DIR (print)")
    if args.out:
        measure(args.out)
    if args.render:
        print(render(args.render))
        for name, (changed, pairs) in map_relabelled(args.render).items():
            print(f"{name}: MAP pretreatment relabels {changed} of {pairs} pairs")


if __name__ == "__main__":
    main()
