"""bench/report.py rewrites one benchmark's section of docs/PERFORMANCE.md and never drops what a
person wrote in it."""

import importlib.util
from pathlib import Path

_SPEC = importlib.util.spec_from_file_location(
    "bench_report", Path(__file__).resolve().parents[1] / "bench/report.py"
)
_REPORT = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(_REPORT)  # bench/ is no package: loaded by path, leaving sys.path alone
HAND_NOTE, KEPT, write_section = _REPORT.HAND_NOTE, _REPORT.KEPT, _REPORT.write_section


def test_a_rewritten_section_keeps_its_notes_by_hand_and_the_other_sections(tmp_path):
    page = tmp_path / "PERFORMANCE.md"
    page.write_text(
        "# Performance\n\nIntro.\n\n## A\n\nold figures\n\n"
        f"{HAND_NOTE}, day 1: the machine was busy;\nits second line.\n\nold table line\n\n"
        "## B\n\nB's figures\n\nNote (by hand): B's own.\n"
    )
    write_section("A", "| newer | figures |", page)
    text = page.read_text()
    a = text[text.index("## A") : text.index("## B")]
    assert "| newer | figures |" in a and "old figures" not in a and "old table line" not in a
    assert a.index("| newer |") < a.index(KEPT) < a.index(f"{HAND_NOTE}, day 1: the machine was busy;\nits")
    write_section("A", "| newest |", page)  # a third rewrite keeps the note once, under one line
    text = page.read_text()
    assert text.count(KEPT) == 1 and text.count("day 1") == 1 and "| newer |" not in text
    assert text.startswith("# Performance\n\nIntro.\n\n## A\n") and text.endswith(
        "B's figures\n\nNote (by hand): B's own.\n"
    )
    write_section("C", "C's figures", page)
    assert page.read_text().rstrip().endswith("C's figures") and KEPT not in page.read_text().split("## C")[1]
