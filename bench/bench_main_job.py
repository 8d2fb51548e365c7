"""Wall time and peak memory of the main job, ``nirl-mj run``, on its default task.

Runs the command as a subprocess in a temporary directory (or in the ``--out`` that the extra
options give, which must be absent or empty: the timing is from scratch) and samples the
resident memory of its whole process tree (the job and its worker processes)
every 0.2 s; the peak is the largest sum seen. Target (issue #4): at most
5 minutes of wall time on a 2-core machine after set-up, peak memory under
2 GB. Writes docs/PERFORMANCE.md.

    python bench/bench_main_job.py [-- extra nirl-mj run options]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

try:
    from report import write_section
except ImportError:  # run as a module
    from bench.report import write_section


def _tree_rss(pid: int) -> int:
    """Resident bytes of ``pid`` and all its descendants (Linux /proc)."""
    children: dict[int, list[int]] = {}
    rss: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            statm = (entry / "statm").read_text().split()
        except OSError:
            continue
        child = int(entry.name)
        children.setdefault(int(fields[1]), []).append(child)
        rss[child] = int(statm[1]) * os.sysconf("SC_PAGE_SIZE")
    total, stack = 0, [pid]
    while stack:
        p = stack.pop()
        total += rss.get(p, 0)
        stack.extend(children.get(p, []))
    return total


def _out_of(extra: list[str]) -> Path | None:
    """The ``--out`` among ``nirl-mj run``'s extra options (argparse keeps the last), else None."""
    found = None
    for i, word in enumerate(extra):
        if word == "--out" and i + 1 < len(extra):
            found = Path(extra[i + 1])
        elif word.startswith("--out="):
            found = Path(word.split("=", 1)[1])
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("extra", nargs="*", help="more `nirl-mj run` options (after --)")
    args = parser.parse_args()
    given = _out_of(args.extra)
    if given is not None and given.exists() and (not given.is_dir() or any(given.iterdir())):
        sys.exit(
            f"--out {given}: exists and is not an empty directory; the benchmark times a run from scratch"
        )
    exe = Path(sys.executable).with_name("nirl-mj")
    with tempfile.TemporaryDirectory() as tmp:
        out = [] if given is not None else ["--out", str(Path(tmp) / "run")]
        command = [str(exe), "run", *out, "--quiet", *args.extra]
        t0 = time.perf_counter()
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        peak = 0
        while proc.poll() is None:
            peak = max(peak, _tree_rss(proc.pid))
            time.sleep(0.2)
        wall = time.perf_counter() - t0
        output = proc.stdout.read()
    if proc.returncode != 0:
        sys.exit(f"nirl-mj run failed ({proc.returncode}):\n{output}")
    rows = [line for line in output.splitlines() if line.startswith("|")]
    print("\n".join(rows))  # the job's whole table, for the README's figures
    table = next((line for line in rows if line.startswith("| NIRL")), "")
    body = (
        f"`nirl-mj run {' '.join(args.extra)}` (default task, all cores), from an empty directory: "
        f"**{int(wall // 60)}:{int(wall % 60):02d} wall** ({wall:.0f} s), "
        "peak resident memory of the job and its workers "
        f"**{peak / 2**30:.2f} GB**. Targets: 5:00 and 2 GB.\n\nIts NIRL row: `{table}`"
    )
    print(body)
    write_section("Main job (bench/bench_main_job.py)", body)


if __name__ == "__main__":
    main()
