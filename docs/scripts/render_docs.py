"""Every results table of the docs, rendered from stored result files by one command.

    python docs/scripts/render_docs.py            # rewrite every generated block in README.md and docs/
    python docs/scripts/render_docs.py --check    # change nothing; exit 1 naming each block that differs

A generated block in a Markdown page names its renderer and the stored file it reads:

    <!-- generated: compare docs/results/table1_fair/results.json table NIRL,BC,rule -->
    ... (replaced by the renderer's output) ...
    <!-- end generated -->

Renderers (``RENDERERS``):

- ``summary RESULTS_JSON``: a compare experiment's short table (``summary_table.py``);
- ``compare RESULTS_JSON table|runs|paired [METHODS]``: the sections of a compare ``table.md``
  (``nirl_mj.experiments.compare``), for the comma-separated METHODS only if given (the first
  method stays the paired reference);
- ``suite-reading [DIR]``: the suites' reading (``suite_reading.py``, default docs/results/suites);
- ``experiment-index``: the claim/experiment/results index (``experiment_index.py``);
- ``include PATH [code|table]``: a stored output file verbatim (a suite's ``suite.md``, a script's
  output), in a code block with ``code``, or its Markdown table lines alone with ``table``;
- ``main-job FOLDER``: the main job's table as its report gives it, from a folder that
  ``publish_main_job.sh`` filled;
- ``experts FOLDER``: docs/EXPERTS.md's table of the demonstrators, from the rows that
  ``expert_table.py`` stored;
- those of ``algorithm_tables.py``, docs/ALGORITHM.md's own.

``tests/test_docs.py`` runs ``--check`` and also fails when a results table in one of the
``CHECKED`` pages lies outside a generated block.
"""

from __future__ import annotations

import json
import re
import shlex
import sys
from collections.abc import Callable
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))

import algorithm_tables  # noqa: E402
import experiment_index  # noqa: E402
import expert_table  # noqa: E402
import suite_reading  # noqa: E402
import summary_table  # noqa: E402

from nirl_mj.data.atomic import write_text  # noqa: E402
from nirl_mj.experiments import compare, main_job  # noqa: E402

BLOCK = re.compile(r"(<!-- generated: (?P<command>[^>]*?) -->\n)(?P<body>.*?)(<!-- end generated -->)", re.S)
PAGES = ("README.md", "docs/*.md", "docs/notebook/*.md")
CHECKED = ("README.md", "docs/RESULTS.md", "docs/ALGORITHM.md", "docs/EXPERTS.md", "docs/INSPECT.md")
"""The pages whose every results table must be generated (issue 35)."""


def _results(path: str) -> dict:
    summary = json.loads((ROOT / path).read_text(encoding="utf-8"))
    for s in summary["methods"].values():  # JSON turned the run indices into strings
        if "by_run" in s:
            s["by_run"] = {int(r): v for r, v in s["by_run"].items()}
        else:  # a summary from before by_run: per_run holds runs 0..n-1 (their cells' names say so)
            s["by_run"] = dict(enumerate(s.get("per_run", [])))
    return summary


def render_summary(path: str) -> str:
    return summary_table.summary_table(_results(path))


def render_compare(path: str, section: str, methods: str | None = None) -> str:
    summary = _results(path)
    if methods:
        names = methods.split(",")
        missing = [n for n in names if n not in summary["methods"]]
        if missing:
            raise ValueError(f"{path} has no method {', '.join(missing)}")
        summary["methods"] = {n: summary["methods"][n] for n in names}
    sections = {
        "table": compare.markdown_table,
        "runs": compare.runs_section,
        "paired": compare.paired_section,
    }
    if section not in sections:
        raise ValueError(f"compare section {section!r}: one of {', '.join(sections)}")
    return sections[section](summary).strip()


def render_suite_reading(folder: str = "docs/results/suites") -> str:
    return suite_reading.render(ROOT / folder).strip()


def render_experiment_index() -> str:
    return experiment_index.render().strip()


def render_include(path: str, form: str = "text") -> str:
    text = (ROOT / path).read_text(encoding="utf-8").strip()
    if form not in ("text", "code", "table"):
        raise ValueError(f"include {path} {form}: the form is text, code or table")
    if form == "table":  # the file's Markdown table alone (a page elsewhere: its heading and links left out)
        return "\n".join(line for line in text.splitlines() if line.startswith("|"))
    return f"```\n{text}\n```" if form == "code" else text


def render_main_job(folder: str) -> str:
    return main_job.report_table(ROOT / folder)


RENDERERS: dict[str, Callable[..., str]] = {
    "summary": render_summary,
    "compare": render_compare,
    "suite-reading": render_suite_reading,
    "experiment-index": render_experiment_index,
    "include": render_include,
    "main-job": render_main_job,
    "experts": lambda folder: expert_table.render(ROOT / folder),
    **algorithm_tables.RENDERERS,
}


def render_block(command: str) -> str:
    """The text a block's command renders (no surrounding blank lines)."""
    name, *args = shlex.split(command)
    if name not in RENDERERS:
        raise ValueError(f"unknown renderer {name!r}: one of {', '.join(RENDERERS)}")
    return RENDERERS[name](*args)


def pages() -> list[Path]:
    return sorted({p for pattern in PAGES for p in ROOT.glob(pattern)})


def rendered(text: str) -> str:
    """``text`` with every generated block rendered again."""
    return BLOCK.sub(lambda m: f"{m.group(1)}\n{render_block(m.group('command'))}\n\n{m.group(4)}", text)


def stale() -> list[str]:
    """``PAGE: COMMAND`` for every block whose text differs from what its command renders."""
    found = []
    for page in pages():
        text = page.read_text(encoding="utf-8")
        for m in BLOCK.finditer(text):
            if m.group("body") != f"\n{render_block(m.group('command'))}\n\n":
                found.append(f"{page.relative_to(ROOT)}: {m.group('command')}")
    return found


NUMBER = re.compile(r"[-+]?\d+(\.\d+)?\b")


def states_results(rows: list[str]) -> bool:
    """Whether a Markdown table (its lines) states measured figures: at least a third of its body's
    cells, the first column left out, begin with a number (bold or "~" before it included)."""
    cells = [c.strip().lstrip("*~") for row in rows[2:] for c in row.strip().strip("|").split("|")[1:]]
    return bool(cells) and 3 * sum(bool(NUMBER.match(c)) for c in cells) >= len(cells)


def ungenerated_tables(page: Path) -> list[int]:
    """Line numbers (1-based) of the Markdown tables of ``page`` that state results outside a block."""
    text = BLOCK.sub(lambda m: m.group(1) + "\n" * m.group("body").count("\n") + m.group(4), page.read_text())
    found, start = [], None
    lines = text.splitlines()
    for i, line in enumerate([*lines, ""], 1):
        if line.startswith("|"):
            start = start or i
            continue
        if start and states_results(lines[start - 1 : i - 1]):
            found.append(start)
        start = None
    return found


def main() -> None:
    if "--check" in sys.argv:
        problems = stale()
        for problem in problems:
            print(f"stale: {problem}")
        for name in CHECKED:
            for line in ungenerated_tables(ROOT / name):
                problems.append(line)
                print(f"not generated: {name}:{line}")
        sys.exit(1 if problems else 0)
    for page in pages():
        text = page.read_text(encoding="utf-8")
        new = rendered(text)
        if new != text:
            write_text(page, new)
            print(f"rewrote {page.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
