"""The docs a newcomer reads: tables rendered from stored results, links that lead somewhere, a
README that fits a screenful of sections (issue 35)."""

from __future__ import annotations

import json
import re
import runpy
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RENDER = runpy.run_path(str(ROOT / "docs" / "scripts" / "render_docs.py"))
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
PAGES = [p for p in PAGES if "results" not in p.relative_to(ROOT).parts[:2]]
"""The written pages (the stored reports under docs/results/ are outputs, not pages)."""


def test_every_generated_block_is_what_its_stored_file_renders():
    assert RENDER["stale"]() == [], "run: python docs/scripts/render_docs.py"


@pytest.mark.parametrize("page", RENDER["CHECKED"])
def test_every_results_table_is_generated(page):
    assert RENDER["ungenerated_tables"](ROOT / page) == [], (
        f"{page}: a table of figures outside a generated block (lines above); render it from a stored file"
    )


def test_the_checks_catch_a_typed_table_and_a_stale_block(tmp_path):
    """Both checks can fail: a table of figures typed by hand, and a generated block edited by hand."""
    typed = tmp_path / "typed.md"
    typed.write_text("Text.\n\n| method | success |\n|---|---|\n| NIRL | 97.4 % |\n| BC | 96 |\n\nMore.\n")
    assert RENDER["ungenerated_tables"](typed) == [3]
    bold = tmp_path / "bold.md"
    bold.write_text("| method | success |\n|---|---|\n| NIRL | **97.4 %** |\n| BC | ~96 % |\n")
    assert RENDER["ungenerated_tables"](bold) == [1]
    words = tmp_path / "words.md"
    words.write_text("| key | meaning |\n|---|---|\n| `name` | informational |\n")
    assert RENDER["ungenerated_tables"](words) == []
    block = "<!-- generated: summary docs/results/table1_fair/results.json -->\n"
    good = f"{block}\n{RENDER['render_block']('summary docs/results/table1_fair/results.json')}\n\n"
    good += "<!-- end generated -->"
    assert RENDER["rendered"](good) == good
    edited = good.replace("| NIRL |", "| NIRL (edited) |", 1)
    assert edited != good and RENDER["rendered"](edited) == good
    assert RENDER["ungenerated_tables"](_write(tmp_path / "block.md", good)) == []


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def paragraphs(text: str) -> list[list[str]]:
    """The prose paragraphs of a Markdown page: runs of non-blank lines outside code fences, tables
    and HTML comments; each list item is a paragraph of its own."""
    found: list[list[str]] = []
    current: list[str] = []
    fenced = False
    for line in [*text.splitlines(), ""]:
        if line.startswith("```"):
            fenced = not fenced
        starts_item = re.match(r"\s*([-*]|\d+\.) ", line) is not None
        prose = not fenced and line.strip() and not line.startswith(("|", "<!--", "```", "#", "!["))
        if not prose or starts_item:
            if current:
                found.append(current)
            current = [line] if prose else []
            continue
        current.append(line)
    return found


def test_the_readme_is_a_front_door():
    """At most 200 lines, no paragraph over 6 lines, the two commands first, no dated history."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 200
    longest = max(paragraphs(text), key=len)
    assert len(longest) <= 6, "a README paragraph over 6 lines:\n" + "\n".join(longest)
    first = text.split("```bash\n", 1)[1].split("```", 1)[0].splitlines()
    assert first[0].startswith("bash .ci/setup && .venv/bin/nirl-mj run")
    assert first[1].startswith(".venv/bin/python -m pytest -q")
    assert not re.search(r"\b(since|before|until) 20\d\d-\d\d-\d\d", text), "a dated history in the README"


def test_the_paragraph_counter_counts():
    text = "one\ntwo\nthree\n\n- item\n  more\n- next\n\n```\nx\ny\n```\n| a |\n"
    assert [len(p) for p in paragraphs(text)] == [3, 2, 1]


def test_algorithm_md_describes_the_default_in_at_most_400_lines():
    assert len((ROOT / "docs" / "ALGORITHM.md").read_text(encoding="utf-8").splitlines()) <= 400


PAPER_TITLE = "Neural Inverse Reinforcement Learning with a Nonlinear Policy Representation"
"""The title of the stored paper, ../shared/paper/nirl-paper.md; it names no authors and no venue."""


def test_the_paper_is_cited_by_its_stored_title_alone():
    """README.md, the docs, the stored reports and the code cite the NIRL paper by the title of the stored
    copy, with no authors or venue that copy cannot confirm."""
    from nirl_mj.inspect.figures import NIRL_PAPER

    assert NIRL_PAPER == f"*{PAPER_TITLE}*"
    for page in ("README.md", "docs/ALGORITHM.md"):
        assert f"*{PAPER_TITLE}*" in " ".join((ROOT / page).read_text(encoding="utf-8").split()), page
    places = ("README.md", "docs", "nirl_mj", "tasks", "bench", "examples", "notebooks")
    files = [f for place in places for f in sorted((ROOT / place).rglob("*")) if (ROOT / place).is_dir()]
    files = [ROOT / "README.md", *(f for f in files if f.suffix in (".md", ".py", ".toml", ".ipynb", ".sh"))]
    for file in files:
        found = re.findall(r"\bXia\b|El Kamel|Autonomous\s+Systems", file.read_text(encoding="utf-8"))
        assert not found, (str(file.relative_to(ROOT)), found)


def slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


LINK = re.compile(r"\]\(([^)\s]+)\)")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_leads_to_a_file_and_its_heading(page):
    """A newcomer clicking through README and docs/ never lands on a missing file or anchor."""
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    broken = []
    for target in LINK.findall(text):
        if re.match(r"[a-z]+:", target):
            continue  # a web address
        path, _, anchor = target.partition("#")
        where = (page.parent / path).resolve() if path else page
        if not where.exists():
            broken.append(target)
        elif anchor and where.suffix == ".md":
            headings = re.findall(r"^#+ (.+)$", where.read_text(encoding="utf-8"), flags=re.M)
            if anchor not in {slug(h) for h in headings}:
                broken.append(target)
    assert broken == []


def test_reproduce_cells_tells_a_missing_metric_from_a_different_result(tmp_path):
    """docs/scripts/reproduce_cells.py on hand-built cells: equal results are identical; a metric the
    published cell predates is named but is no difference, one the new cell lacks is; a changed
    success is, with the run's selected iteration and its ties; restored, reused and unpublished
    cells are counted apart; the platforms the cells recorded are named; a directory with nothing to
    compare is refused."""
    import json

    report = runpy.run_path(str(ROOT / "docs" / "scripts" / "reproduce_cells.py"))["report"]
    result = {"method": "M", "run": 0, "success_rate": 0.84, "spl": 0.81, "sct": 0.8}
    published = {
        "A-run000": dict(result),
        "B-run000": {k: v for k, v in result.items() if k != "sct"},
        "C-run000": {**result, "success_rate": 0.77, "spl": 0.74},
        "D-run000": {**result, "tests": 100},
        "E-run000": dict(result),
        "F-run000": dict(result),
    }
    (tmp_path / "cells").mkdir()
    extras = {
        "A": {"platform": "Vendor/AVX9"},
        "B": {},
        "C": {},
        "D": {},
        "E": {"restored_from": "x"},
        "F": {"reused_from": "y"},
        "G": {},
    }
    for name, extra in extras.items():
        cell = {"id": f"{name}-run000", "result": result, **extra}
        (tmp_path / "cells" / f"{name}-run000.json").write_text(json.dumps(cell))
    run = tmp_path / "runs" / "M" / "0"
    run.mkdir(parents=True)
    (run / "run.json").write_text(
        json.dumps({"selection": {"rule": "demo_balanced"}, "selected_iteration": 2})
    )
    scores = [0.5, 0.7, 0.7, 0.6]
    (run / "metrics.jsonl").write_text(
        "".join(json.dumps({"episode": e, "demo_balanced_accuracy": s}) + "\n" for e, s in enumerate(scores))
    )
    lines = report(tmp_path, published).splitlines()
    assert lines[:4] == [
        "A-run000: identical",
        "B-run000: identical; keys: sct (not published)",
        "C-run000: differs (success 84 %, SPL 0.81 against the published success 77 %, SPL 0.74; "
        "selected iteration 2, one of 2 at its score); keys: success_rate, spl",
        "D-run000: differs (success 84 %, SPL 0.81 against the published success 84 %, SPL 0.81; "
        "selected iteration 2, one of 2 at its score); keys: tests (not computed)",
    ]
    assert lines[4].startswith(
        "2 identical, 2 differ; left out: 2 restored or reused, 1 not published; "
        "computed on (not recorded), Vendor/AVX9; run on "
    )
    assert len(lines) == 5
    for name in "ABCD":
        (tmp_path / "cells" / f"{name}-run000.json").unlink()
    with pytest.raises(SystemExit, match="no cell to compare .2 restored or reused, 1 not in the published"):
        report(tmp_path, published)


def test_paired_runs_takes_any_two_methods_as_the_tables_take_the_first():
    """docs/scripts/paired_runs.py on Table I's stored results: NIRL minus another equals the stored
    paired figure; the order of the two flips its sign; an unknown method is refused."""
    import json

    paired = runpy.run_path(str(ROOT / "docs" / "scripts" / "paired_runs.py"))["paired"]
    results = json.loads((ROOT / "docs" / "results" / "table1_fair" / "results.json").read_text())
    stored = results["methods"]["DQN-reward"]["paired"]
    mine = paired(results, "NIRL", "DQN-reward")
    assert [mine[k] for k in ("runs", "better", "worse")] == [stored[k] for k in ("runs", "better", "worse")]
    assert mine["mean"] == pytest.approx(stored["mean"]) and mine["ci"] == pytest.approx(stored["ci"])
    flipped = paired(results, "DQN-reward", "NIRL")
    assert flipped["mean"] == pytest.approx(-mine["mean"]) and flipped["better"] == mine["worse"]
    with pytest.raises(SystemExit, match="no method 'DQN'"):
        paired(results, "rule", "DQN")
    # the second method from another file: here one whose rule row is shifted by 1 point in run 0
    shifted = json.loads(json.dumps(results))
    shifted["methods"]["rule"]["by_run"]["0"] -= 0.01
    against = paired(results, "rule", "rule", shifted)
    assert against["mean"] == pytest.approx(0.01 / len(results["methods"]["rule"]["by_run"]))
    assert (against["better"], against["worse"]) == (1, 0)
    with pytest.raises(SystemExit, match="no method 'NIRL-x'"):
        paired(results, "rule", "NIRL-x", shifted)


def test_rl_free_actions_reads_each_free_state_by_sector_and_flag():
    """docs/scripts/rl_free_actions.py: the 18 free states are V = 1..9 with I = 0, then with I = 1,
    every danger and wall feature 0; a policy's actions come back as letters in that order."""
    script = runpy.run_path(str(ROOT / "docs" / "scripts" / "rl_free_actions.py"))
    states = script["free_states"]()
    assert states.shape == (18, 16) and not states[:, :7].any() and not states[:, 9:].any()
    assert states[:, 7].tolist() == [*range(1, 10)] * 2 and states[:, 8].tolist() == [0] * 9 + [1] * 9
    # forward with I = 0; with I = 1, sector 1 forward, 2-3 left30, 4-5 left60, 6-7 right60, 8-9 right30
    by_sector = {1: 0, 2: 1, 3: 1, 4: 2, 5: 2, 6: 4, 7: 4, 8: 3, 9: 3}
    line = script["actions_line"](lambda phi: by_sector[int(phi[7])] if phi[8] else 0)
    assert line == "FFFFFFFFF | FllLLRRrr"


def test_cycle_coverage_counts_the_cycle_pairs_the_demonstrations_show_and_agree_with(
    tmp_path, monkeypatch, capsys
):
    """docs/scripts/cycle_coverage.py: the (state, action) pairs of a timeouts.py output, counted once
    per cycle, joined with the demonstrated pairs by the text ``phi_text`` writes for phi(s), in a
    fixed order; on a hand-built dataset: 4 pairs (one in two cycles), 3 demonstrated (one where the
    expert's actions tie), 2 agreeing (the tie counts). The stored replay of the unseen
    seeds' run 16 reads as an orbit in sectors 3 and 4; a dataset of continuous actions is refused."""
    import numpy as np

    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.data.trajectory import Trajectory
    from nirl_mj.inspect.text import phi_text
    from nirl_mj.sim import spec

    script = runpy.run_path(str(ROOT / "docs" / "scripts" / "cycle_coverage.py"))
    stored = (ROOT / "docs" / "results" / "table1_fresh" / "timeouts-NIRL-run16.txt").read_text()
    orbit = {("D 0000000 V 3 I 1 U 0000000", "left30"): 16, ("D 0000000 V 4 I 1 U 0000000", "left60"): 7}
    assert script["cycle_pairs"](stored) == orbit

    def dataset(name: str, actions: np.ndarray, kind: str = "discrete") -> str:
        task = spec.apply_overrides(spec.load_task("navigate"), [f"control.actions={kind}"]).to_dict()
        states = np.zeros((5, 16), np.float32)
        states[:, 7] = 1
        states[:4, 0] = [3, 1, 2, 2]  # danger ahead 3, 1, 2, 2; the final state unused
        demo = Trajectory(features=states, actions=actions, ranges=np.zeros((5, 9)), poses=np.zeros((5, 3)),
                          times=np.arange(5) * 0.5, arena_seed=1, task=task, speed=2.0, outcome="target",
                          demonstrator="sensor")  # fmt: skip
        return str(save_dataset(tmp_path / name, [demo]))

    # forward, forward, backward, forward: the expert ties backward and forward at danger 2
    demos = dataset("demos.npz", np.array([0, 0, 5, 0], np.int8))
    d = {level: phi_text(np.array([level, *[0] * 6, 1, *[0] * 8])) for level in (1, 2, 3, 4)}
    assert d[3] == "D 3000000 V 1 I 0 U 0000000"
    timeouts = tmp_path / "timeouts.txt"
    timeouts.write_text(
        "arena 0: timeout in a cycle of 3 (backward, backward, forward) over its last 30 decisions, "
        f"within 1.0 m, r_theta +0.1 per decision; states: {d[3]}; {d[4]}; {d[1]}\n"
        "arena 1: timeout in a cycle of 2 (forward, backward) over its last 30 decisions, "
        f"within 1.0 m, r_theta +0.1 per decision; states: {d[1]}; {d[2]}\n"
    )
    monkeypatch.setattr("sys.argv", ["cycle_coverage.py", str(timeouts), demos])
    script["main"]()
    assert capsys.readouterr().out.splitlines() == [
        f"{demos}: 4 demonstrated pairs; the cycles of {timeouts}:",
        f"  {d[1]}: policy forward (in 2 cycles); expert: forward 1",
        f"  {d[2]}: policy backward (in 1 cycles); expert: backward 1, forward 1",
        f"  {d[3]}: policy backward (in 1 cycles); expert: forward 1",
        f"  {d[4]}: policy backward (in 1 cycles); expert: never demonstrated",
        "4 (state, action) pairs in the cycles: 3 in demonstrated states, 2 of those the expert's most "
        "frequent action there (or one of those tied)",
    ]
    continuous = dataset("continuous.npz", np.zeros((4, 2), np.float32), "continuous")
    monkeypatch.setattr("sys.argv", ["cycle_coverage.py", str(timeouts), continuous])
    with pytest.raises(SystemExit, match="continuous actions"):
        script["main"]()
    with pytest.raises(ValueError, match="2 actions lists 1 states"):
        script["cycle_pairs"](
            "timeout in a cycle of 2 (forward, backward) over 30 decisions; states: D 1000000 V 1 I 0"
        )


def test_suite_versus_pairs_two_suite_csvs_by_point_and_run(tmp_path):
    """docs/scripts/suite_versus.py: first minus second per (axis, value) over the runs both hold, on a
    hand-computed case; the stored suites and their decaying-step predecessors share BC's rows
    exactly (the same seeds, demonstrations and test arenas), which is what makes NIRL's pair, but
    for the cells whose early-stopping scores tied, which the one tie rule (6c30c7d) changed."""
    versus = runpy.run_path(str(ROOT / "docs" / "scripts" / "suite_versus.py"))["versus"]
    head = "suite,axis,value,method,run,tests,success,collision,timeout,spl,sct\n"
    first, second = tmp_path / "a.csv", tmp_path / "b.csv"
    first.write_text(head + "".join(f"s,n,1,X,{r},10,{v},0,0,0,0\n" for r, v in enumerate([0.9, 0.8, 1.0])))
    second.write_text(head + "s,n,1,X,0,10,0.7,0,0,0,0\ns,n,1,X,1,10,0.8,0,0,0,0\ns,n,2,X,0,10,0.1,0,0,0,0\n")
    (point, pair), *rest = versus(first, second, "X").items()
    assert point == ("n", "1") and rest == []  # value 2 and run 2 are in one file only
    assert pair["runs"] == 2 and pair["mean"] == pytest.approx(0.1)
    assert [pair["better"], pair["worse"], pair["equal"]] == [1, 0, 1]
    with pytest.raises(SystemExit, match="no point of 'Y'"):
        versus(first, second, "Y")
    with pytest.raises(SystemExit, match="cannot read .*missing.csv"):
        versus(first, tmp_path / "missing.csv", "X")
    (tmp_path / "other.csv").write_text("method,run\nX,0\n")
    with pytest.raises(SystemExit, match="is not a suite CSV"):
        versus(first, tmp_path / "other.csv", "X")
    stored, before = (ROOT / "docs" / "results" / name for name in ("suites", "suites_decaying_step"))
    retied = {("demos", "3"): 3, ("demos", "10"): 1, ("quality", "sensor-late2"): 1}  # (suite, value): cells
    for suite in ("demos", "quality", "transfer"):
        bc = versus(stored / f"{suite}.csv", before / f"{suite}.csv", "BC")
        assert bc and all(p["runs"] - p["equal"] == retied.get((suite, v), 0) for (_, v), p in bc.items())


def test_suite_reading_marks_a_pair_with_other_than_five_runs():
    """A paired difference over the 5 runs the caption names carries no n; over 1 run it is that run's
    difference (not the two rows' means over their own runs), with n; over none, a dash."""
    interval = runpy.run_path(str(ROOT / "docs" / "scripts" / "suite_reading.py"))["interval"]
    five = {r: 0.5 for r in range(5)}
    assert interval({r: 0.6 for r in range(5)}, five) == "+10.0 [+10.0, +10.0]"
    assert interval({0: 0.9, 7: 0.0}, {0: 0.5, 8: 1.0}) == "+40.0 (n = 1)"
    assert interval({0: 0.9}, {1: 0.5}) == "-"


def test_suite_reading_pairs_map_on_and_off_and_every_learner_against_the_clone(tmp_path):
    """docs/scripts/suite_reading.py on a hand-built quality and demos suite: NIRL-MAP minus NIRL (the
    paper's pretreatment on minus off), each other learner minus BC and NIRL minus each, paired by
    run, a row per pair in a table per axis; a pair with no common point is left out."""
    render = runpy.run_path(str(ROOT / "docs" / "scripts" / "suite_reading.py"))["render"]
    head = "suite,axis,value,method,run,tests,success,collision,timeout,spl,sct\n"
    quality = {"NIRL": [0.5, 0.6], "NIRL-MAP": [0.7, 0.7], "NIRL-MAP-majority": [0.6, 0.6], "BC": [0.2, 0.2],
               "expert": [0.9, 0.9]}  # fmt: skip
    (tmp_path / "quality.csv").write_text(head + "".join(
        f"quality,demonstrator,{point},{m},{r},10,{v},0,0,0,0\n"
        for point in ("sensor", "sensor-random30") for m, vs in quality.items() for r, v in enumerate(vs)
    ))  # fmt: skip
    demos = {"NIRL": [0.9, 0.8], "BC": [0.4, 0.6], "AL": [0.5, 0.7], "AIRL": [0.0, 0.05], "rule": [1.0, 1.0]}
    (tmp_path / "demos.csv").write_text(head + "".join(
        f"demos,demonstrations,{point},{m},{r},10,{v},0,0,0,0\n"
        for point in (3, 30) for m, vs in demos.items() for r, v in enumerate(vs)
    ) + "demos,demonstrations,100,SCIRL,0,10,0.5,0,0,0,0\n")  # fmt: skip
    text = render(tmp_path)
    # NIRL-MAP minus NIRL: differences 0.2 and 0.1, mean 15 points; t(1) interval 0.15 +- 12.706 * 0.05.
    # Its row in the demonstrator table: sensor, then sensor-random30.
    assert "| demonstrator | sensor | sensor-random30 |" in text
    assert "| NIRL-MAP minus NIRL | +15.0 [-48.5, +78.5] (n = 2) | +15.0 [-48.5, +78.5] (n = 2) |" in text
    # NIRL-MAP-majority minus NIRL: 0.1 and 0.0, mean 5 points, half-width 12.706 * 0.05
    assert "| NIRL-MAP-majority minus NIRL | +5.0 [-58.5, +68.5] (n = 2) |" in text
    # AL minus BC: 0.1 in both runs, no spread; 100 demonstrations: neither has a run there.
    assert "| demonstrations | 3 | 30 | 100 |" in text
    assert "| AL minus BC | +10.0 [+10.0, +10.0] (n = 2) | +10.0 [+10.0, +10.0] (n = 2) | - |" in text
    assert "| NIRL minus AL |" in text  # NIRL against every other learner too
    assert "rule minus BC" not in text and "SCIRL minus BC" not in text  # a reference; no common point
    # the same success at 3 as at 30; AIRL's 2.5 % at 30 is under the 10 % a share is taken of
    assert "| NIRL | 85.0 | 3 | +0.0 [+0.0, +0.0] (n = 2) |" in text
    assert "| AIRL | 2.5 | - (under 10 %) | +0.0 [+0.0, +0.0] (n = 2) |" in text
    assert "(transfer: not computed yet)" in text


def test_iterate_study_picks_the_first_and_the_last_of_the_best_scores():
    """docs/scripts/iterate_study.py: the loop's rule before 6c30c7d (first best) and today's (latest
    best), on ties and without."""
    import numpy as np

    script = runpy.run_path(str(ROOT / "docs" / "scripts" / "iterate_study.py"))
    picks = script["picks"]
    assert picks(np.array([0.2, 1.0, 0.5, 1.0, 0.9])) == {"first_best": 1, "last_best": 3}
    assert picks(np.array([0.2, 0.7, 0.5])) == {"first_best": 1, "last_best": 1}
    with pytest.raises(SystemExit, match="not a training run of the IRL loop"):
        script["study"](ROOT / "no-such-run", 1, 10)


def test_early_stop_ties_names_the_first_and_latest_best_epoch_of_each_tied_fit():
    """docs/scripts/early_stop_ties.py on hand-written scores: a fit is listed only when its best
    score was reached at more than one epoch, with the first and the latest of them (from 1)."""
    tied_fits = runpy.run_path(str(ROOT / "docs" / "scripts" / "early_stop_ties.py"))["tied_fits"]
    fits = [[0.5, 0.7, 0.7, 0.6], [0.1, 0.9], [0.3, 0.3, 0.3], [0.2, 0.8, 0.4, 0.8]]
    assert tied_fits(fits) == [(0, 2, 3), (2, 1, 3), (3, 2, 4)]
    assert tied_fits([]) == []


def test_the_architecture_figure_shows_the_modules_as_they_are():
    """docs/images/architecture.png holds the rooms and modules it was drawn from (a PNG text chunk):
    a module added or moved since needs `python docs/scripts/architecture_figure.py`."""
    from PIL import Image

    script = runpy.run_path(str(ROOT / "docs" / "scripts" / "architecture_figure.py"))
    with Image.open(ROOT / "docs" / "images" / "architecture.png") as image:
        drawn = json.loads(image.text["Description"])
    assert drawn == script["rooms"](), "run python docs/scripts/architecture_figure.py"


def test_refit_last_starts_from_the_runs_last_iterate_and_fits_only_the_network(tmp_path):
    """docs/scripts/refit_last.py: the learner rebuilt from a run's checkpoint acts as the run's last
    iterate (``load_policy(run, "last")``) in every demonstrated state; a further round changes the
    network."""
    import numpy as np

    from nirl_mj.data.dataset import save_dataset
    from nirl_mj.experiments.demos import ExpertConfig, collect
    from nirl_mj.experiments.training import load_policy, train
    from nirl_mj.learn import network
    from nirl_mj.learn.config import LearnerConfig
    from nirl_mj.sim import spec

    task = spec.replace(
        spec.load_task("navigate"),
        arena={"size": [16.0, 16.0], "start": [3.0, 3.0], "target": [13.0, 13.0], "static_obstacles": 2,
               "clear_radius": 2.0},
        robot={"drive": "planar"},
    )  # fmt: skip
    demos = tmp_path / "demos.npz"
    save_dataset(demos, collect(task, ExpertConfig("sensor"), episodes=2, seed=0))
    config = LearnerConfig.preset("default", episodes=3, trajectories_per_episode=2, replay_episodes=2)
    train(tmp_path / "run", task, demos, config, seed=0)
    script = runpy.run_path(str(ROOT / "docs" / "scripts" / "refit_last.py"))
    learner = script["last_iterate"](str(tmp_path / "run"), str(demos))
    last, _ = load_policy(tmp_path / "run", "last")
    greedy = network.greedy_actions(network.q_values(learner.net, learner.demo_inputs))
    assert list(greedy) == [last(phi) for phi in learner.demo_phi]
    before = network.get_weights(learner.net)
    script["refit"](learner, 1)
    assert not np.array_equal(network.get_weights(learner.net)["W2"], before["W2"])


def test_end_checks_lists_each_run_s_candidates_and_the_change(tmp_path, capsys, monkeypatch):
    """docs/scripts/end_checks.py: one line per run by seed, each candidate as iteration: score,
    ended/N, "changed" where the kept iterate is not the rule's; the count of changed runs; a run
    without the check is a one-line error. The stored development listing says run 2018 changed,
    alone."""
    import json
    import sys

    script = runpy.run_path(str(ROOT / "docs" / "scripts" / "end_checks.py"))
    keep = {"first_round_best": 3, "iteration": 3, "end_check_arenas": 20,
            "candidates": {"3": {"score": 0.6, "ended": 20}, "9": {"score": 0.5, "ended": 20}}}  # fmt: skip
    move = {"first_round_best": 4, "iteration": 9, "end_check_arenas": 20,
            "candidates": {"4": {"score": 0.7, "ended": 12}, "9": {"score": 0.55, "ended": 19}}}  # fmt: skip
    lines = script["lines"]({7: {"selection": move}, 5: {"selection": keep}})
    assert lines[1] == "5       3     3  3: 0.600, 20/20, 9: 0.500, 20/20"
    assert lines[2] == "7       4     9  4: 0.700, 12/20, 9: 0.550, 19/20  changed"
    assert lines[3] == "1 of 2 runs keep another iterate than the rule's"
    stored = (ROOT / "docs" / "results" / "end_check" / "end-checks.txt").read_text().splitlines()
    assert [line.split()[0] for line in stored if line.endswith("changed")] == ["2018"]
    assert stored[-1] == "1 of 20 runs keep another iterate than the rule's"
    run = tmp_path / "runs" / "M" / "0"
    run.mkdir(parents=True)
    (run / "run.json").write_text(json.dumps({"selection": {"rule": "demo_balanced", "iteration": 2}}))
    monkeypatch.setattr(sys, "argv", ["end_checks.py", str(tmp_path), "M"])
    with pytest.raises(SystemExit, match="holds no end check"):
        runpy.run_path(str(ROOT / "docs" / "scripts" / "end_checks.py"), run_name="__main__")
