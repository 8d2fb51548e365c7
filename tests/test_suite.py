"""Suites (``nirl-mj suite``): axes validated like any experiment key, tidy CSV rows equal to the cells,
a killed suite resumed without recomputation, navigation metrics by hand, the named demonstrators."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from helpers import TINY_CONFIG, TINY_TABLES, cell_times, killed_after_cells

from nirl_mj.cli import main
from nirl_mj.data.outcomes import metrics_of, sct, spl
from nirl_mj.data.trajectory import Trajectory
from nirl_mj.experiments.definition import ExperimentError, from_dict, load_experiment
from nirl_mj.experiments.demos import ExpertConfig
from nirl_mj.experiments.suite import CSV_COLUMNS
from nirl_mj.experts.late import LateExpert
from nirl_mj.sim import spec

ROOT = Path(__file__).resolve().parents[1]

TOP = "runs = 2\ntests = 2\n"  # before the head: keys after an [[axis]] table belong to it
TINY = TINY_TABLES + TINY_CONFIG
TRAINING = """kind = "suite"
methods = ["NIRL", "BC", "rule", "expert"]
[[axis]]
name = "demonstrator"
values = ["sensor", "sensor-random30"]
"""
TRANSFER = """kind = "suite"
methods = ["BC", "rule"]
[[axis]]
name = "obstacles"
values = [1, 3]
[[axis]]
name = "speed"
values = [1.0, 2.0]
"""


def write(tmp: Path, head: str, name: str) -> Path:
    path = tmp / f"{name}.toml"
    path.write_text(TOP + head + TINY)
    return path


def args(spec_path: Path, out: Path, *extra: str) -> list[str]:
    return ["suite", "--task", str(spec_path), "--out", str(out), "--executor", "serial", "--quiet", *extra]


def cells(out: Path) -> dict:
    return {p.stem: json.loads(p.read_text())["result"] for p in sorted((out / "cells").glob("*.json"))}


@pytest.fixture(scope="module")
def training_suite(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("suite")
    path, out = write(tmp, TRAINING, "training"), tmp / "out"
    assert main(args(path, out, "--json")) == 0
    return path, out, cells(out)


# -- the file -----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("axis", "message"),
    [
        (None, "a suite needs at least one [[axis]] table"),
        ([{"name": "clutter", "values": [1]}], "axis[0].name = 'clutter': accepted: demonstrations, demo"),
        ([{"name": "obstacles", "values": []}], "axis[0].values: list at least one value"),
        ([{"name": "obstacles", "values": 5}], "axis[0].values = 5: expected a list"),
        ([{"name": "obstacles", "values": [5, "many"]}], "values[1] = 'many': expected a whole number"),
        ([{"name": "speed", "values": [1.0, 1]}], "every value must differ"),
        ([{"name": "speed", "values": [9.0]}], "axis[0]: speed = 9: "),
        ([{"name": "demonstrations", "values": [0]}], "axis[0].values[0] = 0: must be >= 1"),
        ([{"name": "demonstrator", "values": ["human"]}], "axis[0].values[0] = 'human': accepted: planner"),
        ([{"name": "family", "values": ["maze"]}], "axis[0].values[0] = 'maze': accepted: random, corridors"),
        ([{"name": "obstacles", "values": [1], "step": 2}], "axis[0]: unknown key(s) step; accepted: name"),
        ([{"name": "demonstrations", "values": [1], "test_task": "structured"}], "only a test axis"),
        ([{"name": "demonstrations", "values": [1]}, {"name": "speed", "values": [1.0]}],
         "must be the suite's only axis"),
        ([{"name": "speed", "values": [1.0]}, {"name": "speed", "values": [2.0]}], "an axis is given twice"),
        ("speed", "axis = 'speed': expected a list"),
    ],
)  # fmt: skip
def test_a_bad_axis_is_one_error_naming_the_key(axis, message):
    data = {"kind": "suite"} if axis is None else {"kind": "suite", "axis": axis}
    with pytest.raises(ExperimentError) as err:
        from_dict(data, "s.toml")
    assert message in str(err.value) and str(err.value).startswith("s.toml")
    assert "\n" not in str(err.value)


def test_an_axis_test_task_takes_the_robot_of_set_but_keeps_its_arenas():
    data = {"kind": "suite", "set": {"arena": {"static_obstacles": 20}, "robot": {"drive": "rollers"},
                                     "control": {"speed": 1.0}},
            "axis": [{"name": "family", "values": ["pockets"], "test_task": "structured"}]}  # fmt: skip
    task = from_dict(data, "s.toml").axes[0].task_at("pockets")
    assert (task.robot.drive, task.control.speed) == ("rollers", 1.0)
    assert task.arena.static_obstacles == spec.load_task("structured").arena.static_obstacles != 20


def test_an_axis_belongs_to_suites_only():
    with pytest.raises(ExperimentError, match=r"unknown key\(s\) axis \(kind compare\)"):
        from_dict({"kind": "compare", "axis": [{"name": "speed", "values": [1.0]}]}, "s.toml")


def test_check_runs_and_writes_nothing_and_says_what_would_run(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text('kind = "suite"\nmethods = ["NIRL", "rule"]\nruns = 2\nseed = 7\n[[axis]]\n'
                    'name = "speed"\nvalues = [1.0, 2.0]\n[quick]\nruns = 1\ntests = 5\n')  # fmt: skip
    out = tmp_path / "out"
    assert main(["suite", "--task", str(path), "--out", str(out), "--check"]) == 0
    text = capsys.readouterr().out
    assert (
        "a valid suite experiment" in text
        and "runs 2 (seeds 7..8)" in text
        and "axis speed: 1.0, 2.0" in text
    )
    assert "rule (rule, a reference): reads features, hand_written" in text and "\nset: none\n" in text
    assert f"output: {out} (does not exist yet)" in text and not out.exists()
    # an output of this experiment, of another one, of something else
    (out / "cells").mkdir(parents=True)
    (out / "cells" / "NIRL-run000.json").write_text("{}")
    assert main(["suite", "--task", str(path), "--out", str(out), "--check", "--quick"]) == 0
    assert "holds no nirl-mj experiment: a run would refuse it" in capsys.readouterr().out
    (out / "experiment.json").write_text(json.dumps(load_experiment(path, quick=True).identity()))
    assert main(["suite", "--task", str(path), "--out", str(out), "--check", "--quick"]) == 0
    text = capsys.readouterr().out
    assert (
        "(--quick)" in text and "runs 1 (seeds 7..7)" in text and "holds this experiment, 1 finished" in text
    )
    assert main(["suite", "--task", str(path), "--out", str(out), "--check"]) == 0
    assert "holds another experiment (it differs in: tests)" in capsys.readouterr().out
    # what a run refuses before it starts, --check refuses too
    for flags, message in ((["--only", "NOPE"], "--only NOPE: not a method"),
                           (["--points", "3"], "--points picks values of a training axis"),
                           (["--restore", str(tmp_path / "none")], "no such directory"),
                           (["--runs", "3"], None)):  # fmt: skip
        code = main(["suite", "--task", str(path), "--out", str(tmp_path / "o2"), "--check", *flags])
        assert code == (0 if message is None else 2) and (
            message is None or message in capsys.readouterr().err
        )
    path.write_text(path.read_text().replace("seed = 7", f"seed = {2**32 - 3}"))
    assert main(["suite", "--task", str(path), "--out", str(out), "--check", "--runs", "4"]) == 2
    assert "--runs with the file's seed = 4294967293 with runs = 4" in capsys.readouterr().err
    path.write_text(path.read_text() + "[quick.demos]\nepisodez = 3\n")
    assert main(["suite", "--task", str(path), "--out", str(out), "--check"]) == 2
    assert "quick.demos: unknown key(s) episodez" in capsys.readouterr().err


def test_check_names_the_set_overrides_of_the_file_and_of_its_quick_table(tmp_path, capsys):
    path = tmp_path / "c.toml"
    path.write_text('kind = "compare"\nmethods = ["rule"]\n[set.arena]\nstatic_obstacles = 20\n'
                    '[set.control]\nspeed = 2.0\n[quick]\ntests = 5\n[quick.set.arena]\n'
                    'static_obstacles = 3\n[quick.set.robot]\ndrive = "planar"\n')  # fmt: skip
    out = str(tmp_path / "out")
    assert main(["compare", "--task", str(path), "--out", out, "--check"]) == 0
    assert "\nset: arena.static_obstacles=20, control.speed=2.0\n" in capsys.readouterr().out
    assert main(["compare", "--task", str(path), "--out", out, "--check", "--quick"]) == 0
    text = capsys.readouterr().out
    assert '\nset: arena.static_obstacles=3, control.speed=2.0, robot.drive="planar"\n' in text
    assert not (tmp_path / "out").exists()


def test_a_suite_error_on_the_command_line_is_one_error_line(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text('kind = "suite"\n[[axis]]\nname = "obstacles"\nvalues = []\n')
    assert main(["suite", "--task", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("nirl-mj suite: error:") and "axis[0].values" in err[0]
    assert not (tmp_path / "out").exists()  # nothing made before the file is valid


def test_the_shipped_suites_load_with_their_axes():
    demos = load_experiment("suites/demos")
    assert [(a.name, a.values) for a in demos.axes] == [("demonstrations", (1, 3, 10, 30, 100))]
    assert demos.at(3).demos == 3 and demos.at(3).kind == "compare"
    quality = load_experiment("suites/quality")
    (axis,) = quality.axes
    assert axis.values[0] == "sensor" and quality.at("sensor-random30").expert == "sensor-random30"
    transfer = load_experiment("suites/transfer")
    assert [a.name for a in transfer.axes] == ["obstacles", "speed", "moving", "family"]
    family = transfer.axes[-1]
    assert family.task_at("rooms").arena.floor_plan == "rooms"
    assert transfer.axes[0].task_at(40).arena.static_obstacles == 40
    for suite in (demos, quality, transfer):
        assert suite.runs >= 5 and suite.test_domain == "final" and suite.demos_per_run
        assert load_experiment(suite.source, quick=True).runs < suite.runs


# -- running ------------------------------------------------------------------------------------------


def test_the_csv_rows_are_the_cells_results(training_suite):
    _, out, results = training_suite
    with open(out / "suite.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == CSV_COLUMNS
    # (2 demonstrators) x (NIRL, BC, rule, expert) x 2 runs; rule is computed once and stands at both
    assert len(rows) == 2 * 4 * 2
    assert sum(1 for c in results if ".rule-" in c) == 2 and len(results) == 2 * 3 * 2 + 2
    for row in rows:
        own = f"demonstrator-{row['value']}.{row['method']}-run{int(row['run']):03d}"
        cell = results.get(own) or results[f"demonstrator-any.{row['method']}-run{int(row['run']):03d}"]
        assert float(row["success"]) == pytest.approx(cell["success_rate"], abs=1e-6)
        assert float(row["spl"]) == pytest.approx(cell["spl"], abs=1e-6)
        assert float(row["sct"]) == pytest.approx(cell["sct"], abs=1e-6)
        assert int(row["tests"]) == cell["tests"] == 2
    summary = json.loads((out / "results.json").read_text())
    rule = [p for p in summary["points"] if p["method"] == "rule"]
    assert all(p["flat"] for p in rule) and rule[0]["avg"] == rule[1]["avg"]
    assert summary["reads"] == {"NIRL": ["demonstrations", "features", "episode_end"],
                                "BC": ["demonstrations", "features"], "rule": ["features", "hand_written"],
                                "expert": ["demonstrator"]}  # fmt: skip
    board = out.parent / "suite-board"
    assert main(["leaderboard", str(out), "--out", str(board)]) == 0
    assert "| **reference:** features, hand_written |" in (board / "leaderboard.md").read_text()
    assert (out / "demonstrator.png").stat().st_size > 10_000
    suite_md = (out / "suite.md").read_text()
    assert "| BC |" in suite_md and "| demonstrations, features |" in suite_md
    assert "| **reference:** features, hand_written |" in suite_md


def test_the_expert_row_is_the_demonstrator_of_each_value(training_suite):
    _, _, results = training_suite
    clean = [results[f"demonstrator-sensor.expert-run{r:03d}"] for r in range(2)]
    noisy = [results[f"demonstrator-sensor-random30.expert-run{r:03d}"] for r in range(2)]
    assert sum(c["success_rate"] for c in clean) > 0  # the tiny arena is solvable: a test that can fail
    # a random action in 30 % of decisions drives other paths on the same arenas
    assert [c["mean_path_length"] for c in clean] != [c["mean_path_length"] for c in noisy]


def test_a_killed_suite_resumes_without_recomputing_finished_cells(training_suite, tmp_path):
    path, _, reference = training_suite
    out = tmp_path / "killed"
    before = killed_after_cells(args(path, out), out, 4)
    assert 4 <= len(before) < len(reference), "the suite was not killed part-way"
    assert main(args(path, out)) == 0
    after = cell_times(out)
    assert {name: after[name] for name in before} == before  # finished cells were not recomputed
    assert cells(out) == reference


def test_a_transfer_suite_trains_once_and_tests_every_point(tmp_path):
    path, out = write(tmp_path, TRANSFER, "transfer"), tmp_path / "out"
    assert main(args(path, out)) == 0
    results = cells(out)
    assert sorted(results) == ["BC-run000", "BC-run001", "rule-run000", "rule-run001"]
    assert sorted(results["BC-run000"]["points"]) == ["obstacles=1", "obstacles=3", "speed=1", "speed=2"]
    with open(out / "suite.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == (2 + 2) * 2 * 2  # points x methods x runs
    assert (out / "obstacles.png").is_file() and (out / "speed.png").is_file()
    # --only: a method's cells alone; the others are reported as stored
    assert main(args(path, out, "--only", "rule")) == 0


# -- metrics and demonstrators -------------------------------------------------------------------------


def episode(outcome: str, poses: list[tuple[float, float]], period: float) -> Trajectory:
    task = spec.load_task("navigate").to_dict()
    task["arena"] = {**task["arena"], "target": [10.0, 0.0], "target_radius": 1.0}
    t = len(poses) - 1
    return Trajectory(features=np.zeros((t + 1, 16), np.float32), actions=np.zeros(t, np.int8),
                      ranges=np.ones((t + 1, 9), np.float32),
                      poses=np.array([[x, y, 0.0] for x, y in poses]), times=np.arange(t + 1) * period,
                      arena_seed=1, task=task, speed=2.0, outcome=outcome, demonstrator="test")  # fmt: skip


def test_spl_and_sct_on_hand_computed_episodes():
    # start (0, 0), target (10, 0) of radius 1: the straight line to the rim is L = 9 m, at 2 m/s C = 4.5 s
    arrived = episode("target", [(0, 0), (0, 3), (4, 0), (9, 0)], period=2.0)  # P = 3 + 5 + 5 = 13 m, T = 6 s
    crashed = episode("collision", [(0, 0), (1, 0)], period=0.5)
    fast = episode("target", [(0, 0), (9, 0)], period=1.0)  # P = 9 m in T = 1 s: both metrics are 1
    assert spl([arrived]) == pytest.approx(9 / 13) and sct([arrived]) == pytest.approx(4.5 / 6)
    assert spl([arrived, crashed]) == pytest.approx(9 / 26) and sct([arrived, crashed]) == pytest.approx(
        0.375
    )
    assert spl([fast]) == pytest.approx(1.0) and sct([fast]) == pytest.approx(1.0)
    m = metrics_of([arrived, crashed, fast])
    assert m["sct"] == pytest.approx((0.75 + 0 + 1) / 3) and m["spl"] == pytest.approx((9 / 13 + 1) / 3)


class Scripted:
    kind = "scripted"

    def __init__(self) -> None:
        self.n = 0

    def reset(self, env, timestep) -> None:
        self.n = 0

    def act(self, timestep) -> int:
        self.n += 1
        return self.n  # 1, 2, 3, ...


def test_the_late_expert_executes_its_decision_of_delay_decisions_ago():
    late = LateExpert(Scripted(), delay=2)
    late.reset(None, None)
    assert [late.act(None) for _ in range(5)] == [0, 0, 1, 2, 3]  # forward first, then 2 decisions late
    late.reset(None, None)
    assert late.act(None) == 0 and late.kind == "late2-scripted"
    with pytest.raises(ValueError, match="delay = 0: must be a whole number >= 1"):
        LateExpert(Scripted(), delay=0)


def test_named_demonstrators_resolve_to_their_settings():
    noisy = ExpertConfig.named("sensor-random30", seed=4)
    assert (noisy.kind, noisy.base, noisy.slip, noisy.random, noisy.seed) == ("noisy", "sensor", 0.0, 0.3, 4)
    assert ExpertConfig.named("sensor-late2").build().kind == "late2-sensor"
    assert ExpertConfig.named("planner") == ExpertConfig("planner")
    with pytest.raises(ValueError, match="unknown demonstrator 'human': accepted: planner, sensor"):
        ExpertConfig.named("human")


# -- leaderboard --------------------------------------------------------------------------------------


def compared(tmp: Path, name: str, methods: str, extra: str = "") -> Path:
    """The tiny task compared for ``methods`` (a TOML list) into tmp/NAME; returns that directory."""
    path, out = tmp / f"{name}.toml", tmp / name
    path.write_text(f'kind = "compare"\n{TOP}methods = {methods}\n{extra}{TINY}')
    assert main(["compare", "--task", str(path), "--out", str(out), "--executor", "serial", "--quiet"]) == 0
    return out


def test_the_leaderboard_merges_directories_of_one_protocol_and_refuses_others(tmp_path, capsys):
    from nirl_mj.experiments import tidy

    a, b = compared(tmp_path, "a", '["BC", "rule"]'), compared(tmp_path, "b", '["forward", "rule"]')
    out = tmp_path / "board"
    assert main(["leaderboard", str(a), str(b), "--out", str(out)]) == 0
    merged = tidy.read(out / "leaderboard.csv")
    inputs = tidy.read(a / "rows.csv") + [r for r in tidy.read(b / "rows.csv") if r["method"] == "forward"]
    assert merged == inputs  # rule is one computation in both: taken once, from the first
    table = (out / "leaderboard.md").read_text()
    assert table.index("| rule |") < table.index("| forward |") and (out / "leaderboard.png").is_file()
    # what each reads, as its comparison recorded it; references in bold
    assert "| BC | 2 |" in table and "| demonstrations, features | `" in table
    assert "| **reference:** features, hand_written | `" in table
    assert "| **reference:** hand_written | `" in table
    assert main(["leaderboard", str(a), "--out", str(out)]) == 2  # an earlier leaderboard: not replaced
    assert "pass --overwrite" in capsys.readouterr().err
    killed = out / ".leaderboard.png.1a2b3c4d.tmp.png"  # what a writer killed mid-write leaves
    killed.write_bytes(b"half a figure")
    assert main(["leaderboard", str(a), "--out", str(out)]) == 2  # still a leaderboard's folder
    assert "pass --overwrite" in capsys.readouterr().err
    assert main(["leaderboard", str(a), "--out", str(out), "--overwrite"]) == 0 and not killed.exists()
    c = compared(tmp_path, "c", '["rule"]', "seed = 5\n")  # another protocol: other test arenas
    capsys.readouterr()
    assert main(["leaderboard", str(a), str(c), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "differ in seed" in err[0] and not (tmp_path / "x").exists()
    d = compared(tmp_path, "d", '["BC"]', '[method.BC]\nvariant = "paper"\n')  # one name, two computations
    capsys.readouterr()
    assert main(["leaderboard", str(a), str(d), "--out", str(tmp_path / "y")]) == 2
    err = capsys.readouterr().err
    assert "method BC of" in err and "(it differs in: clone, variant)" in err  # the fields, named
    # one identity, other results for a run both hold (another machine's floating point): the first's is
    # taken, and the disagreement listed; the CSV's rounding alone is none
    import shutil

    e = shutil.copytree(b, tmp_path / "e")
    rows = (e / "rows.csv").read_text().splitlines()
    at = next(i for i, line in enumerate(rows) if ",rule,0," in line)
    cells = rows[at].split(",")
    success = rows[0].split(",").index("success")
    cells[success] = str(1.0 - float(cells[success]))
    rows[at] = ",".join(cells)
    (e / "rows.csv").write_text("\n".join(rows) + "\n")
    assert main(["leaderboard", str(a), str(e), "--out", str(tmp_path / "z")]) == 0
    board = (tmp_path / "z" / "leaderboard.md").read_text()
    assert board.count("hold other results of the same computation") == 1
    assert f"- rule, run 0: `{a}` and `{e}` hold other results of the same computation (success" in board
    rule = [r for r in tidy.read(tmp_path / "z" / "leaderboard.csv") if r["method"] == "rule"]
    assert rule == [r for r in tidy.read(a / "rows.csv") if r["method"] == "rule"]  # a's rows
    (e / "rows.csv").unlink()  # its cells' full precision against a's CSV: the same
    assert main(["leaderboard", str(a), str(e), "--out", str(tmp_path / "w")]) == 0
    assert "disagree" not in (tmp_path / "w" / "leaderboard.md").read_text()
    assert "k of n" not in board  # every method holds every run
    # a directory whose experiment has not finished: the method with fewer runs is marked and said
    partial = shutil.copytree(a, tmp_path / "partial")
    kept = [line for line in (partial / "rows.csv").read_text().splitlines() if ",BC,1," not in line]
    (partial / "rows.csv").write_text("\n".join(kept) + "\n")
    assert main(["leaderboard", str(partial), "--out", str(tmp_path / "v")]) == 0
    board = (tmp_path / "v" / "leaderboard.md").read_text()
    assert "| BC | 1 of 2 |" in board and "| rule | 2 |" in board and "**Runs `k of n`**" in board
    # the same computation in a second directory fills the runs the first lacks: nothing is partial
    assert main(["leaderboard", str(partial), str(a), "--out", str(tmp_path / "u")]) == 0
    board = (tmp_path / "u" / "leaderboard.md").read_text()
    assert "| BC | 2 |" in board and "k of n" not in board
    assert f"| `{partial}`, `{a}` |" in board and "| rule | 2 |" in board  # BC's run 1 is a's
    # as many runs but other ones (other test arenas): marked too
    other = shutil.copytree(a, tmp_path / "other")
    kept = [line for line in (other / "rows.csv").read_text().splitlines()
            if ",BC,0," not in line and ",rule,1," not in line]  # fmt: skip
    (other / "rows.csv").write_text("\n".join(kept) + "\n")
    assert main(["leaderboard", str(other), "--out", str(tmp_path / "t")]) == 0
    board = (tmp_path / "t" / "leaderboard.md").read_text()
    assert "| BC | 1 of 2 |" in board and "| rule | 1 of 2 |" in board


def test_the_leaderboard_reads_what_each_directory_recorded_and_nothing_from_a_damaged_file(tmp_path):
    from nirl_mj.experiments.leaderboard import recorded_reads

    cases = {
        "compare": {"methods": {"BC": {"reads": ["demonstrations", "features"]}, "old": {"runs": 2}}},
        "suite": {"reads": {"rule": ["features", "hand_written"], "bad": "features", "worse": [1]}},
        "list": [1, 2],
    }
    for name, results in cases.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "results.json").write_text(json.dumps(results))
    (tmp_path / "torn").mkdir()
    (tmp_path / "torn" / "results.json").write_text('{"reads": {"rule": [')
    assert recorded_reads(tmp_path / "compare") == {"BC": ["demonstrations", "features"]}
    assert recorded_reads(tmp_path / "suite") == {"rule": ["features", "hand_written"]}
    assert recorded_reads(tmp_path / "list") == recorded_reads(tmp_path / "torn") == {}
    assert recorded_reads(tmp_path / "missing") == {}


def test_the_example_method_joins_the_comparison_and_the_leaderboard_from_outside(tmp_path, capsys):
    """CI installs examples/knn_method (pip install -e): its method runs through compare by name."""
    from nirl_mj.experiments.plugins import discovered

    if "KNN" not in discovered():
        pytest.skip("examples/knn_method is not installed: pip install -e examples/knn_method")
    out = tmp_path / "knn"
    example = ROOT / "examples" / "knn_method" / "experiment.toml"
    assert main(["compare", "--task", str(example), "--out", str(out), "--quiet", "--runs", "1"]) == 0
    assert main(["leaderboard", str(out), "--out", str(tmp_path / "board")]) == 0
    assert "| KNN |" in (tmp_path / "board" / "leaderboard.md").read_text()


def test_points_computes_some_values_now_and_the_others_later(training_suite, tmp_path, capsys):
    path, _, reference = training_suite
    out = tmp_path / "points"
    assert main(args(path, out, "--points", "sensor-random30")) == 0
    done = set(cells(out))
    assert done == {
        c for c in reference if c.startswith(("demonstrator-sensor-random30.", "demonstrator-any."))
    }
    assert "cells are not finished yet" in (out / "suite.md").read_text()
    assert main(args(path, out)) == 0  # the rest later, the same directory
    assert cells(out) == reference
    assert main(args(path, out, "--points", "sensor-random99")) == 2
    assert "--points sensor-random99: not a value of demonstrator" in capsys.readouterr().err


def test_every_curve_of_a_suite_with_more_rows_than_ten_colours_has_its_own(monkeypatch):
    """The transfer suite draws 12 rows: past the default 10 colours no two curves may share one."""
    import nirl_mj.experiments.suite as suite
    from nirl_mj.experiments.definition import value_name

    transfer = load_experiment("suites/transfer")
    axis = transfer.axes[0]
    points = [
        {"axis": axis.name, "value": value_name(v), "method": m.name, "runs": 5, "avg": 0.5, "ci": [0.4, 0.6],
         "flat": False}
        for m in transfer.methods for v in axis.values
    ]  # fmt: skip
    drawn = {}
    monkeypatch.setattr(suite, "write_figure", lambda path, fig: drawn.setdefault("fig", fig))
    suite.curve_plot(Path("unused.png"), {"points": points}, transfer, axis)
    colours = [line.get_color() for line in drawn["fig"].axes[0].get_lines()]
    assert len(colours) == len(transfer.methods) > 10 and len(set(map(str, colours))) == len(colours)


# -- restoring a published suite -----------------------------------------------------------------------


def publish(out: Path, folder: Path, name: str) -> Path:
    """What docs/scripts/publish_suites.sh keeps of an output directory: NAME.csv, NAME.experiment.json."""
    folder.mkdir(exist_ok=True)
    (folder / f"{name}.csv").write_text((out / "suite.csv").read_text())
    (folder / f"{name}.experiment.json").write_text((out / "experiment.json").read_text())
    return folder


def test_a_lost_suite_is_restored_from_its_publication_and_computes_only_the_rest(
    training_suite, tmp_path, capsys
):
    path, out, reference = training_suite
    published = publish(out, tmp_path / "published", "training")
    lost = tmp_path / "lost"
    assert main(args(path, lost, "--restore", str(published), "--only", "BC,rule")) == 0
    restored = cells(lost)
    assert sorted(restored) == sorted(c for c in reference if ".BC-" in c or ".rule-" in c)
    for cid, cell in restored.items():
        assert cell.keys() <= reference[cid].keys() and cell["physics_error_rate"] == 0.0
        assert all(cell[k] == pytest.approx(reference[cid][k], abs=1e-6) for k in cell)
    record = json.loads((lost / "cells" / f"{next(iter(restored))}.json").read_text())
    assert record["restored_from"] == str((published / "training.csv").resolve())
    assert not (lost / "points" / "demonstrator-sensor" / "runs" / "BC").exists()  # no training run
    assert main(args(path, lost)) == 0  # the rest: NIRL and the expert, computed
    assert (lost / "suite.csv").read_text() == (out / "suite.csv").read_text()
    capsys.readouterr()
    assert main(args(path, lost, "--restore", str(published))) == 0  # nothing left to take
    assert "restore: 0 finished cells taken" in capsys.readouterr().err


def test_restore_refuses_another_experiment_and_skips_methods_computed_otherwise(
    training_suite, tmp_path, capsys
):
    path, out, _ = training_suite
    published = publish(out, tmp_path / "published", "training")
    identity = json.loads((published / "training.experiment.json").read_text())
    other = tmp_path / "other"
    assert main(args(path, other, "--restore", str(tmp_path))) == 2
    assert (
        "holds no published suite training (training.csv and training.experiment.json"
        in capsys.readouterr().err
    )
    (published / "training.experiment.json").write_text(json.dumps({**identity, "tests": 3}))
    assert main(args(path, other, "--restore", str(published), "--only", "rule")) == 2
    assert (
        "another experiment than training's (it differs in: tests); nothing restored"
        in capsys.readouterr().err
    )
    assert not other.exists()  # refused before OUT is made
    learners = {**identity["learners"], "NIRL": {**identity["learners"]["NIRL"], "gamma": 0.5}}
    (published / "training.experiment.json").write_text(json.dumps({**identity, "learners": learners}))
    assert main(args(path, other, "--restore", str(published), "--only", "NIRL,rule")) == 0
    err = capsys.readouterr().err
    assert "restore: NIRL not taken: training.experiment.json computed it with other learner settings" in err
    assert "restore: 2 finished cells taken" in err and "(rule 2)" in err  # NIRL's computed here instead


def test_a_transfer_suite_is_restored_with_every_point_of_a_cell(tmp_path):
    path, out = write(tmp_path, TRANSFER, "transfer"), tmp_path / "out"
    assert main(args(path, out)) == 0
    published = publish(out, tmp_path / "published", "transfer")
    lines = (published / "transfer.csv").read_text().splitlines()
    (published / "transfer.csv").write_text("\n".join(line for line in lines if not (
        ",BC,1," in line and ",speed,1," in line)) + "\n")  # fmt: skip
    lost = tmp_path / "lost"
    assert main(args(path, lost, "--restore", str(published), "--only", "rule,BC")) == 0
    restored, reference = cells(lost), cells(out)
    assert sorted(restored) == sorted(reference)  # BC run 1, one point short, was computed again
    assert restored["rule-run000"]["points"].keys() == reference["rule-run000"]["points"].keys()
    assert "restored" not in json.dumps(cells(lost)["BC-run001"])
    stored = json.loads((lost / "cells" / "BC-run001.json").read_text())
    assert "restored_from" not in stored and "restored_from" in json.loads(
        (lost / "cells" / "BC-run000.json").read_text()
    )


def test_a_point_with_fewer_finished_runs_than_the_experiment_says_how_many():
    """A partial report (cells left to another --only, or not computed yet) marks each such point."""
    from nirl_mj.experiments.definition import value_name
    from nirl_mj.experiments.suite import _paired_table, markdown_table

    experiment = load_experiment(ROOT / "tasks" / "suites" / "quality.toml")  # 5 runs
    axis = experiment.axes[0]
    points = [{"axis": axis.name, "value": value_name(v), "method": m.name, "runs": 0}
              for v in axis.values for m in experiment.methods]  # fmt: skip
    first, partial = points[0], points[1]  # NIRL and NIRL-MAP with the sensor expert
    first.update(runs=5, avg=0.9, ci=[0.8, 1.0])
    partial.update(runs=2, avg=0.5, ci=[0.0, 1.0], paired={"mean": 0.4, "ci": [0.1, 0.7], "runs": 2})
    summary = {"points": points, "first": "NIRL"}
    table = markdown_table(summary, experiment)
    assert "| NIRL | 90.0 [80, 100] | - |" in table and "| NIRL-MAP | 50.0 [0, 100] (n = 2) | - |" in table
    assert "| NIRL-MAP | +40.0 [+10, +70] (n = 2) | - |" in _paired_table(summary, experiment, axis)
    # one run paired: its difference, no interval (as compare's paired table shows it)
    partial.update(runs=1, paired={"mean": -0.6, "ci": [None, None], "runs": 1})
    assert "| NIRL-MAP | -60.0 (1 run) | - |" in _paired_table(summary, experiment, axis)


def test_the_leaderboard_names_a_method_without_runs_at_a_point():
    """A suite's training axis computed with --points for some values only: the methods that have
    no finished run at a value are named under its table, not silently left out."""
    from nirl_mj.experiments.leaderboard import markdown

    def point(value: str, method: str, runs: list[int]) -> dict:
        return {"axis": "demonstrations", "value": value, "method": method, "run_ids": runs,
                "runs": len(runs), "avg": 0.5, "ci": [0.4, 0.6], "spl": 0.4, "sct": None}  # fmt: skip

    summary = [point("10", "NIRL", [0, 1]), point("10", "BC", [0, 1]), point("30", "BC", [0, 1])]
    table = markdown(summary, {"NIRL": "a", "BC": "a"}, {"NIRL": None, "BC": None})
    ten, thirty = table.split("## demonstrations = 30")
    assert "No finished run" not in ten and "No finished run here: NIRL." in thirty
    assert "k of n" not in table
    assert "| 1 | NIRL |" in ten and "| 1 | BC |" in ten  # equal averages: one rank
    # a method of the experiments that finished no run at all (every cell failed) is named too
    table = markdown(summary, {"NIRL": "a", "BC": "a"}, {"NIRL": None, "BC": None, "Mine": None})
    ten, thirty = table.split("## demonstrations = 30")
    assert "No finished run here: Mine." in ten and "No finished run here: NIRL, Mine." in thirty
