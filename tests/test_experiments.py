"""Experiments (Table I, Fig. 6, Fig. 8): specs, executors, identical results, resume, retries, outputs."""

import dataclasses
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
from helpers import TINY_CONFIG, TINY_TABLES, cell_times, killed_after_cells

from nirl_mj.cli import main
from nirl_mj.experiments import kinds, protocol
from nirl_mj.experiments.definition import (
    AXIS_KEYS,
    BUILTIN_METHODS,
    DEMO_KEYS,
    KEYS,
    METHOD_KEYS,
    PAPER_KEYS,
    STRIP_KEYS,
    ExperimentError,
    from_dict,
    load_experiment,
)
from nirl_mj.experiments.executors import Cell, CellStore, Executor, ExecutorError, run_cells
from nirl_mj.experiments.machine import platform_key
from nirl_mj.experiments.stats import paired, summarise_runs, t_interval, wilson
from nirl_mj.learn.config import LearnerConfig

ROOT = Path(__file__).resolve().parents[1]

TINY = TINY_TABLES + TINY_CONFIG  # tests/helpers.py: seconds per cell, the policies differ
SWEEP = """kind = "sweep"
runs = 2
tests = 2
methods = ["NIRL", "rule"]
obstacles = [3]
speeds = [1.0, 2.0]
"""
TABLE1_ROWS = ["NIRL", "NIRL-last", "NIRL-paper", "NIRL-classifier", "AL", "RE", "SCIRL", "AL-traj",
               "RE-traj", "GAIL", "GAIL-linear-last", "AIRL", "BC", "BC-paper", "DAgger", "PPO-reward",
               "DQN-reward", "forward", "rule"]  # fmt: skip


def write_spec(tmp_path: Path, head: str, name: str = "tiny.toml") -> Path:
    path = tmp_path / name
    path.write_text(head + TINY)
    return path


# -- specs ------------------------------------------------------------------------------------------


RECORDED = {"table1_v2": ("table1_extended", {}), "table1": ("table1_fair", {}),
            "table1_nirl": ("table1_fair", {})}  # fmt: skip
"""A task file whose recorded outputs (docs/results/...) have another name, and its methods' names
there. docs/results/table1 is the first Table I (2026-11-22); tasks/archive/table1_v2.toml the
extended one (until 2026-11-26); tasks/table1.toml the fair protocol, and tasks/table1_nirl.toml its
NIRL row alone."""
RENAMED_REFERENCES = {"table1_v2": {"BC": {"variant": "paper"}, "DAgger": {"variant": "paper"}},
                      "fig8": {"BC": {"variant": "paper"}}}  # fmt: skip
"""A recorded method that does not train whose code has since become a named variant: the task file
asks for that variant, and its recorded identity held the default's name for it."""
SHARED = ("kind", "task", "test_task", "seed", "tests", "expert", "demos", "obstacles", "speeds",
          "test_domain", "demos_per_run")  # fmt: skip
ROWS_OF = {"table1_nirl", "nirl_reading", "nirl_inner", "re_ceiling"}
"""Files that compute some rows of their recorded experiment (tasks/table1_nirl.toml: Table I's NIRL;
nirl_reading, nirl_inner and re_ceiling: all but their rows of a retired setting, learn/config.py
RETIRED)."""


@pytest.mark.parametrize(
    "task",
    sorted(p.stem for p in [*ROOT.glob("tasks/*.toml"), *ROOT.glob("tasks/*/*.toml")]
           if "kind" in tomllib.loads(p.read_text("utf-8"))),  # experiments, not task files
)  # fmt: skip
def test_a_shipped_experiment_still_resolves_to_the_settings_of_its_recorded_results(task):
    """A default that changes after an experiment was recorded must not change what its task file
    computes: the file pins the old value (as tasks/ablations/nirl_default.toml's [config] does).
    Compared with the recorded identity: the task, tests and demonstrations; the definition of each
    method that does not train; and every learner setting the recorded identity holds and the
    learner reads (settings added since then are not in it)."""
    results, names = RECORDED.get(task, (task, {}))
    recorded = ROOT / "docs" / "results" / results / "experiment.json"
    if not recorded.is_file():  # a suite's identity is published beside its tables
        recorded = ROOT / "docs" / "results" / "suites" / f"{task}.experiment.json"
    if not recorded.is_file():
        pytest.skip(f"no recorded results for {task}")
    path = next(p for p in [ROOT / "tasks" / f"{task}.toml", *ROOT.glob(f"tasks/*/{task}.toml")]
                if p.is_file())  # fmt: skip
    saved, now = json.loads(recorded.read_text()), load_experiment(path).identity()
    assert {k: saved.get(k) for k in SHARED} == {k: now.get(k) for k in SHARED}, path.name
    old_methods = {m["name"]: m for m in saved["methods"]}
    for method in now["methods"]:
        if method["name"] not in now["learners"]:
            renamed = RENAMED_REFERENCES.get(task, {}).get(method["name"], {})
            old = {**old_methods.get(method["name"], {}), **renamed}
            assert old == method, f"{path.name}: {method['name']} changed"
    wanted = sorted(names.get(n, n) for n in now["learners"])
    if task in ROWS_OF:
        assert set(wanted) <= set(saved["learners"]), path.name
    else:
        assert sorted(saved["learners"]) == wanted, path.name
    for name, settings in now["learners"].items():
        # resolved as a run record is: a setting added since takes the value it had before; only
        # what the learner reads (the loop's and its own step's settings)
        old = LearnerConfig.from_record(saved["learners"][names.get(name, name)]).settings_read()
        read = LearnerConfig.from_dict(settings).settings_read()
        changed = {k: (v, read.get(k)) for k, v in old.items() if read.get(k) != v}
        assert not changed, (
            f"{path.name}: {name}'s settings changed since its results were recorded: {changed}"
        )


def test_shipped_experiments_load_full_and_quick():
    table1 = load_experiment(ROOT / "tasks" / "table1.toml")
    assert (table1.kind, table1.runs, table1.tests) == ("compare", 25, 100)
    assert (table1.demos, table1.expert, table1.demos_per_run, table1.test_domain) == (
        30,
        "sensor",
        True,
        "final",
    )
    assert [m.name for m in table1.methods] == TABLE1_ROWS
    assert (table1.task.arena.static_obstacles, table1.task.control.speed) == (20, 2.0)
    paper = {name: tuple(row[k] for k in ("avg", "best", "worst")) for name, row in table1.paper.items()}
    assert paper == {"NIRL": (83, 94, 69), "NIRL-paper": (83, 94, 69), "NIRL-classifier": (83, 94, 69),
                     "AL": (66, 82, 43), "RE": (78, 87, 61), "AL-traj": (66, 82, 43), "RE-traj": (78, 87, 61),
                     "SCIRL": (79, 88, 60)}  # fmt: skip
    assert [(m.algo, m.steps, m.selection, m.envs) for m in table1.methods if m.name == "DQN-reward"] == [
        ("dqn", 100_000, "validation_success", 1)]  # fmt: skip
    assert {m.name: m.steps for m in load_experiment("table1", quick=True).methods if m.kind == "rl"} == {
        "GAIL": 2048, "GAIL-linear-last": 2048, "AIRL": 2048, "PPO-reward": 2048,
        "DQN-reward": 2048}  # fmt: skip
    quick = load_experiment("table1", quick=True)  # a name under tasks/ works too
    assert (quick.runs, quick.tests, quick.quick) == (3, 20, True)
    # a name that is not there: the shipped ones of the command's kind, where a typo finds them
    said = r"no experiment 'demos' under tasks/: accepted: suites/demos, suites/quality, suites/transfer, or"
    with pytest.raises(ExperimentError, match=said):
        load_experiment("demos", kind="suite")
    with pytest.raises(ExperimentError, match=r"no experiment 'tabel1' under tasks/: accepted: .*\btable1\b"):
        load_experiment("tabel1", kind="compare")
    assert quick.methods[2].learner_config(quick.config).loop.variant == "paper"
    fig6 = load_experiment(ROOT / "tasks" / "fig6.toml")
    assert (fig6.kind, fig6.obstacles, fig6.speeds) == ("sweep", (5, 10, 20, 30, 40, 50), (1.0, 2.0, 3.0))
    corner = fig6.cell_task(50, 3.0)
    assert (corner.arena.static_obstacles, corner.control.speed, fig6.tests) == (50, 3.0, 50)
    fig8 = load_experiment(ROOT / "tasks" / "fig8.toml")
    assert (fig8.task.arena.moving_obstacles, fig8.test_task.arena.moving_obstacles) == (0, 10)
    assert fig8.strip.method == "NIRL"
    assert table1.identity() != quick.identity()


EXPERIMENT_FILES = sorted(
    path for path in (ROOT / "tasks").rglob("*.toml") if "kind" in tomllib.loads(path.read_text("utf-8"))
)


@pytest.mark.parametrize("path", EXPERIMENT_FILES, ids=lambda p: str(p.relative_to(ROOT / "tasks")))
def test_every_shipped_experiment_file_loads_full_and_quick(path):
    # the files whose figures docs/ cites must stay runnable as the code changes
    for quick in (False, True):
        experiment = load_experiment(path, quick=quick)
        for method in experiment.methods:
            if method.trains:
                method.learner_config(experiment.config)  # a bad setting raises here


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"kind": None}, "kind = None: accepted: compare, sweep"),
        ({"run": 3}, "unknown key(s) run (kind compare); accepted: kind, description"),
        ({"obstacles": [5]}, "unknown key(s) obstacles (kind compare)"),
        ({"runs": 0}, "runs = 0: must be >= 1"),
        ({"tests": 2.5}, "tests = 2.5: expected a whole number"),
        ({"methods": ["NIRL", "WGAN"]}, "unknown method 'WGAN'; built in: NIRL, NIRL-paper"),
        ({"methods": "NIRL"}, "methods = 'NIRL': expected a list"),
        ({"config": {"episode": 3}}, "config: unknown key(s) episode; accepted: episodes"),
        ({"config": {"episodes": "3"}}, "config.episodes = '3': expected a int"),
        ({"methods": ["BC", "rule"], "config": {"gamma": 7.0}}, "config: gamma = 7.0: expected a finite"),
        ({"config": {"selection": "best"}}, "config: unknown selection 'best'; accepted: demo_balanced"),
        ({"demos": {"expert": "human"}}, "demos.expert = 'human': accepted: planner, sensor, noisy, rule"),
        ({"set": {"arena": {"static_obstacles": -1}}}, "set: navigate (overridden).arena.static_obstacles"),
        ({"set": {"physics": {}}}, "set: unknown key(s) physics; accepted: arena, robot"),
        ({"set": {"arena": 3}}, "set.arena: expected a table, got 3"),
        ({"methods": ["NIRL"], "strip": {"method": "NIRL", "snapshots": 1}},
         "strip.snapshots = 1: must be >= 2"),
        ({"task": "no-such-task"}, "task: unknown task 'no-such-task'"),
        ({"paper": {"AL": {"avg": 66}}}, "paper.AL: 'AL' is not a method of this experiment"),
        ({"paper": {"NIRL": {"mean": 1}}}, "paper.NIRL: unknown key(s) mean; accepted: avg"),
        ({"strip": {"method": "BC"}}, "strip.method: 'BC' is not a method"),
        ({"methods": ["NIRL"], "strip": {"method": "NIRL", "camera": "side"}},
         "strip: unknown camera 'side'; accepted: top, follow, chase"),
        ({"methods": ["NIRL"], "strip": {"method": "NIRL", "width": 481}},
         "strip: frame 481x360: width and height must be even"),
        ({"methods": ["Mine"], "method": {"Mine": {"kind": "irl", "method": "gail"}}},
         "method.Mine.method = 'gail': accepted: nirl"),
        ({"methods": ["Mine"], "method": {"Mine": {"kind": "bc", "config": {"eta": 1.0}}}},
         'method.Mine: method and config apply to kind = "irl" only'),
        ({"methods": ["Mine"], "method": {"Mine": {"kind": "rule", "variant": "paper"}}},
         'method.Mine: variant applies to kind = "irl", "bc" and "dagger" only'),
        ({"methods": ["D"], "method": {"D": {"kind": "dagger", "settings": {"round": 2}}}},
         "method.D.settings: unknown DAgger setting(s) round; accepted: rounds, episodes"),
        ({"methods": ["D"], "method": {"D": {"kind": "dagger", "settings": {"episodes": 2.5}}}},
         "method.D.settings: DAgger's episodes must be a whole number, got 2.5"),
        ({"methods": ["D"], "method": {"D": {"kind": "dagger", "settings": {"episodes": 0}}}},
         "method.D.settings: DAgger needs rounds >= 0 and episodes >= 1, got 8, 0"),
        ({"methods": ["D"], "method": {"D": {"kind": "dagger", "steps": 5}}},
         "method.D: DAgger takes settings (its rounds and episodes) only"),
        ({"methods": ["NIRL"], "test_domain": "dev"}, "test_domain = 'dev': accepted: test, final"),
        ({"methods": ["NIRL"], "demos": {"per_run": 1}}, "demos.per_run = 1: expected true or false"),
        ({"method": {"Mine": {"kind": "bc"}}}, "method: Mine defined but not in methods"),
        ({"quick": {"kind": "sweep"}}, "quick: unknown key(s) kind; accepted: description"),
        ({"kind": "sweep", "obstacles": [5], "speeds": [9.0]}, "cell (5 obstacles, 9.0 m/s): "),
        ({"kind": "sweep", "speeds": [1.0]}, "a sweep needs non-empty obstacles and speeds"),
        ({"kind": "sweep", "obstacles": [5, 5], "speeds": [1.0]}, "obstacles ['5', '5']: every value"),
        ({"kind": "sweep", "obstacles": [5], "speeds": [1.0, 1.0000001]}, "speeds ['1', '1']: every"),
    ],
)  # fmt: skip
def test_spec_errors_name_the_key_and_what_is_accepted(data, message):
    with pytest.raises(ExperimentError) as err:
        from_dict({"kind": "compare", **data}, "e.toml")
    assert message in str(err.value)
    assert str(err.value).startswith("e.toml")


def test_quick_errors_say_they_come_from_the_quick_table():
    # found at load, with or without --quick: a typo in [quick] does not wait for the first --quick
    for data in ({"quick": {"runs": 0}}, {"quick": {"demos": {"episodez": 3}}},
                 {"quick": {"set": {"arena": {"static_obstacle": 3}}}}):  # fmt: skip
        for quick in (False, True):
            with pytest.raises(ExperimentError, match=r"quick\.(runs = 0|demos: unknown|set: navigate)"):
                from_dict({"kind": "compare", **data}, "e.toml", quick=quick)


def test_a_paper_row_of_a_method_that_quick_leaves_out_is_dropped_from_the_quick_run():
    data = {"kind": "compare", "methods": ["NIRL", "BC"], "paper": {"BC": {"avg": 50}},
            "quick": {"methods": ["NIRL"]}}  # fmt: skip
    assert from_dict(data, "e.toml").paper == {"BC": {"avg": 50.0}}
    assert from_dict(data, "e.toml", quick=True).paper == {}
    with pytest.raises(ExperimentError, match="paper.AL: 'AL' is not a method"):
        from_dict({**data, "paper": {"AL": {"avg": 50}}}, "e.toml", quick=True)


def test_seeds_are_32_bit_words():
    from nirl_mj.experiments.seeds import domain_seed, episode_seed

    with pytest.raises(ExperimentError, match="seed = 4294967295 with runs = 2: the run seeds"):
        from_dict({"kind": "compare", "seed": 2**32 - 1, "runs": 2}, "e.toml")
    from_dict({"kind": "compare", "seed": 2**32 - 1}, "e.toml")
    for call in (lambda: episode_seed(2**32, 0), lambda: domain_seed("test", 0, 2**32)):
        with pytest.raises(ValueError, match="0 .. 2\\^32 - 1"):
            call()
    with pytest.raises(SystemExit):
        main(["demos", "--seed", str(2**32), "--out", "never.npz"])
    # the one overlap kept (seeds.py): a dataset seeded with a domain word, arena 0 of that domain
    assert episode_seed(104, 5) == domain_seed("final", 5, 0) != domain_seed("final", 5, 1)
    assert episode_seed(105, 5) != domain_seed("final", 5, 0)


def test_a_relative_task_path_is_the_experiment_files_never_the_working_directorys(tmp_path, monkeypatch):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "e.toml").write_text('kind = "compare"\ntask = "mine.toml"\n')
    (tmp_path / "b" / "mine.toml").write_text("[control]\nspeed = 3.0\n")
    monkeypatch.chdir(tmp_path / "b")
    with pytest.raises(ExperimentError, match="no such file beside the experiment"):
        load_experiment(tmp_path / "a" / "e.toml")
    (tmp_path / "a" / "mine.toml").write_text("[control]\nspeed = 1.5\n")
    assert load_experiment(tmp_path / "a" / "e.toml").task.control.speed == 1.5
    (tmp_path / "a" / "e.toml").write_text('kind = "compare"\ntask = "tasks/dynamic.toml"\n')
    assert load_experiment(tmp_path / "a" / "e.toml").task.arena.moving_obstacles > 0  # the checkout's


def test_a_method_table_of_a_method_that_quick_leaves_out_is_kept_for_the_full_run():
    pinned = {"kind": "rl", "algo": "ppo", "selection": "training_success"}
    data = {"kind": "compare", "methods": ["rule", "PPO-reward"], "quick": {"methods": ["rule"]},
            "method": {"PPO-reward": pinned}}  # fmt: skip
    assert [m.name for m in from_dict(data, "e.toml", quick=True).methods] == ["rule"]
    assert from_dict(data, "e.toml").methods[1].selection == "training_success"
    # a table that names no method of the file is still refused, quick or not
    other = {**data, "method": {**data["method"], "PPO-rewrd": {"kind": "rl"}}}
    for quick in (False, True):
        with pytest.raises(ExperimentError, match="method: PPO-rewrd defined but not in methods"):
            from_dict(other, "e.toml", quick=quick)
        # and the kept table is checked in a quick load too
        broken = {**data, "method": {"PPO-reward": {**pinned, "selection": "best"}}}
        with pytest.raises(ExperimentError, match="selection"):
            from_dict(broken, "e.toml", quick=quick)


def test_own_methods_change_the_learner():
    e = from_dict({"kind": "compare", "methods": ["NIRL", "low-margin", "BC"], "config": {"episodes": 7},
                   "method": {"low-margin": {"variant": "default", "config": {"margin_loss": 0.05}},
                              "BC": {"kind": "bc"}}})  # fmt: skip
    config = e.methods[1].learner_config(e.config)
    assert (config.loop.margin_loss, config.loop.episodes, config.loop.method) == (0.05, 7, "nirl")
    assert (
        e.methods[0].learner_config(e.config).loop.margin_loss == 0.1
        and e.methods[2] == BUILTIN_METHODS["BC"]
    )


def test_every_experiment_key_is_documented_in_docs_experiments_md():
    text = (ROOT / "docs" / "EXPERIMENTS.md").read_text()
    keys = {*KEYS["compare"], *KEYS["sweep"], *KEYS["suite"]}
    for key in keys:
        assert f"| `{key}` |" in text, f"top-level key {key} is not documented in docs/EXPERIMENTS.md"
    for table, names in (("demos", DEMO_KEYS), ("method.NAME", METHOD_KEYS), ("paper.NAME", PAPER_KEYS),
                         ("strip", STRIP_KEYS), ("axis", AXIS_KEYS)):  # fmt: skip
        for key in names:
            assert f"| `{table}.{key}` |" in text, f"{table}.{key} is not documented in docs/EXPERIMENTS.md"
    for name in BUILTIN_METHODS:
        assert f"| `{name}` |" in text, f"built-in method {name} is not documented in docs/EXPERIMENTS.md"


# -- statistics -------------------------------------------------------------------------------------


def test_intervals_match_hand_computation():
    low, high = t_interval([0.5, 0.6, 0.4])  # mean 0.5, sd 0.1, t(0.975, 2) = 4.3027
    half = 4.3027 * 0.1 / math.sqrt(3)
    assert (low, high) == pytest.approx((0.5 - half, 0.5 + half), abs=1e-4)
    assert t_interval([0.1, 0.9]) == (0.0, 1.0)  # clipped to what a rate can be
    assert all(math.isnan(v) for v in t_interval([0.5]))
    assert wilson(0, 10) == pytest.approx((0.0, 0.2775), abs=1e-4)
    assert wilson(5, 10) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    rows = [{"success_rate": s, "collision_rate": 1 - s, "timeout_rate": 0.0, "physics_error_rate": 0.0,
             "spl": s / 2, "tests": 10} for s in (0.6, 0.9, 0.7)]  # fmt: skip
    s = summarise_runs(rows)
    summary = (s["avg"], s["best"], s["worst"], s["runs"], s["tests"])
    assert summary == pytest.approx((0.7333, 0.9, 0.6, 3, 30), abs=1e-4)
    # the runs' sample sd: squared deviations from 11/15, (2/15)^2 + (1/6)^2 + (1/30)^2 = 42/900, over
    # 3 - 1 runs: sqrt(21) / 30 = 0.152753
    assert s["sd"] == pytest.approx(math.sqrt(21) / 30, rel=1e-12)
    half = 4.3027 * math.sqrt(21) / 30 / math.sqrt(3)  # 0.37946: the upper bound 1.1128 clipped to 1
    assert s["ci"] == pytest.approx([11 / 15 - half, 1.0], abs=1e-4)
    assert summarise_runs(rows[:1])["ci"] == [None, None]  # standard JSON, no NaN


def test_paired_difference_by_hand():
    # differences 0.1, 0.3, -0.1, 0.0: mean 0.075, sd sqrt(0.0875 / 3) = 0.17078, SE 0.08539
    p = paired([0.9, 0.8, 0.5, 0.6], [0.8, 0.5, 0.6, 0.6])
    assert (p["runs"], p["better"], p["worse"], p["equal"]) == (4, 2, 1, 1)
    assert (p["mean"], p["se"]) == pytest.approx((0.075, 0.08539), abs=1e-5)
    half = 3.1824 * 0.08539  # t(0.975, 3)
    assert p["ci"] == pytest.approx([0.075 - half, 0.075 + half], abs=1e-4)  # negative bound kept
    assert paired([0.5], [0.2])["se"] is None and paired([], [])["runs"] == 0


# -- executors --------------------------------------------------------------------------------------


def counted_cell(directory: str, name: str, fail_times: int) -> dict:
    """Records the attempt in ``directory``; raises for the first ``fail_times`` attempts."""
    attempt = len(list(Path(directory).glob(f"{name}.*"))) + 1
    Path(directory, f"{name}.{attempt}").touch()
    if attempt <= fail_times:
        raise ValueError(f"{name} attempt {attempt} failed on purpose")
    return {"name": name, "attempt": attempt, "value": 0.1 * attempt}


def dying_cell(directory: str) -> dict:
    """Kills its own process at the first attempt (as the out-of-memory killer would)."""
    marker = Path(directory, "died")
    if not marker.exists():
        marker.touch()
        os._exit(1)
    return {"survived": True}


@pytest.mark.parametrize("executor", ["serial", "local"])
def test_failing_cell_is_retried_then_reported_and_never_stored(tmp_path, executor):
    calls, store = tmp_path / "calls", CellStore(tmp_path / "cells")
    calls.mkdir()
    cells = [Cell("flaky", counted_cell, (str(calls), "flaky", 1)),
             Cell("broken", counted_cell, (str(calls), "broken", 99))]  # fmt: skip
    seen = []
    report = run_cells(cells, executor, workers=2, retries=2, store=store,
                       on_done=lambda i, r, f: seen.append((i, f is None)))  # fmt: skip
    assert report.results == {"flaky": {"name": "flaky", "attempt": 2, "value": 0.2}}
    failure = report.failures["broken"]
    assert failure.attempts == 3 and len(list(calls.glob("broken.*"))) == 3
    assert failure.error == "ValueError: broken attempt 3 failed on purpose"
    assert "Traceback" in failure.traceback
    assert sorted(seen) == [("broken", False), ("flaky", True)]
    stored = json.loads(store.path("flaky").read_text())
    assert stored["attempts"] == 2 and stored["platform"] == platform_key()  # the worker's machine
    assert not store.path("broken").exists()  # the next run tries it again
    again = run_cells(cells, executor, workers=2, retries=0, store=store)
    assert again.reused == ["flaky"] and list(again.failures) == ["broken"]


def test_a_dead_worker_process_is_replaced_and_its_cell_retried(tmp_path):
    cells = [Cell("dies", dying_cell, (str(tmp_path),)),
             Cell("fine", counted_cell, (str(tmp_path), "fine", 0))]  # fmt: skip
    report = run_cells(cells, "local", workers=2, retries=1)
    assert report.results["dies"] == {"survived": True} and not report.failures


def test_missing_ray_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(ExecutorError, match=r"pip install 'nirl-mj\[ray\]'"):
        run_cells([Cell("x", counted_cell, ("/nonexistent", "x", 0))], "ray", workers=1)
    with pytest.raises(ExecutorError, match="accepted: serial, local, ray"):
        run_cells([Cell("x", counted_cell, ("/nonexistent", "x", 0))], "dask")


SHARED = """
[method.last-wide]          # another learner: trains a run of its own
kind = "irl"
config = { selection = "last", hidden_units = 12 }

[method.val]                # selects on validation episodes: a run of its own, lent to none
kind = "irl"
config = { selection = "validation" }

[method.val-last]           # its last iterate: NIRL-last's settings, so it reads NIRL's run
kind = "irl"
config = { selection = "last" }
"""


def test_a_last_iterate_row_reads_the_training_run_it_shares_and_tests_the_same_policy(tmp_path, capsys):
    """NIRL-last differs from NIRL in its selection alone: its job reads NIRL's training run (its last
    iterate) instead of training the same again, starts after every other job, and gives the cells of
    a run trained for it alone, bit for bit."""
    head = 'kind = "compare"\nruns = 1\ntests = 2\nmethods = ["NIRL", "NIRL-last", "rule"]\n'
    spec = write_spec(tmp_path, head)
    spec.write_text(spec.read_text().replace("episodes = 1\n", "episodes = 3\n", 1))
    alone = tmp_path / "alone.toml"
    alone.write_text(spec.read_text().replace('["NIRL", "NIRL-last", "rule"]', '["NIRL-last"]'))
    assert protocol.training_owners(load_experiment(spec)) == {"NIRL-last": load_experiment(spec).methods[0]}
    for path, out in ((spec, "shared"), (alone, "own")):
        assert main(["compare", "--task", str(path), "--executor", "serial", "--quiet", "--out",
                     str(tmp_path / out)]) == 0  # fmt: skip
    capsys.readouterr()
    assert sorted(p.name for p in (tmp_path / "shared" / "runs").iterdir()) == ["NIRL"]

    def cell(out: str) -> dict:
        record = json.loads((tmp_path / out / "cells" / "NIRL-last-run000.json").read_text())
        return {k: v for k, v in record["result"].items() if k != "seconds"}

    assert cell("shared") == cell("own")
    own = np.load(tmp_path / "own" / "runs" / "NIRL-last" / "0" / "policy.npz")
    shared = np.load(tmp_path / "shared" / "runs" / "NIRL" / "0" / "policy.npz")
    assert own.files == shared.files and all(np.array_equal(own[k], shared[k]) for k in own.files
                                             if k.startswith("last"))  # fmt: skip
    record = json.loads((tmp_path / "own" / "runs" / "NIRL-last" / "0" / "run.json").read_text())
    assert record["selected_iteration"] == record["iterations"] - 1 == 2
    # NIRL's rule picks another iterate here, whose cell differs: reading "selected" would be caught
    nirl = json.loads((tmp_path / "shared" / "runs" / "NIRL" / "0" / "run.json").read_text())
    assert nirl["selected_iteration"] != 2
    nirl_cell = json.loads((tmp_path / "shared" / "cells" / "NIRL-run000.json").read_text())["result"]
    assert nirl_cell["mean_path_length"] != cell("shared")["mean_path_length"]


def test_both_jobs_of_a_shared_training_run_wait_for_its_lock_instead_of_failing(tmp_path, capsys):
    """NIRL's and NIRL-last's cells may start together (more workers than jobs left): whichever
    finds the run's lock held waits for it, the owner as well as the borrower."""
    import threading

    from nirl_mj.data.lock import DirectoryLock

    e = load_experiment(
        write_spec(tmp_path, 'kind = "compare"\nruns = 1\ntests = 2\nmethods = ["NIRL", "NIRL-last"]\n')
    )
    out = protocol.open_output(tmp_path / "out", e)
    jobs = protocol.run_jobs(e, out, {0: protocol.ensure_demos(out, e, 1, lambda _: None)})
    for name in ("NIRL", "NIRL-last"):
        lock = DirectoryLock(jobs[name, 0].run_dir, "training").acquire()  # the other cell, training
        threading.Timer(1.0, lock.release).start()
        assert "train_seeds" in kinds.ensure_trained(jobs[name, 0])
        assert "waiting for process" in capsys.readouterr().err


def test_only_a_last_iterate_row_with_the_same_settings_but_selection_shares_a_training_run(tmp_path):
    """A run selected on validation episodes is lent to none (its validation arenas are its own), nor
    one of other settings; a run selected by a rule is preferred wherever it is listed."""
    names = '["NIRL-last", "val", "last-wide", "NIRL", "val-last"]'
    head = f'kind = "compare"\nruns = 1\ntests = 2\nmethods = {names}\n'
    e = load_experiment(write_spec(tmp_path, head + SHARED))
    nirl = e.methods[3]
    assert protocol.training_owners(e) == {"NIRL-last": nirl, "val-last": nirl}
    out = protocol.open_output(tmp_path / "out", e)
    demos = protocol.ensure_demos(out, e, 1, lambda _: None)
    jobs = protocol.run_jobs(e, out, {0: demos})
    assert [m for m, _ in jobs] == ["val", "last-wide", "NIRL", "NIRL-last", "val-last"]  # borrowers last
    job = jobs["NIRL-last", 0]
    assert (job.trained_by, job.policy, job.run_dir) == ("NIRL", "last", jobs["NIRL", 0].run_dir)
    assert job.config == jobs["NIRL", 0].config  # the run's settings, with NIRL's selection
    assert (jobs["last-wide", 0].trained_by, jobs["val", 0].policy) == ("", "selected")
    assert [m for (m, _), j in jobs.items() if j.shared_run] == ["NIRL", "NIRL-last", "val-last"]
    without = dataclasses.replace(e, methods=tuple(m for m in e.methods if m.name != "NIRL"))
    assert protocol.training_owners(without) == {"val-last": e.methods[0]}  # the first last-iterate row's


def test_experiment_json_is_strict_and_one_with_the_old_epsilon_spelling_still_resumes(tmp_path):
    """The learners' "never stop" is null (strict JSON); an OUT written before holds -Infinity,
    which reads as the same setting, so it resumes instead of being refused."""

    def strict(constant: str) -> None:
        raise ValueError(f"not strict JSON: {constant}")

    e = load_experiment(
        write_spec(tmp_path, 'kind = "compare"\nruns = 1\ntests = 2\nmethods = ["NIRL", "rule"]\n')
    )
    out = protocol.open_output(tmp_path / "out", e)
    text = (out / "experiment.json").read_text()
    assert json.loads(text, parse_constant=strict)["learners"]["NIRL"]["epsilon"] is None
    (out / "experiment.json").write_text(text.replace('"epsilon": null', '"epsilon": -Infinity'))
    assert protocol.open_output(tmp_path / "out", e) == out
    assert protocol.output_state(out, e).startswith("holds this experiment")
    stops = dataclasses.replace(e, config={**e.config, "epsilon": 0.0})  # another setting: refused
    assert "learners (NIRL: epsilon)" in protocol.output_state(out, stops)
    saved = json.loads((out / "experiment.json").read_text())  # a learner this version cannot read
    saved["learners"]["NIRL"]["setting_of_a_later_version"] = 1
    (out / "experiment.json").write_text(json.dumps(saved))
    assert protocol.output_state(out, e).startswith("holds another experiment (it differs in: learners (NIRL")


def test_interrupted_training_resumes_to_the_uninterrupted_result(tmp_path):
    e = load_experiment(write_spec(tmp_path, SWEEP.replace("runs = 2", "runs = 1")))
    e = dataclasses.replace(e, config={**e.config, "episodes": 2})
    out = protocol.open_output(tmp_path / "out", e)
    demos = protocol.ensure_demos(out, e, 1, lambda _: None)
    job = protocol.run_jobs(e, out, {0: demos})["NIRL", 0]
    reference = dataclasses.replace(job, run_dir=str(tmp_path / "reference"))
    kinds.ensure_trained(reference)

    class Stop(Exception):
        pass

    def stop(_):
        raise Stop

    from nirl_mj.experiments.training import train
    from nirl_mj.learn.config import LearnerConfig

    with pytest.raises(Stop):  # killed after its first iteration's checkpoint
        train(
            job.run_dir,
            job.task,
            job.demos_path,
            LearnerConfig.from_dict(job.config),
            job.seed,
            on_metrics=stop,
        )
    assert not (Path(job.run_dir) / "policy.npz").exists()
    policy = Path(job.run_dir) / "policy.npz"
    kinds.ensure_trained(job)
    assert policy.read_bytes() == (Path(reference.run_dir) / "policy.npz").read_bytes()
    # Killed between policy.npz and the final run.json: finished again, not taken as done.
    record_file = Path(job.run_dir) / "run.json"
    record = json.loads(record_file.read_text())
    for key in ("iterations", "selected_iteration", "train_seeds"):
        record.pop(key)
    record_file.write_text(json.dumps(record))
    assert "train_seeds" in kinds.ensure_trained(job)
    assert policy.read_bytes() == (Path(reference.run_dir) / "policy.npz").read_bytes()
    # Killed before its first checkpoint: only run.json is there; started afresh.
    policy.unlink()
    (Path(job.run_dir) / "checkpoint.npz").unlink()
    kinds.ensure_trained(job)
    assert policy.read_bytes() == (Path(reference.run_dir) / "policy.npz").read_bytes()


# -- a small sweep on every executor, killed and resumed ---------------------------------------------


def sweep_args(spec: Path, out: Path, executor: str, *extra: str) -> list[str]:
    workers = [] if executor == "serial" else ["--workers", "2"]  # serial refuses --workers: one process
    return ["sweep", "--task", str(spec), "--out", str(out), "--executor", executor, *workers, "--quiet",
            *extra]  # fmt: skip


def cell_results(out: Path) -> dict:
    return {p.stem: json.loads(p.read_text())["result"] for p in sorted((out / "cells").glob("*.json"))}


@pytest.fixture(scope="module")
def serial_sweep(tmp_path_factory):
    """The tiny sweep, serially in this process: the reference every other way must reproduce."""
    tmp = tmp_path_factory.mktemp("sweep")
    spec, out = write_spec(tmp, SWEEP), tmp / "serial"
    assert main(sweep_args(spec, out, "serial", "--json")) == 0
    return spec, out, cell_results(out)


def test_serial_sweep_writes_csv_plot_and_table(serial_sweep, capsys):
    spec, out, results = serial_sweep
    assert len(results) == 2 + 2 * 2 * 1 * 2  # 2 trainings; (NIRL, rule) x 2 runs x 1 obstacles x 2 speeds
    lines = (out / "sweep.csv").read_text().splitlines()
    assert lines[0].startswith("method,obstacles,speed,runs,failed,tests,success_avg") and len(lines) == 1 + 4
    assert (out / "sweep.png").stat().st_size > 10_000 and "| rule | 2 |" in (out / "sweep.md").read_text()
    rule = [r for r in results.values() if r.get("method") == "rule"]
    assert sum(r["success_rate"] for r in rule) > 0  # the tiny arena is solvable: a test that can fail
    assert {r["tests"] for r in results.values() if "tests" in r} == {2}


def test_a_sweep_records_and_tables_what_each_method_reads(serial_sweep):
    """A sweep's results.json carries each method's reads as compare's do (``method_reads``), where
    the leaderboard finds them, and its table marks a reference as compare's does."""
    from nirl_mj.experiments.leaderboard import recorded_reads
    from nirl_mj.experiments.reads import method_reads

    spec, out, _ = serial_sweep
    experiment = load_experiment(spec, kind="sweep")
    reads = json.loads((out / "results.json").read_text())["reads"]
    assert reads == {m.name: method_reads(m, experiment.config) for m in experiment.methods}
    assert reads["NIRL"] == ["demonstrations", "features", "episode_end"]
    assert reads["rule"] == ["features", "hand_written"]
    assert recorded_reads(out) == reads
    table = (out / "sweep.md").read_text().splitlines()
    nirl, rule = ([line for line in table if line.startswith(f"| {name} |")] for name in ("NIRL", "rule"))
    assert len(nirl) == len(rule) == 2  # a row per speed
    assert all(line.endswith("| demonstrations, features, episode_end |") for line in nirl)
    assert all(line.endswith("| **reference:** features, hand_written |") for line in rule)


@pytest.mark.parametrize("executor", ["local", "ray"])
def test_executors_and_workers_give_identical_results(serial_sweep, tmp_path, executor, monkeypatch):
    import tempfile

    if executor == "ray":
        pytest.importorskip("ray", reason="Ray is optional: pip install 'nirl-mj[ray]' to test it")
    # a short temporary root of its own (Ray's socket paths must fit 107 bytes), Python's and Ray's
    # alike (Ray's default session folder is TMPDIR/ray on Linux), to see what a run leaves there
    root = Path(tempfile.mkdtemp(prefix="r", dir="/tmp"))
    monkeypatch.setattr(tempfile, "tempdir", str(root))
    monkeypatch.setenv("TMPDIR", str(root))
    monkeypatch.delenv("RAY_TMPDIR", raising=False)
    spec, _, reference = serial_sweep
    try:
        assert main(sweep_args(spec, tmp_path / executor, executor)) == 0
        assert list(root.iterdir()) == []  # a local Ray cluster's session folder went with it
    finally:
        shutil.rmtree(root, ignore_errors=True)
    assert cell_results(tmp_path / executor) == reference


def test_killed_sweep_resumes_without_recomputing_finished_cells(serial_sweep, tmp_path):
    spec, _, reference = serial_sweep
    out = tmp_path / "killed"
    before = killed_after_cells(sweep_args(spec, out, "serial"), out, 4, seconds=120)
    assert 4 <= len(before) < len(reference), "the sweep was not killed part-way"
    assert main(sweep_args(spec, out, "serial")) == 0
    after = cell_times(out)
    assert {name: after[name] for name in before} == before  # finished cells were not recomputed
    assert cell_results(out) == reference


def test_a_killed_experiment_leaves_no_worker_writing(tmp_path):
    """A killed parent (SIGKILL: no clean-up runs) takes its local workers and multiprocessing's
    resource tracker with it, so a restarted command is the only writer of its directory: a worker
    notices within a second that its parent has gone and ends (the 120 s below only bound a test
    that would otherwise hang)."""
    pid_file = tmp_path / "worker.pid"
    script = (
        "import sys; sys.path.insert(0, {tests!r})\n"
        "from helpers import sleeping_cell\n"
        "from nirl_mj.experiments.executors import Cell, run_cells\n"
        "run_cells([Cell('sleep', sleeping_cell, ({pid!r},))], 'local', workers=1)\n"
    ).format(tests=str(ROOT / "tests"), pid=str(pid_file))
    parent = subprocess.Popen([sys.executable, "-c", script], cwd=ROOT)
    deadline = time.monotonic() + 120
    while not pid_file.is_file() or not pid_file.read_text():
        assert time.monotonic() < deadline and parent.poll() is None, "the worker did not start"
        time.sleep(0.05)
    worker = int(pid_file.read_text())

    def ppid(proc: Path) -> int | None:
        try:
            return int(proc.joinpath("stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            return None

    # the worker and multiprocessing's resource tracker, every child the parent had
    children = {int(p.name) for p in Path("/proc").iterdir() if p.name.isdigit() and ppid(p) == parent.pid}
    assert worker in children and len(children) >= 2, children  # the tracker too
    parent.send_signal(signal.SIGKILL)
    parent.wait()

    def alive(pid: int) -> bool:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        # reaped by init once it exits; a zombie still answers signal 0
        return Path(f"/proc/{pid}/stat").is_file() and Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"

    while any(alive(child) for child in children):
        if time.monotonic() > deadline:
            for child in children:
                if alive(child):
                    os.kill(child, signal.SIGKILL)
            pytest.fail("a worker or the resource tracker outlived its killed parent")
        time.sleep(0.1)


# -- compare ----------------------------------------------------------------------------------------


def test_compare_quick_prints_the_json_line_and_writes_the_table(tmp_path, capsys):
    head = f"""kind = "compare"
runs = 5
tests = 50
methods = {json.dumps(TABLE1_ROWS)}
[quick]
runs = 2
tests = 2
[quick.method.GAIL]
steps = 1024
[quick.method.AIRL]
steps = 1024
[quick.method.PPO-reward]
steps = 1024
[quick.method.DQN-reward]
steps = 1024
[quick.method.DAgger]
settings = {{ rounds = 1, episodes = 2 }}
[paper.AL]
avg = 66
best = 82
worst = 43
"""
    spec, out = write_spec(tmp_path, head), tmp_path / "out"
    quick = ["compare", "--task", str(spec), "--quick", "--out", str(out), "--executor", "serial", "--quiet"]
    code = main([*quick, "--json"])
    captured = capsys.readouterr()
    last = json.loads(captured.out.strip().splitlines()[-1])
    assert code == 0, captured.err
    assert list(last["methods"]) == TABLE1_ROWS
    for row in last["methods"].values():
        assert {"avg", "best", "worst", "collision", "timeout", "ci"} <= set(row) and row["runs"] == 2
        assert 0.0 <= row["worst"] <= row["avg"] <= row["best"] <= 1.0
    assert last["failures"] == []
    assert last["methods"]["rule"]["avg"] > last["methods"]["forward"]["avg"]
    table = (out / "table.md").read_text()
    assert "| AL | 2 |" in table and "66 / 82 / 43 |" in table
    # every run's success, and the first method minus each other paired by run, from the cells
    cells = {p.stem: json.loads(p.read_text())["result"]["success_rate"] for p in (out / "cells").iterdir()}
    first, al = TABLE1_ROWS[0], [cells[f"AL-run{r:03d}"] for r in (0, 1)]
    assert f"| AL | {round(100 * al[0])} | {round(100 * al[1])} |" in table
    diff = sum(cells[f"{first}-run{r:03d}"] - cells[f"AL-run{r:03d}"] for r in (0, 1)) / 2
    assert f"**{first} minus each method, paired by run**" in table
    assert f"| AL | 2 | {100 * diff:+.1f} (SE " in table
    assert (out / "table.csv").read_text().startswith("method,runs,failed,tests,success_avg,success_ci_low")
    assert (out / "table.png").stat().st_size > 10_000
    # The runs of one seed share their test arenas and the learners' runs are on disk.
    assert (out / "runs" / "AL" / "1" / "policy.npz").is_file()

    # Another experiment never writes into this directory; the same one resumes (nothing to do).
    assert main(["compare", "--task", str(spec), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "holds another experiment (it differs in: methods (" in err and "), tests)" in err
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    assert main(["compare", "--task", str(spec), "--quick", "--out", str(tmp_path / "other"), "--quiet"]) == 2
    assert "holds no nirl-mj experiment" in capsys.readouterr().err
    assert main(["sweep", "--task", str(spec), "--quick", "--out", str(tmp_path / "x"), "--quiet"]) == 2
    assert "is a compare experiment: run it with `nirl-mj compare`" in capsys.readouterr().err
    mtimes = {p: p.stat().st_mtime_ns for p in (out / "cells").iterdir()}
    assert main(quick) == 0
    assert {p: p.stat().st_mtime_ns for p in (out / "cells").iterdir()} == mtimes

    # --report runs nothing: a partial table from the finished cells, the missing ones counted.
    (out / "cells" / "AL-run001.json").unlink()
    assert main([*quick, "--report", "--json"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert last["methods"]["AL"]["runs"] == 1 and last["methods"]["AL"]["failed"] == 1
    assert not (out / "cells" / "AL-run001.json").exists()
    table = (out / "table.md").read_text()
    assert "| AL | 1 (1 missing) |" in table and "Partial report" in table
    # --runs 1: the table of run 0 alone, which every row finished
    assert main([*quick, "--report", "--runs", "1", "--json"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert {(m["runs"], m["failed"]) for m in last["methods"].values()} == {(1, 0)}
    assert "Partial report" not in (out / "table.md").read_text()
    assert (
        main(
            ["compare", "--task", str(spec), "--quick", "--report", "--out", str(tmp_path / "new"), "--quiet"]
        )
        == 2
    )
    assert "holds no started experiment" in capsys.readouterr().err


def test_per_run_demonstrations_final_arenas_and_only(tmp_path, capsys):
    """[demos] per_run: run r learns from its own demonstrations (seeded seed + r), every method of
    the run from the same file; test_domain = "final" draws other test arenas than the development
    domain; --only computes the named methods' cells and reports the others as they are stored;
    --reuse takes the cells of a directory with the same runs' demonstrations."""
    head = (
        'kind = "compare"\nruns = 2\ntests = 2\ntest_domain = "final"\nmethods = ["BC", "rule", "forward"]\n'
    )
    spec, out = tmp_path / "tiny.toml", tmp_path / "out"
    spec.write_text(head + TINY.replace("[demos]\n", "[demos]\nper_run = true\n"))
    args = ["compare", "--task", str(spec), "--out", str(out), "--executor", "serial", "--quiet"]
    assert main([*args, "--only", "BC,rule", "--json"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert {n: m["runs"] for n, m in last["methods"].items()} == {"BC": 2, "rule": 2, "forward": 0}
    assert sorted(p.name for p in (out / "demos").iterdir()) == ["run000.npz", "run001.npz"]
    from nirl_mj.data.dataset import load_dataset

    seeds = [{t.arena_seed for t in load_dataset(out / "demos" / f"run{r:03d}.npz")} for r in (0, 1)]
    assert not seeds[0] & seeds[1]
    e = load_experiment(spec)
    jobs = protocol.run_jobs(e, out, {r: protocol.demos_path(out, e, r) for r in (0, 1)})
    assert {jobs[m, 1].demos_path for m in ("BC", "rule")} == {str(out / "demos" / "run001.npz")}
    development = protocol.run_test_seeds(dataclasses.replace(e, test_domain="test"), 0, seeds[0])
    assert not set(jobs["BC", 0].test_seeds) & set(development)
    # the rest later: the finished cells are kept, the new ones computed
    assert main([*args, "--only", "forward", "--json"]) == 0
    last = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert {m["runs"] for m in last["methods"].values()} == {2}
    assert main([*args, "--only", "PPO"]) == 2
    assert "--only PPO: not a method of tiny" in capsys.readouterr().err
    # --reuse checks each run's own demonstrations: every cell is taken, none computed again
    again = tmp_path / "again"
    assert main([*args[:3], "--out", str(again), *args[5:], "--reuse", str(out)]) == 0
    assert "reuse: 6 finished cells taken from" in capsys.readouterr().err
    for ident in ("BC-run001", "rule-run000", "forward-run001"):
        taken = json.loads((again / "cells" / f"{ident}.json").read_text())
        assert taken["reused_from"] == str(out.resolve())
        assert taken["result"] == json.loads((out / "cells" / f"{ident}.json").read_text())["result"]
    # a published folder (experiment.json and results.json alone) restores per-run cells too: each
    # run's demonstrations are made again from its seed, and its test arenas checked against them
    from nirl_mj.experiments.compare import cell_id
    from nirl_mj.experiments.reuse import restore_published

    published, lost = tmp_path / "published", tmp_path / "lost"
    published.mkdir()
    for name in ("experiment.json", "results.json"):
        (published / name).write_text((out / name).read_text())
    restored, jobs = protocol.prepare(e, lost, protocol.Execution("serial"), lambda _: None)
    assert len(restore_published(published, e, restored, jobs, cell_id)) == 6
    assert main([*args[:3], "--out", str(lost), *args[5:], "--json"]) == 0  # nothing left to compute
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["methods"] == last["methods"]


def test_an_experiment_grows_by_methods_that_keep_its_test_arenas(tmp_path):
    """A method added to an experiment file joins its output directory when every finished cell
    stays valid: the saved methods unchanged, and the new learner visiting no arena the old ones
    did not (so the runs' test arenas stay the same). Anything else is refused."""
    base = 'kind = "compare"\nruns = 2\ntests = 2\n'

    def experiment(methods: list[str], extra: str = ""):
        spec = tmp_path / "grow.toml"
        spec.write_text(base + f"methods = {json.dumps(methods)}\n" + extra + TINY)
        return load_experiment(spec)

    out = protocol.open_output(tmp_path / "out", experiment(["NIRL", "rule"]))
    assert protocol.open_output(out, experiment(["NIRL", "rule", "NIRL-last", "BC"])) == out
    assert [m["name"] for m in json.loads((out / "experiment.json").read_text())["methods"]] == [
        "NIRL", "rule", "NIRL-last", "BC"]  # fmt: skip
    longer = '[method.long]\nkind = "irl"\nconfig = { episodes = 3 }\n'
    with pytest.raises(ExperimentError, match="methods may be added"):
        protocol.open_output(out, experiment(["NIRL", "rule", "NIRL-last", "BC", "long"], longer))
    with pytest.raises(ExperimentError, match=r"differs in: learners \(NIRL-last removed\), methods "
                       r"\(NIRL-last removed; BC removed\)\)"):  # fmt: skip
        protocol.open_output(out, experiment(["NIRL", "rule"]))
    other = protocol.open_output(tmp_path / "other_out", experiment(["NIRL", "long"], longer))
    with pytest.raises(ExperimentError, match=r"differs in: learners \(long: episodes\)\);"):
        protocol.open_output(other, experiment(["NIRL", "long"], longer.replace("3", "4")))


def test_a_default_pinned_or_dropped_in_config_resumes_the_same_output(tmp_path):
    """Pinning a learner setting at the value it already has (in [config] or a method's config)
    changes no cell, so the output directory resumes; a value that changes a learner is refused."""
    base = 'kind = "compare"\nruns = 1\ntests = 2\nmethods = ["NIRL", "n1"]\n'
    gamma = LearnerConfig().loop.gamma

    def experiment(n1: str = "n_step = 1", config: str = ""):
        spec = tmp_path / "pins.toml"
        spec.write_text(base + f'[method.n1]\nkind = "irl"\nconfig = {{ {n1} }}\n' + TINY + config)
        return load_experiment(spec)

    out = protocol.open_output(tmp_path / "out", experiment())
    assert protocol.open_output(out, experiment(f"n_step = 1, gamma = {gamma}", f"gamma = {gamma}\n")) == out
    assert "gamma" not in json.loads((out / "experiment.json").read_text())["config"]  # nothing rewritten
    assert protocol.open_output(out, experiment()) == out
    with pytest.raises(ExperimentError, match="differs in: learners"):
        protocol.open_output(out, experiment(config="gamma = 0.5\n"))


def test_a_method_whose_packages_are_missing_is_refused_before_anything_runs(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(kinds.PACKAGES, "rl", ("gymnasium", "no_such_package_here"))
    spec, out = (
        write_spec(tmp_path, 'kind = "compare"\nruns = 1\ntests = 1\nmethods = ["rule", "PPO-reward"]\n'),
        tmp_path / "out",
    )
    assert main(["compare", "--task", str(spec), "--out", str(out), "--executor", "serial", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        len(err) == 1
        and "PPO-reward: need the optional extra nirl-mj[gym] (no module 'no_such_package_here')" in err[0]
    )
    assert not out.exists()  # refused before OUT was made
    assert main(["compare", "--task", str(spec), "--out", str(out), "--executor", "serial", "--quiet",
                 "--only", "rule"]) == 0  # fmt: skip


def test_fig8_strip_is_written_from_the_first_run(tmp_path):
    head = ('kind = "compare"\ntest_task = "dynamic"\nruns = 2\ntests = 1\nmethods = ["rule"]\n'
            '[strip]\nmethod = "rule"\nsnapshots = 3\nwidth = 64\nheight = 48\n')  # fmt: skip
    spec, out = write_spec(tmp_path, head), tmp_path / "out"
    assert main(["compare", "--task", str(spec), "--out", str(out), "--executor", "serial", "--quiet"]) == 0
    import imageio.v3 as iio

    from nirl_mj.experts.policies import rule_policy
    from nirl_mj.inspect.video import snapshot_strip

    strip = iio.imread(out / "strip.png")
    # three frames side by side, each the arena's square of the 48-pixel frame height
    assert strip.shape[0] == 48 and strip.shape[1] >= 3 * 48
    experiment = load_experiment(spec)
    firsts = [protocol.run_test_seeds(experiment, run, set())[0] for run in range(2)]
    assert firsts[0] != firsts[1]
    again = [iio.imread(snapshot_strip(experiment.test_task, rule_policy, seed, tmp_path / f"{seed}.png", 3,
                                       "top", 64, 48)) for seed in firsts]  # fmt: skip
    assert not np.array_equal(again[0], again[1])  # so the strip tells the runs apart
    np.testing.assert_array_equal(strip, again[0])  # run 0's first test arena
    identity = json.loads((out / "experiment.json").read_text())
    assert identity["test_task"]["arena"]["moving_obstacles"] == 10
    assert identity["task"]["arena"]["moving_obstacles"] == 0


def threads_cell() -> dict:
    import torch

    return {"threads": torch.get_num_threads()}


def test_a_cell_runs_on_one_torch_thread_and_the_caller_keeps_its_own():
    import torch

    torch.set_num_threads(2)
    assert run_cells([Cell("t", threads_cell)], "serial").results == {"t": {"threads": 1}}
    assert torch.get_num_threads() == 2


def test_a_worker_death_costs_no_attempt_to_the_cells_beside_it(tmp_path):
    """Two cells run together and the pool breaks: the one that died is run again alone without an
    attempt counted (it survives its second, lone run), and the one beside it, if it was still
    running, too; either way it finishes, not failed."""
    retries = []
    cells = [Cell("dies", dying_cell, (str(tmp_path),)),
             Cell("slow", counted_cell, (str(tmp_path), "slow", 0))]  # fmt: skip
    with Executor("local", workers=2, retries=0) as runner:
        report = runner.run(cells, on_retry=lambda cell_id, why: retries.append((cell_id, why)))
    assert report.results["dies"] == {"survived": True} and not report.failures, report.failures
    assert retries and all("no attempt counted" in why for _, why in retries)
    assert "dies" in {cell_id for cell_id, _ in retries}
    assert report.results["slow"]["name"] == "slow"


def test_reuse_takes_the_same_cells_of_an_earlier_comparison_and_computes_the_rest(tmp_path, capsys):
    def spec(name: str, methods: list[str], tests: int = 2) -> Path:
        head = f'kind = "compare"\nruns = 2\ntests = {tests}\nmethods = {json.dumps(methods)}\n'
        return write_spec(tmp_path, head, name)

    def compare(path: Path, out: Path, *extra: str) -> int:
        return main(
            ["compare", "--task", str(path), "--out", str(out), "--executor", "serial", "--quiet", *extra]
        )

    old, new, fresh = tmp_path / "old", tmp_path / "new", tmp_path / "fresh"
    assert compare(spec("old.toml", ["NIRL", "rule"]), old) == 0
    wider = spec("new.toml", ["NIRL", "rule", "NIRL-classifier"])
    assert compare(wider, new, "--reuse", str(old)) == 0
    assert "reuse: 4 finished cells taken from" in capsys.readouterr().err
    assert compare(wider, fresh) == 0  # the same experiment, every cell computed here
    for ident in ("NIRL-run000", "NIRL-run001", "rule-run000", "rule-run001"):
        taken = json.loads((new / "cells" / f"{ident}.json").read_text())
        assert taken["reused_from"] == str(old.resolve())
        assert taken["result"] == json.loads((fresh / "cells" / f"{ident}.json").read_text())["result"]
    assert "reused_from" not in json.loads((new / "cells" / "NIRL-classifier-run000.json").read_text())
    assert (new / "runs" / "NIRL" / "1" / "policy.npz").is_file()  # the training run came along
    # Only methods and learner settings may differ; and nothing is taken twice.
    assert (
        compare(spec("other.toml", ["NIRL", "rule", "forward"], tests=3), tmp_path / "x", "--reuse", str(old))
        == 2
    )
    assert "another experiment (it differs in: tests)" in capsys.readouterr().err
    assert compare(wider, new, "--reuse", str(old)) == 0
    assert "reuse: 0 finished cells taken" in capsys.readouterr().err


def test_published_cells_are_restored_into_a_lost_directory_and_the_resume_computes_the_rest(tmp_path):
    """docs/scripts/restore_cells.py's function: a published results folder (experiment.json and
    results.json alone) gives back the runs asked, renamed where told; the resume then computes the
    rest and the table is the published one. Another experiment, other test arenas, a rename naming
    a method neither side holds, or runs outside the experiment are refused before anything is
    written; another computation or an interrupted training run is left to be computed."""
    from nirl_mj.experiments.compare import cell_id
    from nirl_mj.experiments.protocol import Execution, prepare
    from nirl_mj.experiments.reuse import restore_published

    head = 'kind = "compare"\nruns = 2\ntests = 2\nmethods = {}\n'
    policy = '[method.NIRL-policy]\nkind = "irl"\nconfig = { matching = "policy" }\n'
    old_spec = write_spec(tmp_path, head.format('["NIRL-policy", "rule"]'), "old.toml")
    old_spec.write_text(old_spec.read_text() + policy)
    new_spec = write_spec(tmp_path, head.format('["NIRL", "rule", "forward"]'), "new.toml")
    run = ["compare", "--executor", "serial", "--quiet"]
    assert main([*run, "--task", str(old_spec), "--out", str(tmp_path / "old")]) == 0
    published = tmp_path / "published"  # what docs/results keeps of an experiment
    published.mkdir()
    for name in ("experiment.json", "results.json"):
        (published / name).write_text((tmp_path / "old" / name).read_text())

    experiment, lost = load_experiment(new_spec), tmp_path / "lost"
    out, jobs = prepare(experiment, lost, Execution("serial"), lambda _: None)
    said = []
    # Refused before anything is written: run 1's test arenas differ (run 0's would be taken).
    moved = {
        k: dataclasses.replace(j, test_seeds=j.test_seeds[::-1]) if k[1] == 1 else j for k, j in jobs.items()
    }
    with pytest.raises(ExperimentError, match="run 1's test arenas differ.*nothing restored"):
        restore_published(published, experiment, out, moved, cell_id, {"NIRL": "NIRL-policy"})
    assert not list((lost / "cells").glob("*.json"))
    with pytest.raises(ExperimentError, match="GAIL is not a method of"):
        restore_published(published, experiment, out, jobs, cell_id, {"NIRL": "GAIL"})
    with pytest.raises(ExperimentError, match="none is a run of this experiment"):
        restore_published(published, experiment, out, jobs, cell_id, runs=range(5, 7))
    # rule's cells are not NIRL's computation; an interrupted training run is left to the resume.
    assert restore_published(
        published, experiment, out, jobs, cell_id, {"NIRL": "rule"}, range(1), said.append
    ) == ["rule-run000"]
    assert "not taken, another definition or learner settings" in said[0] and "NIRL (from rule)" in said[0]
    (lost / "cells" / "rule-run000.json").unlink()
    interrupted = Path(jobs["NIRL", 1].run_dir)
    interrupted.mkdir(parents=True)
    assert restore_published(
        published, experiment, out, jobs, cell_id, {"NIRL": "NIRL-policy"}, range(1, 2)
    ) == ["rule-run001"]
    interrupted.rmdir()
    (lost / "cells" / "rule-run001.json").unlink()
    said.clear()
    taken = restore_published(
        published, experiment, out, jobs, cell_id, {"NIRL": "NIRL-policy"}, range(1), said.append
    )
    assert taken == ["NIRL-run000", "rule-run000"], said  # run 0 only; forward is not published
    record = json.loads((lost / "cells" / "NIRL-run000.json").read_text())
    assert (record["reused_as"], record["result"]["method"], "seconds" in record) == (
        "NIRL-policy",
        "NIRL",
        False,
    )
    assert record["restored_from"] == str(published.resolve() / "results.json")
    # Without the rename, the published NIRL-policy is not NIRL; rule's run 1 is taken.
    assert restore_published(published, experiment, out, jobs, cell_id, log=said.append) == ["rule-run001"]
    assert main([*run, "--task", str(new_spec), "--out", str(lost)]) == 0  # the resume: NIRL's run 1, forward
    old = json.loads((tmp_path / "old" / "results.json").read_text())["cells"]
    new = json.loads((lost / "results.json").read_text())["cells"]
    for r in (0, 1):
        assert new[f"NIRL-run00{r}"] == {**old[f"NIRL-policy-run00{r}"], "method": "NIRL"}
        assert new[f"rule-run00{r}"] == old[f"rule-run00{r}"]
    assert (
        not (lost / "runs" / "NIRL" / "0").exists()
        and (lost / "runs" / "NIRL" / "1" / "policy.npz").is_file()
    )

    with pytest.raises(ExperimentError, match="not a method of this experiment"):
        restore_published(published, experiment, out, jobs, cell_id, {"NIRL-policy": "NIRL"})
    other = dataclasses.replace(experiment, tests=3)
    with pytest.raises(ExperimentError, match=r"another experiment \(it differs in: tests\)"):
        restore_published(published, other, out, jobs, cell_id)
    with pytest.raises(ExperimentError, match="not a published experiment"):
        restore_published(tmp_path / "nowhere", experiment, out, jobs, cell_id)
    # A published NIRL with a retired setting at a value that did something is not today's NIRL: its
    # cells are left to be computed, and the rest is restored (arenas are chosen without that setting).
    saved = json.loads((published / "experiment.json").read_text())
    saved["learners"]["NIRL"] = {**saved["learners"]["NIRL-policy"], "reward_ceiling": 0.5}
    policy_method = next(m for m in saved["methods"] if m["name"] == "NIRL-policy")
    saved["methods"].append({**policy_method, "name": "NIRL"})
    (published / "experiment.json").write_text(json.dumps(saved))
    results = json.loads((published / "results.json").read_text())
    for r in (0, 1):
        results["cells"][f"NIRL-run00{r}"] = {**results["cells"][f"NIRL-policy-run00{r}"], "method": "NIRL"}
    (published / "results.json").write_text(json.dumps(results))
    again, again_jobs = prepare(experiment, tmp_path / "again", Execution("serial"), lambda _: None)
    said.clear()
    taken = restore_published(published, experiment, again, again_jobs, cell_id, log=said.append)
    assert taken == ["rule-run000", "rule-run001"] and "not taken" in said[0] and "NIRL" in said[0]
    # A learner this version cannot read for another reason is still a clear error.
    saved["learners"]["NIRL"] = {**saved["learners"]["NIRL-policy"], "no_such_setting": 1}
    (published / "experiment.json").write_text(json.dumps(saved))
    with pytest.raises(ExperimentError, match="cannot be read by this version"):
        restore_published(published, experiment, again, again_jobs, cell_id)


def test_a_row_that_does_not_train_is_its_renamed_twin_with_the_same_definition(tmp_path):
    """A Stable-Baselines3 row defined as a saved one but for its name is that row's computation
    (its seed is the run's, its name only a label); another number of decisions is not."""
    from nirl_mj.experiments.reuse import method_sources, saved_form

    head = 'kind = "compare"\nruns = 1\ntests = 2\nmethods = {}\n'
    twin = '[method.{}]\nkind = "rl"\nalgo = "gail"\nselection = "demo_balanced"\nenvs = 8\nsteps = {}\n'
    saved = saved_form(load_experiment(write_spec(tmp_path, head.format('["GAIL", "rule"]'), "old.toml")))
    spec = write_spec(tmp_path, head.format('["GAIL-twin", "GAIL-short", "rule"]'), "new.toml")
    spec.write_text(spec.read_text() + twin.format("GAIL-twin", "50_000") + twin.format("GAIL-short", 2048))
    sources = method_sources(saved, load_experiment(spec))
    assert sources == {"GAIL-twin": ["GAIL"], "GAIL-short": [], "rule": ["rule"]}


def test_reuse_takes_a_renamed_variant_with_the_same_learner_settings_under_the_new_name(tmp_path, capsys):
    """A named variant that became the default (``NIRL-policy`` then, ``NIRL`` now) is the same
    computation; one whose resolved settings differ (``NIRL-classifier``) is computed."""
    head = 'kind = "compare"\nruns = 1\ntests = 2\nmethods = {}\n'
    policy = '[method.NIRL-policy]\nkind = "irl"\nconfig = { matching = "policy" }\n'
    old_spec = write_spec(tmp_path, head.format('["NIRL-policy"]'), "old.toml")
    old_spec.write_text(old_spec.read_text() + policy)
    new_spec = write_spec(tmp_path, head.format('["NIRL", "NIRL-classifier"]'), "new.toml")
    old, new = tmp_path / "old", tmp_path / "new"
    run = ["compare", "--executor", "serial", "--quiet"]
    assert main([*run, "--task", str(old_spec), "--out", str(old)]) == 0
    assert main([*run, "--task", str(new_spec), "--out", str(new), "--reuse", str(old)]) == 0
    assert "reuse: 1 finished cells taken from" in capsys.readouterr().err
    before = json.loads((old / "cells" / "NIRL-policy-run000.json").read_text())
    taken = json.loads((new / "cells" / "NIRL-run000.json").read_text())
    assert (taken["id"], taken["reused_as"], taken["result"]["method"]) == (
        "NIRL-run000",
        "NIRL-policy",
        "NIRL",
    )
    assert {**taken["result"], "method": "NIRL-policy"} == before["result"]
    assert (new / "runs" / "NIRL" / "0" / "policy.npz").is_file()
    assert "reused_from" not in json.loads((new / "cells" / "NIRL-classifier-run000.json").read_text())
    assert list(json.loads((new / "results.json").read_text())["methods"]) == ["NIRL", "NIRL-classifier"]
    # Taken again under its own name, the cell names only where it now came from.
    assert main([*run, "--task", str(new_spec), "--out", str(tmp_path / "third"), "--reuse", str(new)]) == 0
    again = json.loads((tmp_path / "third" / "cells" / "NIRL-run000.json").read_text())
    assert again["reused_from"] == str(new.resolve()) and "reused_as" not in again


@pytest.mark.parametrize("key, value", [("test_domain", "final"), ("demos", {"per_run": True})])
def test_a_key_written_only_when_set_is_compared_when_it_goes_back_to_its_default(tmp_path, key, value):
    """``test_domain`` and ``demos_per_run`` enter the identity only when set: an OUT computed with one
    set is another experiment for a file without it (it resumed it before, mixing test arenas)."""
    base = {"kind": "compare", "methods": ["rule"], "runs": 1, "tests": 2}
    out = tmp_path / "out"
    protocol.prepare(from_dict({**base, key: value}, "set.toml"), out, protocol.Execution("serial"), print)
    with pytest.raises(ExperimentError, match="holds another experiment"):
        protocol.prepare(from_dict(base, "unset.toml"), out, protocol.Execution("serial"), print)


def test_a_stored_cell_of_another_id_method_or_run_is_not_taken_for_a_finished_one(tmp_path):
    metrics = {"success_rate": 1.0, "collision_rate": 0.0, "timeout_rate": 0.0, "physics_error_rate": 0.0,
               "mean_path_length": 1.0, "spl": 1.0, "tests": 2}  # fmt: skip
    store = CellStore(tmp_path, check=protocol.cell_problem)
    store.save("rule-run000", {**metrics, "method": "rule", "run": 0}, 1.0, 1)
    assert store.load("rule-run000") is not None
    shutil.copy(store.path("rule-run000"), store.path("forward-run000"))  # its record says rule-run000
    assert store.load("forward-run000") is None
    store.save("forward-run001", {**metrics, "method": "rule", "run": 1}, 1.0, 1)  # another method's
    store.save("forward-run002", {**metrics, "method": "forward", "run": 7}, 1.0, 1)  # another run's
    assert store.load("forward-run001") is None and store.load("forward-run002") is None
    # suite and sweep cells end or continue with the method's run
    for ident in ("demos-10.rule-run000", "rule-run000-n020-v2"):
        store.save(ident, {**metrics, "method": "rule", "run": 0}, 1.0, 1)
        assert store.load(ident) is not None


def test_sweep_plot_draws_speeds_with_the_same_curve_once(tmp_path, monkeypatch):
    """Fig. 6: forward's success does not depend on the speed; its three curves would hide each other."""
    from types import SimpleNamespace

    from nirl_mj.experiments import sweep

    drawn = {}
    monkeypatch.setattr(sweep, "write_figure", lambda path, fig: drawn.setdefault("fig", fig))
    methods = [SimpleNamespace(name="NIRL"), SimpleNamespace(name="forward")]
    experiment = SimpleNamespace(name="s", runs=2, tests=10, speeds=(1.0, 2.0, 3.0), methods=methods)

    def cell(method, speed, obstacles, avg):
        return {"method": method, "speed": speed, "obstacles": obstacles, "runs": 2, "avg": avg,
                "worst": avg - 0.1, "best": avg}  # fmt: skip

    cells = [cell("NIRL", v, n, 0.9 - 0.1 * v - 0.01 * n) for v in (1.0, 2.0, 3.0) for n in (5, 10)]
    cells += [cell("forward", v, n, 0.6 - 0.01 * n) for v in (1.0, 2.0, 3.0) for n in (5, 10)]
    sweep.line_plot(tmp_path / "p.png", {"cells": cells}, experiment)
    labels = [line.get_label() for line in drawn["fig"].axes[0].get_lines()]
    assert labels == ["NIRL, 1 m/s", "NIRL, 2 m/s", "NIRL, 3 m/s", "forward, 1, 2 and 3 m/s (the same)"]
