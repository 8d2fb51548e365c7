"""The main job's report and the compare table read without the code (issue 35): every figure has a
caption with its units, every term is defined, the selected iteration is marked on the training
curves, paths.png has its axes in metres and always forward's path on top, and the report's path
length counts the successful tests only."""

import json
import re
import subprocess
import sys

import numpy as np
import pytest

from nirl_mj.data.dataset import save_dataset
from nirl_mj.data.outcomes import metrics_of
from nirl_mj.data.rundir import RunDir
from nirl_mj.data.trajectory import Trajectory
from nirl_mj.experiments import compare
from nirl_mj.experiments.main_job import (
    ROWS,
    main_experiment,
    report_rows,
    rewrite_report,
    success_path_length,
    write_report,
)
from nirl_mj.experiments.reads import method_reads
from nirl_mj.inspect import figures
from nirl_mj.learn.bc import CloneSettings
from nirl_mj.learn.config import LearnerConfig
from nirl_mj.sim import spec

TASK = spec.load_task("navigate")
METRIC_KEYS = ("margin", "cost", "dw1", "dw2", "demo_accuracy", "demo_balanced_accuracy", "success_rate")
UNITS = ("metres", "m)", "iteration", "percent", "fraction", "seconds", "decisions")


def episode(outcome: str, poses: list[tuple[float, float]], seed: int = 1) -> Trajectory:
    """A test episode of ``navigate`` (start (10, 10), target (90, 90)) along ``poses``."""
    t = len(poses) - 1
    features = np.zeros((t + 1, 16), np.float32)
    features[:, 7] = 1  # V: the target ahead
    return Trajectory(features=features, actions=np.zeros(t, np.int8),
                      ranges=np.ones((t + 1, 9), np.float32), poses=np.array([[x, y, 0.0] for x, y in poses]),
                      times=np.arange(t + 1) * 0.5, arena_seed=seed, task=TASK.to_dict(), speed=2.0,
                      outcome=outcome, demonstrator="test")  # fmt: skip


# A crash after 5 m, and a success that drives 10 + 140 = 150 m: the mean over both (77.5 m) looks
# shorter than any success.
CRASH = episode("collision", [(10, 10), (13, 14)])
SUCCESS = episode("target", [(10, 10), (10, 20), (94, 132)])


def test_the_path_length_counts_the_successful_tests_only():
    assert metrics_of([CRASH, SUCCESS])["mean_path_length"] == pytest.approx(77.5)
    assert success_path_length([CRASH, SUCCESS]) == pytest.approx(150.0)
    assert success_path_length([CRASH, CRASH]) is None
    stored = {"crashes": metrics_of([CRASH, CRASH]), "mixed": metrics_of([CRASH, SUCCESS])}
    table = figures.results_table(report_rows(stored, {"crashes": [CRASH, CRASH], "mixed": [CRASH, SUCCESS]}))
    assert "| path of successful tests (m) |" in table
    assert re.search(r"\| crashes \| 0% \| 100% \| 0% \| - \|", table)
    assert re.search(r"\| mixed \| 50% \| 50% \| 0% \| 150\.0 \|", table)
    assert "77.5" not in table and "5.0" not in table
    # without the test episodes (a stored results.json alone) the all-tests mean is not shown at all
    assert "path" not in figures.results_table(stored) and "77.5" not in figures.results_table(stored)
    # the stored results keep their keys: report_rows copies them
    assert "success_path_length" not in stored["mixed"]


def _metrics_rows(n: int) -> list[dict]:
    rng = np.random.default_rng(0)
    values = rng.random((n, len(METRIC_KEYS)))
    rows = [dict(zip(METRIC_KEYS, map(float, values[i]), strict=True)) for i in range(n)]
    return [{"episode": i, **row, "validation_success": None} for i, row in enumerate(rows)]


def _selected_lines(fig) -> list:
    return [
        line for ax in fig.axes for line in ax.get_lines() if line.get_label().startswith("selected policy")
    ]


def test_every_training_figure_marks_the_selected_iteration():
    figs = figures.training_figures(_metrics_rows(12), selected=7)
    assert set(figs) == {"margin.png", "cost.png", "weights.png", "training.png"}
    for name, fig in figs.items():
        (line,) = _selected_lines(fig)
        assert line.get_label() == "selected policy (iteration 7)", name
        assert list(line.get_xdata()) == [7, 7], name  # a vertical line at iteration 7
        ax = fig.axes[0]
        assert "selected policy (iteration 7)" in [t.get_text() for t in ax.get_legend().get_texts()], name
        assert ax.get_xlabel().startswith("iteration"), name
        # a series without any value (validation success of a run that never validated) is left out
        assert "validation success" not in [line.get_label() for line in ax.get_lines()], name
    unmarked = figures.training_figures(_metrics_rows(3))
    assert not any(_selected_lines(fig) for fig in unmarked.values())


def test_drawing_a_figure_changes_no_global_matplotlib_state(tmp_path):
    """A notebook's or GUI program's backend and open figures stay as they were: nirl_mj draws
    without pyplot (nirl_mj.inspect.canvas)."""
    rows = [{"episode": i, **dict.fromkeys(METRIC_KEYS, 0.5 + i)} for i in range(3)]
    script = (
        "import matplotlib; matplotlib.use('svg'); import matplotlib.pyplot as plt\n"
        "mine = plt.figure()\n"
        "from nirl_mj.inspect import figures\n"
        f"figures.training_plots({rows!r}, {str(tmp_path)!r}, selected=1)\n"
        "print(matplotlib.get_backend(), plt.get_fignums(), plt.gcf() is mine)\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["svg", "[1]", "True"] and (tmp_path / "margin.png").stat().st_size > 1000


def test_paths_figure_has_axes_in_metres_and_always_forward_on_top():
    runs = {
        "NIRL": [SUCCESS, episode("target", [(10, 10), (60, 60), (90, 89)], seed=2)],
        "rule on phi(s)": [SUCCESS, SUCCESS],
        "always forward": [CRASH, episode("collision", [(10, 10), (30, 30)], seed=2)],
    }
    fig = figures.paths_figure(runs, arenas=3)
    assert len(fig.axes) == 2  # as many arenas as every policy drove
    for ax in fig.axes:
        assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
        paths = {line.get_label().split(":")[0]: line for line in ax.get_lines() if ":" in line.get_label()}
        assert set(paths) == set(runs)
        forward = paths["always forward"]
        assert forward.get_zorder() > max(p.get_zorder() for n, p in paths.items() if n != "always forward")
        assert forward.get_linewidth() < paths["NIRL"].get_linewidth()  # NIRL's wider line shows beside it
        assert forward.get_color() != paths["NIRL"].get_color()
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert any(
            label.startswith("always forward: collided, ") and label.endswith(" m") for label in labels
        )


def _fake_main_job(tmp_path):
    """A finished main job's inputs to ``write_report``: a NIRL run record and metrics, the results and
    every row's test episodes (always forward crashes early; the constant control never succeeds)."""
    config = LearnerConfig.preset("default").to_dict()
    run = RunDir(tmp_path / "runs" / "NIRL" / "0")
    run.write_record({"task": TASK.to_dict(), "config": config, "seed": 0, "demos": "demos.npz",
                      "demo_seeds": [], "validation_seeds": [], "iterations": 12, "selected_iteration": 7,
                      "selection": {"rule": "demo_balanced", "iteration": 7}})  # fmt: skip
    run.start_metrics()
    for row in _metrics_rows(12):
        run.append_metrics(row)
    paths = {row: [SUCCESS, CRASH] for row in ROWS.values()}
    paths["always forward"] = [CRASH, CRASH]
    paths["control: constant reward"] = [CRASH, episode("timeout", [(10, 10), (20, 10), (20, 20)])]
    results = {row: {**metrics_of(episodes), "reads": ["features"]} for row, episodes in paths.items()}
    return run, results, paths


def test_the_report_captions_every_figure_and_defines_its_terms(tmp_path):
    run, results, paths = _fake_main_job(tmp_path)
    before = json.dumps(results, sort_keys=True)
    report = write_report(tmp_path, run, main_experiment(TASK, tests=2), results, paths, 30).read_text()
    assert json.dumps(results, sort_keys=True) == before  # the stored results are not changed

    lines = report.splitlines()
    images = [
        (i, m.group(1)) for i, line in enumerate(lines) if (m := re.match(r"!\[[^\]]*\]\(([^)]+)\)", line))
    ]
    assert {file for _, file in images} == {
        "margin.png",
        "cost.png",
        "weights.png",
        "training.png",
        "paths.png",
    }
    for i, file in images:
        assert (tmp_path / file).stat().st_size > 10_000, file
        caption = next(line for line in lines[i + 1 :] if line.strip())
        assert caption.startswith("*Figure "), file
        text = " ".join(lines[i + 1 : lines.index("", i + 2)])
        assert text.endswith("*") and any(unit in text for unit in UNITS), file
        if file != "paths.png":
            assert "the selected policy (iteration 7)" in text, file

    # the paper named once, every term defined, the paper's figure numbers explained
    flat = " ".join(report.split())
    title = "*Neural Inverse Reinforcement Learning with a Nonlinear Policy Representation*"
    assert f"*the NIRL paper*: {title}." in flat and "Xia" not in flat
    terms = ("*margin t*", "*network cost J(Omega)*", "*path of successful tests (m)*", "*selected policy*",
             "*iteration*", "*balanced accuracy*",
             "*SPL*, success weighted by path length (Anderson et al. 2018)",
             "*SCT*, success weighted by completion time (Yokoyama et al. 2021)")  # fmt: skip
    for term in terms:
        assert term in flat, term
    for figure in ("Fig. 4a", "Fig. 4b", "Fig. 5", "Fig. 7"):
        assert f"NIRL paper's {figure}" in flat, figure
    # behaviour cloning as learn/bc.py does it now
    bc = CloneSettings.of("default")
    assert (
        f"{bc.hidden_units} hidden units" in flat
        and "class-balanced" in flat
        and "trains the same" not in flat
    )

    # the path column: successful tests only, "-" where none succeeded
    table = {line.split(" | ")[0][2:]: line.split(" | ") for line in lines if line.startswith("| ")}
    header = table.pop("policy")
    path = header.index("path of successful tests (m)")
    assert table["NIRL"][path] == f"{success_path_length([SUCCESS]):.1f}"
    assert table["always forward"][path] == table["control: constant reward"][path] == "-"


def test_the_report_marks_a_reference_as_compare_does(tmp_path):
    """The report's reads column marks a method that reads a task signal as compare's and a suite's
    tables do (``reads.reads_text``): the progress control reads the task's reward."""
    run, results, paths = _fake_main_job(tmp_path)
    experiment = main_experiment(TASK, tests=2)
    for method in experiment.methods:
        results[ROWS[method.name]]["reads"] = method_reads(method, experiment.config)
    report = write_report(tmp_path, run, experiment, results, paths, 30).read_text()
    rows = {line.split(" | ")[0][2:]: line for line in report.splitlines() if line.startswith("| ")}
    reference = "| **reference:** demonstrations, features, episode_end, task_reward |"
    assert rows["control: progress reward"].endswith(reference)
    assert rows["NIRL"].endswith("| demonstrations, features, episode_end |")
    assert rows["control: constant reward"].endswith("| demonstrations, features, episode_end |")
    assert rows["rule on phi(s)"].endswith("| **reference:** features, hand_written |")
    assert "a **reference** reads a task signal that a learner from demonstrations does not" in " ".join(
        report.split()
    )


def test_the_compare_table_defines_its_terms_and_captions_its_figure(tmp_path):
    experiment = main_experiment(TASK, tests=2)
    results = {compare.cell_id(m.name, 0): metrics_of([SUCCESS, CRASH]) for m in experiment.methods}
    summary = compare.summarise(experiment, results)
    summary["failures"] = []
    compare.write_outputs(tmp_path, experiment, summary, results)
    text = (tmp_path / "table.md").read_text()
    lines = text.splitlines()
    (image,) = [i for i, line in enumerate(lines) if line.startswith("![")]
    caption = next(line for line in lines[image + 1 :] if line.strip())
    assert caption.startswith("*Figure") and "percent" in caption
    flat = " ".join(text.split())
    assert "*SPL*, success weighted by path length (Anderson et al. 2018)" in flat
    title = "*Neural Inverse Reinforcement Learning with a Nonlinear Policy Representation*"
    assert f"the NIRL paper ({title}) reports" in flat and "Xia" not in flat


def test_rewrite_report_rewrites_the_report_alone(tmp_path):
    run, results, paths = _fake_main_job(tmp_path)
    experiment = main_experiment(TASK, tests=2)
    methods = [{"name": m.name, "kind": m.kind, "variant": m.variant} for m in experiment.methods]
    saved = {"kind": "main", "task": TASK.to_dict(), "seed": 0, "tests": 2, "expert": "sensor", "demos": 30}
    (tmp_path / "experiment.json").write_text(json.dumps({**saved, "methods": methods}))
    (tmp_path / "results.json").write_text(json.dumps({"task": "navigate", "seed": 0, "results": results}))
    (tmp_path / "tests").mkdir()
    for name, row in ROWS.items():
        save_dataset(tmp_path / "tests" / f"{name}.npz", paths[row])
    save_dataset(tmp_path / "demos.npz", [SUCCESS, SUCCESS, SUCCESS])
    kept = {f: f.read_bytes() for f in tmp_path.rglob("*") if f.is_file()}
    report = " ".join(rewrite_report(tmp_path).read_text().split())
    assert "3 demonstrations by the sensor expert" in report and "selected policy: iteration 7" in report
    assert {f: f.read_bytes() for f in kept} == kept  # every stored file as it was
    assert {f.name for f in tmp_path.iterdir() if f.suffix == ".png"} == {
        "margin.png", "cost.png", "weights.png", "training.png", "paths.png"}  # fmt: skip
