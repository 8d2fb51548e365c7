"""``nirl-mj leaderboard DIR...``: the results of several output directories as one table.

Each DIR is the output of ``nirl-mj compare`` or ``nirl-mj suite`` (its ``experiment.json`` and its
tidy rows: ``rows.csv``, ``suite.csv``, or for a comparison written before ``rows.csv`` existed the
cells of its ``results.json``). The directories must share the protocol (:data:`PROTOCOL`: the same
tasks, seeds, tests, test domain, demonstrations and axes, hence the same test arenas run by run);
a method found in two of them must be the same computation (its identity), and is taken once, from
the first (the runs on which the two differ, as the same computation may on another machine, are
listed under the table).
Outputs in OUT: ``leaderboard.md`` (per point, the methods ranked by average success with its 95 %
t interval, SPL, SCT, runs, what each reads, a reference in bold, and source), ``leaderboard.csv``
(the merged tidy rows) and ``leaderboard.png`` (the same as bars with their intervals).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from nirl_mj.data.atomic import leftover_temporaries, write_figure, write_text
from nirl_mj.data.lock import DirectoryLock
from nirl_mj.experiments import tidy
from nirl_mj.experiments.definition import ExperimentError
from nirl_mj.experiments.reads import is_reference, reads_text
from nirl_mj.experiments.stats import summarise_runs

PROTOCOL = ("kind", "task", "test_task", "seed", "tests", "test_domain", "expert", "demos", "demos_per_run",
            "axes", "config")  # fmt: skip
"""The identity keys every merged directory must share: what decides each run's test arenas and
demonstrations (``config`` too: it decides the training arenas the test arenas avoid)."""
FILES = ("leaderboard.md", "leaderboard.csv", "leaderboard.png")


def read_dir(path: str | Path) -> tuple[dict, list[dict]]:
    """A result directory's identity and tidy rows."""
    path = Path(path)
    marker = path / "experiment.json"
    try:
        identity = json.loads(marker.read_text())
    except FileNotFoundError:
        raise ExperimentError(f"{path}: no experiment.json; give output directories of nirl-mj compare or "
                              "suite") from None  # fmt: skip
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ExperimentError(f"{marker}: cannot be read ({exc})") from None
    if not isinstance(identity, dict) or identity.get("kind") not in ("compare", "suite"):
        raise ExperimentError(f"{marker}: not the identity of a compare or suite experiment")
    for name in ("rows.csv", "suite.csv"):
        if (path / name).is_file():
            try:
                return identity, tidy.read(path / name)
            except tidy.TidyError as exc:
                raise ExperimentError(str(exc)) from None
    return identity, _rows_of_results(path, identity)


def _rows_of_results(path: Path, identity: dict) -> list[dict]:
    """The tidy rows of a comparison written before ``rows.csv``: its ``results.json`` cells."""
    try:
        results = json.loads((path / "results.json").read_text())
        cells = results["cells"]
        return [tidy.row(path.name, "", "", c["method"], int(c["run"]), c) for c in cells.values()]
    except FileNotFoundError:
        raise ExperimentError(f"{path}: no rows.csv, suite.csv or results.json: run the experiment (or its "
                              "--report) first") from None  # fmt: skip
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ExperimentError(f"{path / 'results.json'}: its cells cannot be read ({exc!r})") from None


def recorded_reads(path: str | Path) -> dict[str, list[str]]:
    """What each method of a result directory reads, as its ``results.json`` records it (a
    comparison's per method, a suite's under ``reads``); {} where it records none."""
    try:
        results = json.loads((Path(path) / "results.json").read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return {}
    if not isinstance(results, dict):
        return {}
    found = results.get("reads")
    if not isinstance(found, dict) and isinstance(results.get("methods"), dict):
        found = {name: m.get("reads") for name, m in results["methods"].items() if isinstance(m, dict)}
    if not isinstance(found, dict):
        return {}
    # a damaged entry reads as unrecorded ("?"), never as words it does not hold
    return {name: words for name, words in found.items()
            if isinstance(words, list) and all(isinstance(w, str) for w in words)}  # fmt: skip


def merge(
    dirs: list[str | Path],
) -> tuple[list[dict], dict[str, list[str]], dict[str, list[str] | None], list[str]]:
    """The merged tidy rows of ``dirs``, each method's source directories (the first, then any that
    adds runs the ones before lack), what each method reads
    (:func:`recorded_reads`, from the first directory that records it; None if none does), and the
    runs on which two directories' same computation disagrees (:func:`_disagreements`); refuses
    directories of another protocol and a method name that means two computations."""
    if not dirs:
        raise ExperimentError("leaderboard: give at least one output directory")
    rows, source, methods, reads, notes = [], {}, {}, {}, []
    first_dir, first = None, None
    for d in dirs:
        identity, found = read_dir(d)
        if first is None:
            first_dir, first = d, identity
        differ = [k for k in PROTOCOL if identity.get(k) != first.get(k)]
        if differ:
            raise ExperimentError(f"{d} and {first_dir} differ in {', '.join(differ)}: their test arenas or "
                                  "protocol are not the same, so their results do not compare")  # fmt: skip
        methods_of = identity.get("methods")
        if not isinstance(methods_of, list) or not all(
            isinstance(m, dict) and "name" in m for m in methods_of
        ):
            raise ExperimentError(f"{d}/experiment.json: its methods cannot be read")
        recorded = recorded_reads(d)
        for m in methods_of:
            name = m["name"]
            if name in methods and methods[name] != m:
                fields = sorted(f for f in {*m, *methods[name]} if m.get(f) != methods[name].get(f))
                code = ", its package's code changed" if "source" in fields else ""
                raise ExperimentError(f"method {name} of {d} is not the {name} of {source[name][0]} "
                                      f"(it differs in: {', '.join(fields)}{code}): rename one of them in "
                                      "its experiment file")  # fmt: skip
            if reads.get(name) is None:
                reads[name] = recorded.get(name)
            if name in methods:  # the same computation: taken from the first directory that holds a run
                mine = [r for r in found if r["method"] == name]
                kept = {_point_run(r): r for r in rows if r["method"] == name}
                notes += _disagreements(name, kept, mine, source[name][0], str(d))
                added = [r for r in mine if _point_run(r) not in kept]
                rows += added
                if added:  # the "from" column names every directory the method's runs come from
                    source[name].append(str(d))
                continue
            methods[name], source[name] = m, [str(d)]
            rows += [r for r in found if r["method"] == name]
    return rows, source, reads, notes


def _point_run(row: dict) -> tuple:
    """A tidy row's (axis, value, run): a run of one method at one point."""
    return row["axis"], row["value"], row["run"]


def _disagreements(name: str, held: dict, other: list[dict], first: str, second: str) -> list[str]:
    """Where two directories' rows of one method (one identity) differ on a run both hold (``held``:
    the first's rows by :func:`_point_run`), beyond the CSV's 6 digits: one line each, naming the
    columns and both values. The same computation on another machine can end elsewhere (floating
    point); the first directory's row is the one kept."""
    notes = []
    for r in other:
        mine = held.get(_point_run(r))
        if mine is None:
            continue
        measured = [k for k in ("tests", *tidy.RATES) if None not in (mine[k], r[k])]
        differ = [k for k in measured if not math.isclose(mine[k], r[k], rel_tol=1e-5, abs_tol=1e-9)]
        if differ:
            point = f" at {r['axis']}={r['value']}" if r["axis"] else ""
            values = ", ".join(f"{k} {mine[k]:.6g} against {r[k]:.6g}" for k in differ)
            notes.append(f"{name}, run {r['run']}{point}: `{first}` and `{second}` hold other results of "
                         f"the same computation ({values}); `{first}`'s is taken")  # fmt: skip
    return notes


def points(rows: list[dict]) -> list[dict]:
    """Per (axis, value, method): the runs' summary (``stats.summarise_runs``), best first per point."""
    keys = list(dict.fromkeys((r["axis"], r["value"]) for r in rows))
    out = []
    for axis, value in keys:
        here = [r for r in rows if (r["axis"], r["value"]) == (axis, value)]
        per = []
        for method in dict.fromkeys(r["method"] for r in here):
            mine = sorted((r for r in here if r["method"] == method), key=lambda r: r["run"])
            per.append({"axis": axis, "value": value, "method": method, "run_ids": [r["run"] for r in mine],
                        **summarise_runs([tidy.as_metrics(r) for r in mine])})  # fmt: skip
        out += sorted(per, key=lambda p: -p["avg"])
    return out


def markdown(summary: list[dict], source: dict[str, list[str]], reads: dict[str, list[str] | None]) -> str:
    # every method the directories' experiments list, one that finished no run anywhere too
    parts, partial, everyone = [], False, list(dict.fromkeys([*(p["method"] for p in summary), *reads]))
    for axis, value in dict.fromkeys((p["axis"], p["value"]) for p in summary):
        title = f"## {axis} = {value}\n\n" if axis else ""
        lines = [
            "| rank | method | runs | success [95 % CI] | SPL | SCT | reads | from |",
            "|---|---|---|---|---|---|---|---|",
        ]
        here = [p for p in summary if (p["axis"], p["value"]) == (axis, value)]
        for p in here:
            # equal averages share a rank (1, 2, 2, 4): the order among them says nothing
            rank = next(i for i, q in enumerate(here, start=1) if q["avg"] == p["avg"])
            ci = p.get("ci") or [None, None]
            band = f" [{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]" if ci[0] is not None else ""
            sct = f"{p['sct']:.2f}" if p.get("sct") is not None else "-"
            success = f"{100 * p['avg']:.1f}{band}"
            runs = partial_runs(p, here) or p["runs"]
            where = from_text(source[p["method"]])
            lines.append(f"| {rank} | {p['method']} | {runs} | {success} | {p['spl']:.2f} | "
                         f"{sct} | {reads_text(reads[p['method']])} | {where} |")  # fmt: skip
        partial |= any(partial_runs(p, here) for p in here)
        absent = [m for m in everyone if m not in {p["method"] for p in here}]
        none_here = f"\n\nNo finished run here: {', '.join(absent)}." if absent else ""
        parts.append(title + "\n".join(lines) + none_here)
    if partial:
        parts.append(PARTIAL)
    return "\n\n".join(parts)


def from_text(dirs: list[str]) -> str:
    """The "from" column: every directory a method's runs come from (the first holds most)."""
    return ", ".join(f"`{d}`" for d in dirs)


def partial_runs(point: dict, here: list[dict]) -> str | None:
    """``k of n`` when a method lacks some of the n runs its point's methods hold between them."""
    every = set().union(*(p["run_ids"] for p in here))
    return f"{point['runs']} of {len(every)}" if set(point["run_ids"]) != every else None


PARTIAL = (
    "**Runs `k of n`**: a method that holds k of the n runs the methods of its point hold between them "
    "(an experiment not finished, or a trial on other runs) is averaged over its own runs, on their "
    "test arenas only: its average compares with the others' only loosely, and its interval is wider "
    "(none with one run). Finish its runs (rerun its experiment) to rank it on the same arenas."
)
"""Said under a leaderboard in which some method lacks runs that others hold."""


def bar_plot(path: Path, summary: list[dict], reads: dict[str, list[str] | None] | None = None) -> Path:
    """A panel per point: each method's average success with its 95 % interval, best on top; a
    reference (``reads`` holds a task signal or an expert) in grey, "(reference)" after its name."""
    from nirl_mj.inspect.canvas import subplots

    groups = list(dict.fromkeys((p["axis"], p["value"]) for p in summary))
    columns = min(3, len(groups))
    rows_ = -(-len(groups) // columns)
    height = max(len([p for p in summary if (p["axis"], p["value"]) == g]) for g in groups)
    fig, axes = subplots(rows_, columns, figsize=(4.2 * columns, 0.35 * height * rows_ + 1.2), dpi=110,
                         squeeze=False)  # fmt: skip
    for k, (axis, value) in enumerate(groups):
        ax = axes[k // columns][k % columns]
        here = [p for p in summary if (p["axis"], p["value"]) == (axis, value)][::-1]
        y = range(len(here))
        avg = [100 * p["avg"] for p in here]
        err = [
            [100 * (p["avg"] - p["ci"][0]) if p.get("ci") and p["ci"][0] is not None else 0 for p in here],
            [100 * (p["ci"][1] - p["avg"]) if p.get("ci") and p["ci"][1] is not None else 0 for p in here],
        ]
        reference = [is_reference((reads or {}).get(p["method"]) or []) for p in here]
        ax.barh(list(y), avg, xerr=err, color=["#9a9a9a" if r else "#4c78a8" for r in reference], capsize=3)
        labels = [
            p["method"] + " (reference)" * r + (f" ({k} runs)" if (k := partial_runs(p, here)) else "")
            for p, r in zip(here, reference, strict=True)
        ]
        ax.set_yticks(list(y), labels, fontsize=8)
        ax.set_xlim(0, 100)
        ax.set_xlabel("success (%)")
        ax.set_title(f"{axis} = {value}" if axis else "leaderboard", fontsize=9)
        ax.grid(axis="x", alpha=0.3)
    for k in range(len(groups), rows_ * columns):
        axes[k // columns][k % columns].axis("off")
    fig.tight_layout()
    write_figure(path, fig)
    return path


def write_leaderboard(
    dirs: list[str | Path], out: str | Path, overwrite: bool = False
) -> tuple[str, list[Path]]:
    """Merges ``dirs`` into OUT (module docstring); returns the Markdown table and the files written.
    OUT must be new, empty, or (with ``overwrite``) an earlier leaderboard's."""
    rows, source, reads, notes = merge(list(dirs))
    if not rows:
        raise ExperimentError(
            f"{', '.join(map(str, dirs))}: no finished run to rank (run the experiments first)"
        )
    out = Path(out)
    with DirectoryLock(out, "leaderboard"):  # one writer of OUT (taken once the sources are read)
        return _write(out, dirs, overwrite, rows, source, reads, notes)


def _write(
    out: Path,
    dirs: list[str | Path],
    overwrite: bool,
    rows: list[dict],
    source: dict[str, list[str]],
    reads: dict[str, list[str] | None],
    notes: list[str],
) -> tuple[str, list[Path]]:
    """:func:`write_leaderboard`'s checks of OUT and its files, under OUT's lock."""
    if out.exists():
        # a writer killed mid-write leaves its hidden temporary: not another file, and swept below
        leftovers = leftover_temporaries(out)
        held = {p.name for p in out.iterdir()} - {p.name for p in leftovers} if out.is_dir() else {"?"}
        if held - set(FILES):
            raise ExperimentError(f"{out} holds other files than a leaderboard's; choose another --out")
        if held and not overwrite:
            raise ExperimentError(f"{out} holds a leaderboard; pass --overwrite to replace it")
        if overwrite:
            for path in leftovers:
                path.unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    summary = points(rows)
    table = markdown(summary, source, reads)
    if notes:
        table += (
            "\n\n**Runs on which the merged directories disagree** (the same method and identity):\n\n"
            + ("\n".join(f"- {note}" for note in notes))
        )
    write_text(out / "leaderboard.md", f"# Leaderboard\n\nFrom: {', '.join(f'`{d}`' for d in dirs)}. Success "
               "averaged over each method's runs (95 % Student-t interval); the directories share their "
               f"protocol and test arenas.\n\n{table}\n\n![leaderboard](leaderboard.png)\n")  # fmt: skip
    write_text(out / "leaderboard.csv", tidy.csv_text(rows))
    figure = bar_plot(out / "leaderboard.png", summary, reads)
    files = [out / "leaderboard.md", out / "leaderboard.csv", figure]
    return table, files
