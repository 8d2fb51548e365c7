"""A digest of a tiny end-to-end run pins results across refactors.

Through the public command line only (``nirl_mj.cli.main``), so that moving code
cannot change what is measured: demonstrations, every trained array of the
default and paper variants and of each baseline's reward step, the selection,
and the held-out evaluation. The digest was first pinned at aa67077, before
the package was split into sub-packages, and re-pinned on 2026-11-24 when the
default inner learner changed (3-step Q-learning targets, 32 hidden units,
gamma 0.9; the paper variant's checkpoint was checked bit-identical across that
change); a change that alters any number changes it. Update ``PINNED`` only
for a change that is meant to alter results, and say so in the commit.

The bits also depend on the platform (CPU, BLAS kernels, library builds): on a new
machine the digest of 44e7b06 itself came out different (8ae27ff... instead of
ee3e5c9...), and was re-pinned on 2026-11-24 after checking that 44e7b06 and the
new code give the same digest there. If this test fails, first run it at the last
commit it passed at: if that fails too, the platform changed, not the results.
Re-pinned the same day when the default variant took bearing reward features and
network inputs (docs/notebook/algorithm.md, "Bearing features"): meant to change results; the paper
variant's checkpoint, policy, metrics, reward and evaluation stayed bit-identical.
Re-pinned on 2026-11-25 when AL and RE took the per-state reading by default (issue 16): meant
to change results; with ``al_expectations`` and ``re_expectations`` set to "trajectory" the new
code gives the previous digest (9725b24...) bit for bit.
Re-pinned the same day when NIRL's default margin took the learner's policies as its alternatives
(``matching = "policy"``, issue 14): meant to change results; with ``matching = "occupancy"`` as the
default the new code gives the previous digest (88f9b24...) bit for bit.
Re-pinned on 2026-11-26 for the information budget (issue 31): the learned value of an episode's
end and selection by balanced accuracy on the demonstrations, behaviour cloning at its strongest,
the progress kept only for its control, and a ``reads`` list in the main job's results: meant to
change results; with ``terminal_value = "outcome"`` and ``selection = "validation"`` as the
defaults, the paper settings for behaviour cloning, the progress always kept and no ``reads`` in
the results, the new code gives the previous digest (c7a37a4...) bit for bit.
Re-pinned the same day for the suites (issue 32): every evaluation's metrics hold SCT beside SPL,
and every learner config the ``pretreatment`` setting (off): no number changed; with the ``sct``
key left out of the metrics and ``pretreatment`` out of the configs, the new code gives the
previous digest (d579c0d...) bit for bit.
Re-pinned on 2026-11-27 when the decaying max-margin step left the default (issue 31,
``mmp_step_decay`` 0.1 -> 0, the paper's constant step): meant to change results; with 0.1 as the
default the new code gives the previous digest (7288e92...) bit for bit.
Re-pinned on 2026-11-28 for one tie rule (every method keeps the latest of its best-scored
iterates, commit 6c30c7d), and pinned per platform from then on: meant to change results. On an
AMD EPYC machine (torch CPU capability AVX2) da6de53 gives 8902bff... where the Intel machine of
its CI gave 0aff7bc..., so the bits depend on the platform; there the new code gives ae13bc6...
without the selection record's new ``ties`` key and 3fffecc... with it. The digest on the Intel
machine was not measured at this commit: on a platform with no pinned digest the test is skipped
and prints the digest to pin, after checking that the last commit it passed at gives that
platform's previous digest (or, with none, that the change is the one meant).
Pinned on 2026-11-29 for a second platform, an AMD EPYC machine whose torch CPU capability is AVX512:
a7826ef, whose CI on the AVX2 machine passed its digest, gives dc23578... there; no result changed.
A third digest on 2026-11-30, an AMD EPYC of another generation (cpu family 26, model 2: Zen 5)
whose key is the same, AuthenticAMD/AVX512: 00e8dae, which passed dc23578... on the earlier
AVX512 machine, gives 641f16e... there; no result changed. So a key holds every digest seen under
it, each with the machine it came from (the key stays what cells record).
Re-pinned on 2026-11-30 when the paper reading of the margin (``matching = "paper"``) stopped
building its (N, 6, D) array of identical rows (the paper variant's theta moved by about 1e-8; no
other method's arrays changed; Table I's 25 NIRL-paper cells came out the same, field for field),
for all three machines at once from the Zen 5 machine: ``tests/digest_platforms.py`` has each
library pick the kernels of the machine it stands in for, and at 3513ea6 it gave the three
digests pinned before, each for its own machine. The two AVX512 machines differ in OpenBLAS's
kernels only: SkylakeX, its own choice on these AMD machines, and Haswell, which the Zen 5
machine's environment sets (``OPENBLAS_CORETYPE=Haswell``).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from nirl_mj.cli import main
from nirl_mj.experiments.machine import platform_key

TINY_TASK = [
    "--set", "arena.size=[24.0, 24.0]", "--set", "arena.start=[4.0, 4.0]",
    "--set", "arena.target=[20.0, 20.0]", "--set", "arena.static_obstacles=3",
    "--set", "arena.clear_radius=3.0", "--set", "robot.drive=\"planar\"",
]  # fmt: skip
TINY_LEARNER = ["episodes=3", "trajectories_per_episode=2", "validation_arenas=2", "validate_every=1",
                "replay_episodes=2"]  # fmt: skip
METHODS = {"default": [], "paper": ["--variant", "paper"], "al": ["--config", "method=\"al\""],
           "re": ["--config", "method=\"re\""], "scirl": ["--config", "method=\"scirl\""]}  # fmt: skip
PINNED = {
    "AuthenticAMD/AVX2": ("fed5b51b5eee4296b82cb1cc5860e79c8742e41873e9cd21a99245da46be918d",),
    "AuthenticAMD/AVX512": (
        "70f9ba98289bb8bbdbfca2df094cafb9784eba57c3c7635883f5c730adcc9475",  # OpenBLAS SkylakeX kernels
        "446163fac0a2b746ba2fb18e7e82b9763b4c451f5baf1220caacfcbc9ebbecea",  # OpenBLAS Haswell kernels
    ),
}
"""The digests seen by platform (:func:`nirl_mj.experiments.machine.platform_key`): one per machine
of the key whose bits differ."""


def _arrays_digest(h, path: Path) -> None:
    with np.load(path, allow_pickle=False) as data:
        for key in sorted(data.files):
            h.update(key.encode())
            h.update(np.ascontiguousarray(data[key]).tobytes())


def tiny_run_digest(tmp: Path) -> str:
    """sha256 over the datasets, trained arrays, selections, rewards and evaluations of a tiny run."""
    h = hashlib.sha256()
    demos = tmp / "demos.npz"
    assert main(["demos", "--episodes", "3", "--seed", "1", "--workers", "1", "--quiet", "--out",
                 str(demos), *TINY_TASK]) == 0  # fmt: skip
    _arrays_digest(h, demos)
    for name, extra in METHODS.items():
        run = tmp / name
        config = [arg for kv in TINY_LEARNER for arg in ("--config", kv)]
        assert main(["train", "--demos", str(demos), "--out", str(run), "--quiet", "--seed", "2",
                     *TINY_TASK, *config, *extra]) == 0  # fmt: skip
        for file in ("checkpoint.npz", "policy.npz"):
            _arrays_digest(h, run / file)
        record = json.loads((run / "run.json").read_text())
        for key in ("selection", "selected_iteration", "train_seeds", "validation_seeds", "demo_seeds"):
            h.update(json.dumps(record[key], sort_keys=True).encode())
        h.update(json.dumps(json.loads((run / "reward.json").read_text()), sort_keys=True).encode())
        h.update((run / "metrics.jsonl").read_bytes())
        assert main(["eval", "--run", str(run), "--tests", "3", "--quiet"]) == 0
        h.update(json.dumps(json.loads((run / "eval.json").read_text()), sort_keys=True).encode())
    out = tmp / "main"
    assert main(["run", "--demos", "2", "--episodes", "1", "--tests", "2", "--workers", "1", "--quiet",
                 "--out", str(out), *TINY_TASK]) == 0  # fmt: skip
    results = json.loads((out / "results.json").read_text())
    h.update(json.dumps(results, sort_keys=True).encode())
    _arrays_digest(h, out / "demos.npz")
    _arrays_digest(h, out / "runs" / "NIRL" / "0" / "policy.npz")
    return h.hexdigest()


def test_tiny_run_digest_is_unchanged(tmp_path):
    digest, key = tiny_run_digest(tmp_path), platform_key()
    if key not in PINNED:
        pytest.skip(
            f"no digest pinned for platform {key}: this commit gives {digest} (see the module docstring)"
        )
    assert digest in PINNED[key], f"{key} ({_cpu()}): {digest} is none of the digests pinned for the key"


def _cpu() -> str:
    """The CPU's family and model, which the platform key leaves out, for the message."""
    lines = Path("/proc/cpuinfo").read_text().splitlines() if Path("/proc/cpuinfo").is_file() else []
    fields = {k.strip(): v.strip() for k, v in (line.split(":", 1) for line in lines if ":" in line)}
    return ", ".join(f"{k} {fields[k]}" for k in ("cpu family", "model") if k in fields)


def test_a_run_directory_written_before_the_restructure_still_evaluates_the_same(tmp_path):
    """tests/data/legacy_run_aa67077: the default tiny run above, as aa67077 wrote it."""
    legacy = Path(__file__).parent / "data" / "legacy_run_aa67077"
    run = tmp_path / "run"
    run.mkdir()
    for file in legacy.iterdir():
        (run / file.name).write_bytes(file.read_bytes())
    before = json.loads((run / "eval.json").read_text())
    (run / "eval.json").unlink()
    assert main(["eval", "--run", str(run), "--tests", "3", "--quiet"]) == 0
    now = json.loads((run / "eval.json").read_text())
    sct = [entry.pop("sct") for entry in now.values()]  # a metric added since (2026-11-26)
    assert now == before and all(0.0 <= v <= 1.0 for v in sct)


def test_a_main_job_directory_of_the_old_layout_is_refused_with_a_clear_error(tmp_path, capsys):
    out = tmp_path / "main"
    (out / "nirl").mkdir(parents=True)
    for file in ("run.json", "policy.npz", "reward.json"):
        (out / "nirl" / file).write_bytes(
            (Path(__file__).parent / "data" / "legacy_run_aa67077" / file).read_bytes()
        )
    assert main(["run", "--out", str(out), "--resume", "--quiet"]) == 2
    assert "a main job of an older nirl-mj" in capsys.readouterr().err
    assert (
        main(["eval", "--run", str(out / "nirl"), "--tests", "1", "--quiet"]) == 0
    )  # its run still evaluates
