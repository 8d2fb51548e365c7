"""Writes one benchmark's section of docs/PERFORMANCE.md, atomically, keeping the others."""

from __future__ import annotations

import os
import platform
import re
import shlex
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

from nirl_mj.data.atomic import write_text
from nirl_mj.data.lock import DirectoryLock

PERFORMANCE_MD = Path(__file__).resolve().parents[1] / "docs" / "PERFORMANCE.md"
_HEADER = (
    "# Performance\n\nEach section is written by the benchmark named in it; "
    "rerun the command to refresh it (the main job's\n`--out` must be absent or empty: it is timed "
    'from scratch; its\nparagraphs that start "Note (by hand)" are kept, after the new figures: '
    "`bench/report.py`).\n"
)
HAND_NOTE = "Note (by hand)"
"""How a hand-written paragraph of a section starts: a rewrite keeps it (:func:`write_section`)."""
KEPT = (
    "Notes by hand kept from this section's earlier versions (they speak of the figures they were "
    "written beside):"
)


def machine() -> str:
    """CPU model, cores and Python/MuJoCo versions, one line."""
    cpu = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import mujoco

    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, MuJoCo {mujoco.__version__}"


def git_commit() -> str:
    try:
        out = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        )
        dirty = subprocess.run(
            ["git", "status", "--porcelain"], capture_output=True, text=True
        ).stdout.strip()
        return out.stdout.strip() + ("+uncommitted" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def write_section(name: str, body: str, path: Path = PERFORMANCE_MD) -> None:
    """Replaces (or appends) the section ``## name`` of ``path`` with ``body`` plus machine, date and
    command; the old section's paragraphs that start with :data:`HAND_NOTE` follow the new figures
    (a rerun never deletes what a person wrote there)."""
    stamp = (
        f"Machine: {machine()}. Date: {datetime.now(UTC):%Y-%m-%d %H:%M} UTC. Commit: {git_commit()}.\n"
        f"Command: `{shlex.join(['python', *sys.argv])}`\n\n"
    )
    section = f"## {name}\n\n{stamp}{body.strip()}\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    with DirectoryLock(path, "benchmark", wait=True):  # two benchmarks ending together: one waits
        _replace_section(path, name, section)


def _replace_section(path: Path, name: str, section: str) -> None:
    text = path.read_text() if path.exists() else _HEADER
    pattern = re.compile(rf"^## {re.escape(name)}\n.*?(?=^## |\Z)", re.S | re.M)
    old = pattern.search(text)
    if old is None:
        text = text.rstrip() + "\n\n" + section
    else:
        notes = [p.strip() for p in re.split(r"\n[ \t]*\n", old.group(0)) if p.lstrip().startswith(HAND_NOTE)]
        if notes:
            section += "\n" + "\n\n".join([KEPT, *notes]) + "\n"
        text = text[: old.start()] + section + "\n" + text[old.end() :]
    write_text(path, text)


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    """A Markdown table from a header and rows of already formatted cells."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in rows])
