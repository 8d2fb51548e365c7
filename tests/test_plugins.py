"""Methods from other packages (entry point group ``nirl_mj.methods``): found by name, trained through
the same interface as the built-in ones, held to the protocol's rules, resumed after a kill."""

import csv
import inspect
import json
import os
import sys
import textwrap
from pathlib import Path

import pytest

pytest.importorskip("gymnasium", reason="the plugin adapter's environments need nirl-mj[gym]")

from helpers import TINY_TABLES, cell_times, killed_after_cells  # noqa: E402

from nirl_mj.cli import main  # noqa: E402
from nirl_mj.experiments import protocol  # noqa: E402
from nirl_mj.experiments.definition import METHOD_KINDS, ExperimentError, from_dict  # noqa: E402
from nirl_mj.experiments.kinds import KINDS  # noqa: E402
from nirl_mj.experiments.plugins import discovered  # noqa: E402
from nirl_mj.experiments.reads import method_reads  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

PACKAGE = '''
"""A throwaway method package: nothing here imports nirl-mj."""
import numpy as np


class Walker:
    """Drives its environments for a few episodes (recording what it was given), then always
    answers with the action it was told."""

    reads = ("demonstrations", "features", "episode_end")
    observation = "features"

    def __init__(self, action=0, episodes=2, arena=None, shape=None, forked=False, reads=None):
        self.action, self.episodes, self.arena, self.shape = action, episodes, arena, shape
        self.forked = forked
        if reads is not None:
            self.reads = tuple(reads)

    def train(self, demonstrations, make_env, budget, seed, workdir):
        if self.forked:  # environments in forked processes: the budget is copied without pickling
            import gymnasium

            vector = gymnasium.vector.AsyncVectorEnv([make_env, make_env], context="fork")
            try:
                vector.reset()
            finally:
                vector.close(terminate=True)
        env = make_env()
        shape = None if demonstrations is None else list(demonstrations["observations"].shape)
        seen = {"rewards": [], "infos": [], "shape": shape}
        for _ in range(self.episodes):
            obs, info = env.reset(seed=self.arena)
            seen["infos"].append(info)
            done = False
            while not done:
                obs, reward, terminated, truncated, info = env.step(self.action)
                seen["rewards"].append(reward)
                done = terminated or truncated
        import json, os
        with open(os.path.join(workdir, "seen.json"), "w") as f:
            json.dump({**seen, "rewards": sorted(set(seen["rewards"]))}, f)
        if self.shape:
            return lambda observation: np.zeros(self.shape, np.int64)
        return lambda observation: self.action


class Silent:
    observation = "features"

    def train(self, demonstrations, make_env, budget, seed, workdir):
        return lambda observation: 0


class Still:
    """Never drives: its policy is the demonstrations' first action, or ``answer`` where given
    (after ``after`` decisions)."""

    reads = ("demonstrations", "features")
    observation = "features"

    def __init__(self, answer=None, after=0):
        self.answer, self.after = answer, after

    def train(self, demonstrations, make_env, budget, seed, workdir):
        first, calls = int(demonstrations["actions"][0]), [0]

        def policy(observation):
            calls[0] += 1
            return first if self.answer is None or calls[0] <= self.after else self.answer

        return policy


class Breaks(Still):
    """Its policy raises after ``after`` decisions."""

    def train(self, demonstrations, make_env, budget, seed, workdir):
        calls = [0]

        def policy(observation):
            calls[0] += 1
            if calls[0] > self.after:
                raise ValueError("policy broke at test time")
            return 0

        return policy


class Locked(Still):
    """Records whether its workdir was locked while it trained."""

    def train(self, demonstrations, make_env, budget, seed, workdir):
        import json, os

        lock = os.path.join(os.path.dirname(workdir), "." + os.path.basename(workdir) + ".lock")
        with open(os.path.join(workdir, "locked.json"), "w") as f:
            json.dump(os.path.exists(lock), f)
        return super().train(demonstrations, make_env, budget, seed, workdir)


class Raiser(Still):
    """Its own error mid-training (``demonstrations`` is None: it did not declare them)."""

    reads = ("features",)

    def train(self, demonstrations, make_env, budget, seed, workdir):
        return demonstrations["actions"]


class BadSignature(Still):
    def train(self, demos):
        return lambda observation: 0


class Picky(Still):
    def __init__(self, k=1):
        if k < 1:
            raise ValueError(f"k = {k}: must be >= 1")
        super().__init__()


def still_of(answer):
    """A factory: the entry point may name a function that makes the method from its settings."""
    return Still(answer=answer)


STILL = Still()
'''

TINY = TINY_TABLES


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """The throwaway package, installed as pip would install it (a module and its dist-info with the
    entry points) in a folder on the import path of this process and of every process it starts."""
    site = tmp_path / "site"
    (site / "walker_method").mkdir(parents=True)
    (site / "walker_method" / "__init__.py").write_text(PACKAGE)
    info = site / "walker_method-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: walker-method\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(
        "[nirl_mj.methods]\nWalker = walker_method:Walker\nSilent = walker_method:Silent\n"
        "Still = walker_method:Still\nRaiser = walker_method:Raiser\nBreaks = walker_method:Breaks\n"
        "Locked = walker_method:Locked\n"
        "BadSignature = walker_method:BadSignature\nPicky = walker_method:Picky\n"
        "StillOf = walker_method:still_of\nSTILL = walker_method:STILL\n"
    )
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]))
    return site


def spec(tmp_path: Path, methods: str, extra: str = "") -> Path:
    path = tmp_path / "exp.toml"
    path.write_text(f'kind = "compare"\nruns = 2\ntests = 2\nmethods = {methods}\n{extra}{TINY}')
    return path


def failed_lines(capsys) -> list[str]:
    """The FAILED lines a comparison printed (one per failed cell)."""
    return [line for line in capsys.readouterr().err.splitlines() if line.startswith("FAILED")]


def compare(path: Path, out: Path, *extra: str) -> list[str]:
    return ["compare", "--task", str(path), "--out", str(out), "--executor", "serial", "--quiet", *extra]


def test_every_kind_trains_through_one_interface_and_the_protocol_special_cases_none():
    assert set(KINDS) == set(METHOD_KINDS)
    source = inspect.getsource(protocol)
    assert ".kind ==" not in source and "kind in (" not in source  # no kind is special-cased there


def test_an_installed_method_is_a_method_name_with_what_it_reads(installed, tmp_path, capsys):
    assert {"Walker", "Silent"} <= set(discovered())
    experiment = from_dict({"kind": "compare", "methods": ["NIRL", "Walker"]}, "e.toml")
    walker = experiment.methods[1]
    assert (walker.kind, walker.plugin) == ("plugin", "Walker")
    assert method_reads(walker) == ["demonstrations", "features", "episode_end"]
    identity = experiment.identity()["methods"][1]
    assert identity["version"] == "walker-method 1.0"  # another version would be another experiment


def test_an_installed_method_runs_in_an_experiment_within_the_protocols_rules(installed, tmp_path):
    path, out = (
        spec(tmp_path, '["Walker", "rule"]', "[method.Walker]\nsettings = { action = 0 }\n"),
        tmp_path / "out",
    )
    assert main(compare(path, out)) == 0
    seen = json.loads((out / "runs" / "Walker" / "0" / "seen.json").read_text())
    assert seen["rewards"] == [0.0] and all(info == {} for info in seen["infos"])  # no reward, no outcome
    assert seen["shape"][1] == 16
    with open(out / "table.csv", newline="") as f:
        rows = {r["method"]: r for r in csv.DictReader(f)}
    assert rows["Walker"]["runs"] == "2"


def test_a_method_that_does_not_declare_the_demonstrations_is_not_given_them(installed, tmp_path):
    reads = '["features", "episode_end"]'
    path = spec(tmp_path, '["Walker"]', f"[method.Walker]\nsettings = {{ reads = {reads} }}\n")
    assert main(compare(path, tmp_path / "out", "--runs", "1")) == 0
    assert json.loads((tmp_path / "out" / "runs" / "Walker" / "0" / "seen.json").read_text())["shape"] is None


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ("{ arena = TEST }", "method 'Walker' asked for arena TEST, one of its run's test arenas"),
        ("{ shape = 6 }", "method 'Walker': its policy answered an observation of shape (16,) with"),
        ("{ episodes = 50 }", "method 'Walker' drove more than its budget of 200 decisions"),
        (
            '{ reads = ["demonstrations", "features"] }',
            "method 'Walker' drives the robot (make_env): declare episode_end in its reads",
        ),
        pytest.param(
            "{ forked = true }",
            "method 'Walker': its environments run in this process (a process vector",
            # the refusal raised in the forked workers, which Gymnasium reports as warnings too
            marks=pytest.mark.filterwarnings("ignore::UserWarning:gymnasium.vector.async_vector_env"),
        ),
    ],
)
def test_a_method_that_breaks_a_rule_fails_once_with_one_line_naming_it(
    installed, tmp_path, capsys, settings, message
):
    from nirl_mj.experiments.definition import load_experiment
    from nirl_mj.experiments.protocol import run_test_seeds

    probe = load_experiment(spec(tmp_path, '["Walker"]'))
    test_arena = run_test_seeds(probe, 0, set())[0]
    settings, message = settings.replace("TEST", str(test_arena)), message.replace("TEST", str(test_arena))
    path = spec(tmp_path, '["Walker"]', f"[method.Walker]\nsteps = 200\nsettings = {settings}\n")
    assert main(compare(path, tmp_path / "out", "--runs", "1")) == 1
    failed = failed_lines(capsys)
    assert len(failed) == 1 and "(1 attempt(s))" in failed[0] and message in failed[0]


def test_without_gymnasium_a_method_that_never_drives_runs_and_one_that_drives_is_told_the_extra(
    installed, tmp_path, capsys, monkeypatch
):
    """Gymnasium is the optional extra nirl-mj[gym]: a method that never calls make_env needs none, and
    one that does fails once, with one line naming the extra (not a bare ModuleNotFoundError)."""
    import sys

    monkeypatch.setitem(sys.modules, "gymnasium", None)  # import gymnasium: ModuleNotFoundError
    for module in [m for m in sys.modules if m.startswith("nirl_mj.gym.")]:
        monkeypatch.delitem(sys.modules, module)
    path = spec(tmp_path, '["Still", "Walker"]')
    assert main(compare(path, tmp_path / "out", "--runs", "1")) == 1
    failed = failed_lines(capsys)
    assert len(failed) == 1 and "Walker" in failed[0] and "(1 attempt(s))" in failed[0]
    assert "method 'Walker' drives the robot: its environments are Gymnasium's; install the extra " \
           "nirl-mj[gym]" in failed[0]  # fmt: skip
    assert json.loads((tmp_path / "out" / "cells" / "Still-run000.json").read_text())["result"]["tests"] == 2


@pytest.mark.parametrize(
    ("method", "settings", "message"),
    [
        ("Still", "{ answer = 7, after = 3 }",
         "method 'Still': its policy answered an observation of shape (16,) with array(7)"),
        # its cell is seeded: another attempt would train and raise again, so none is made
        ("Breaks", "{ after = 3 }",
         "method 'Breaks': its policy raised ValueError: policy broke at test time"),
    ],
)  # fmt: skip
def test_a_policy_that_answers_out_of_range_or_raises_later_fails_once_naming_it(
    installed, tmp_path, capsys, method, settings, message
):
    path = spec(tmp_path, f'["{method}"]', f"[method.{method}]\nsettings = {settings}\n")
    assert main(compare(path, tmp_path / "out", "--runs", "1")) == 1
    failed = failed_lines(capsys)
    assert len(failed) == 1 and "(1 attempt(s))" in failed[0]
    assert message in failed[0]


def test_an_installed_method_trains_holding_its_workdirs_lock(installed, tmp_path):
    """A sweep trains a (method, run) once per grid cell in one workdir: one training at a time."""
    assert main(compare(spec(tmp_path, '["Locked"]'), tmp_path / "out", "--runs", "1")) == 0
    (locked,) = (tmp_path / "out" / "runs" / "Locked").glob("*/locked.json")
    assert json.loads(locked.read_text()) is True
    assert not list((tmp_path / "out" / "runs" / "Locked").glob(".*.lock"))  # released


def test_a_method_that_declares_nothing_is_refused_before_anything_runs(installed, tmp_path):
    with pytest.raises(ExperimentError, match="method 'Silent': declare `reads`"):
        from_dict({"kind": "compare", "methods": ["Silent"]}, "e.toml")
    with pytest.raises(ExperimentError, match="unknown method 'Nobody'; .* installed .*Walker"):
        from_dict({"kind": "compare", "methods": ["Nobody"]}, "e.toml")
    # its table copied from a machine where a package provides it
    with pytest.raises(ExperimentError, match="method.Nobody: unknown method 'Nobody': not built in, and no "
                                              "installed package provides it .*Walker"):  # fmt: skip
        from_dict(
            {"kind": "compare", "methods": ["Nobody"], "method": {"Nobody": {"settings": {"k": 1}}}}, "e.toml"
        )
    with pytest.raises(
        ExperimentError, match="method 'Walker': it acts on features: declare features in its reads"
    ):
        walker = {"Walker": {"settings": {"reads": ["demonstrations"]}}}
        from_dict({"kind": "compare", "methods": ["Walker"], "method": walker}, "e.toml")
    with pytest.raises(ExperimentError, match="settings {'speed': 3}: .*unexpected keyword"):
        walker = {"Walker": {"settings": {"speed": 3}}}
        from_dict({"kind": "compare", "methods": ["Walker"], "method": walker}, "e.toml")


def test_a_method_that_would_run_as_something_else_is_refused_before_anything_runs(installed, tmp_path):
    """A built-in method's name, a name two packages provide, settings for an instance, a train() that
    cannot take the five keywords, settings its own __init__ refuses: refused by name, before any cell."""

    def refused(methods: list, match: str, tables: dict | None = None) -> None:
        with pytest.raises(ExperimentError, match=match):
            from_dict({"kind": "compare", "methods": methods, "method": tables or {}}, "e.toml")

    other = installed / "other_method-2.0.dist-info"
    other.mkdir()
    (other / "METADATA").write_text("Metadata-Version: 2.1\nName: other-method\nVersion: 2.0\n")
    (other / "entry_points.txt").write_text("[nirl_mj.methods]\nBC = walker_method:Still\nStill = x:Y\n")
    refused(["BC"], "'BC' is a built-in method, and the installed package other-method provides a method "
            "of that name too; rename its entry point")  # fmt: skip
    refused(["Still"], "method 'Still': several packages provide it \\(other-method: x:Y; walker-method: "
            "walker_method:Still\\); uninstall or rename all but one")  # fmt: skip
    refused(["STILL"], "method 'STILL': its entry point 'walker_method:STILL' is an instance, which takes no "
            "settings", {"STILL": {"settings": {"answer": 1}}})  # fmt: skip
    refused(["BadSignature"], r"its train\(demos\) cannot be called as train\(demonstrations, make_env, "
            r"budget, seed, workdir\)")  # fmt: skip
    refused(["Picky"], r"method 'Picky': settings \{'k': 0\}: ValueError: k = 0: must be >= 1",
            {"Picky": {"settings": {"k": 0}}})  # fmt: skip
    refused(["Still-1"], 'plugin = \'Still\' names an installed method: add kind = "plugin" to the table',
            {"Still-1": {"plugin": "Still", "settings": {"answer": 1}}})  # fmt: skip
    factory = {"StillOf": {"settings": {"answer": 2}}}
    made = from_dict({"kind": "compare", "methods": ["StillOf"], "method": factory}, "e.toml")
    assert made.methods[0].declared_reads == ("demonstrations", "features")


def test_a_methods_own_error_fails_its_cell_once_with_its_traceback(installed, tmp_path, capsys):
    path = spec(tmp_path, '["Raiser", "rule"]')
    assert main(compare(path, tmp_path / "out", "--runs", "1")) == 1
    failed = failed_lines(capsys)
    assert len(failed) == 1 and "(1 attempt(s))" in failed[0]
    assert "method 'Raiser': train() raised TypeError: 'NoneType' object is not subscriptable " \
           "(demonstrations=None: they are not in its reads)" in failed[0]  # fmt: skip
    failures = json.loads((tmp_path / "out" / "results.json").read_text())["failures"]
    failure = next(f for f in failures if f["id"] == "Raiser-run000")
    assert 'return demonstrations["actions"]' in failure["traceback"]  # the method's own line


def test_a_methods_identity_holds_its_source_and_what_it_reads(installed, tmp_path):
    """Edited code under an unchanged version (an editable install) is another computation."""
    from nirl_mj.experiments import protocol
    from nirl_mj.experiments.definition import ExperimentError, load_experiment

    path = spec(tmp_path, '["Still", "rule"]')
    before = load_experiment(path).identity()
    out = protocol.open_output(tmp_path / "out", load_experiment(path))
    still = next(m for m in before["methods"] if m["name"] == "Still")
    assert still["reads"] == ["demonstrations", "features"] and len(still["source"]) == 16
    module = installed / "walker_method" / "__init__.py"
    module.write_text(module.read_text() + "\n# edited\n")
    after = load_experiment(path).identity()
    assert after != before and [m for m in after["methods"] if m["name"] == "rule"] == [
        m for m in before["methods"] if m["name"] == "rule"
    ]
    # the refusal names the method and why: its code changed
    with pytest.raises(
        ExperimentError, match=r"differs in: methods \(Still: source \(its package's code changed\)\)"
    ):
        protocol.open_output(out, load_experiment(path))


def test_an_installed_method_resumes_after_a_kill(installed, tmp_path):
    path = spec(tmp_path, '["Walker", "rule"]', "[method.Walker]\nsettings = { episodes = 4 }\n")
    reference = tmp_path / "reference"
    assert main(compare(path, reference)) == 0
    out = tmp_path / "killed"
    before = killed_after_cells(compare(path, out), out, 1)
    assert 1 <= len(before) < 4, "the comparison was not killed part-way"
    assert main(compare(path, out)) == 0
    after = cell_times(out)
    assert {name: after[name] for name in before} == before

    def results(d: Path) -> dict:
        return {p.stem: json.loads(p.read_text())["result"] for p in (d / "cells").glob("*.json")}

    assert results(out) == results(reference)


def test_the_example_package_is_a_method_outside_nirl_mj():
    source = (ROOT / "examples" / "knn_method" / "knn_method" / "__init__.py").read_text()
    assert "nirl_mj" not in source.replace("nirl-mj", "")  # written against NumPy alone
    sys.path.insert(0, str(ROOT / "examples" / "knn_method"))
    try:
        from knn_method import KNN
    finally:
        sys.path.pop(0)
    import numpy as np

    demos = {"observations": np.array([[0.0] * 16, [5.0] * 16, [5.1] * 16], np.float32),
             "actions": np.array([1, 4, 4])}  # fmt: skip
    policy = KNN(k=1).train(demos, None, 0, 0, "")
    assert policy(np.full(16, 4.9, np.float32)) == 4 and policy(np.zeros(16, np.float32)) == 1
    assert KNN(k=3).train(demos, None, 0, 0, "")(np.zeros(16, np.float32)) == 4  # majority of 3
    assert textwrap.dedent(KNN.__doc__ or "")
