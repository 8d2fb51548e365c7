"""The index of experiment files in docs/EXPERIMENTS.md: which file backs which claim, run by which
command, with its results where.

Rendered from the files themselves: every TOML under tasks/ with a top-level ``kind`` (an experiment
file), its ``description``, the command that runs it, its stored results (docs/results/NAME/, or
docs/results/suites/NAME.* for a suite, or the folder the tests' RECORDED table names) and the docs
that cite it (README.md, RESULTS, ALGORITHM, EXTENDING and the notebook; not PERFORMANCE.md,
which the benchmarks rewrite). docs/EXPERIMENTS.md holds it in a generated block
(``experiment-index``), rewritten by ``python docs/scripts/render_docs.py`` and checked by
tests/test_docs.py.

    python docs/scripts/experiment_index.py      # print it
"""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RECORDED = {"table1_v2": "table1_extended", "table1": "table1_fair", "table1_nirl": "table1_fair"}
"""A file whose results folder has another name (as tests/test_experiments.py's RECORDED)."""
DOCS = (
    "README.md",
    "docs/RESULTS.md",
    "docs/ALGORITHM.md",
    "docs/EXTENDING.md",
    "docs/notebook/results.md",
    "docs/notebook/algorithm.md",
)


def results_of(path: Path, kind: str) -> str:
    name = path.stem
    if kind == "suite":
        found = sorted((ROOT / "docs" / "results" / "suites").glob(f"{name}.*"))
        return ", ".join(f"`{p.relative_to(ROOT)}`" for p in found if p.suffix in (".csv", ".md")) or "-"
    folder = ROOT / "docs" / "results" / RECORDED.get(name, name)
    return f"`{folder.relative_to(ROOT)}/`" if folder.is_dir() else "-"


def cited_in(path: Path) -> str:
    rel = str(path.relative_to(ROOT))
    cited = [d for d in DOCS if (ROOT / d).is_file() and rel in (ROOT / d).read_text(encoding="utf-8")]
    return ", ".join(cited) or "-"


def render() -> str:
    rows = ["| file | kind | what | run | results | cited in |", "|---|---|---|---|---|---|"]
    for path in sorted((ROOT / "tasks").rglob("*.toml")):
        data = tomllib.loads(path.read_text(encoding="utf-8"))
        kind = data.get("kind")
        if kind is None:
            continue  # a task file
        rel = path.relative_to(ROOT)
        what = str(data.get("description", "")).replace("|", "/")
        run = f"`nirl-mj {kind} --task {rel}`"
        rows.append(f"| `{rel}` | {kind} | {what} | {run} | {results_of(path, kind)} | {cited_in(path)} |")
    return "\n".join(rows)


def main() -> None:
    print(render())


if __name__ == "__main__":
    main()
