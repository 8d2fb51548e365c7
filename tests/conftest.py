"""Test-wide set-up: headless rendering before any MuJoCo or dm_control import.

dm_control picks its OpenGL backend when first imported; a test module that
imports it before ``nirl_mj`` would otherwise get GLFW, which aborts without a
display.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

# Longest processing time first: pytest-xdist hands out whole files in the order it is given
# (`--dist loadfile`, with `--no-loadscope-reorder` in pyproject.toml: its own order puts the files
# with most tests first, whatever they take), and a long file handed out last keeps one core busy
# while the others idle. The seconds are those of each file's slowest tests in CI at 97a654f (its
# "slowest 25 durations"): a rough order is enough. Then the files with most tests; the rest last.
_SLOW_SECONDS = {
    "test_warp_worlds.py": 343,
    "test_experiments.py": 310,
    "test_suite.py": 232,
    "test_adversarial.py": 190,
    "test_information_budget.py": 61,
    "test_pipeline.py": 32,
    "test_reliability.py": 31,
    "test_plugins.py": 29,
}


def pytest_collection_modifyitems(items: list) -> None:
    count: dict = {}
    for item in items:
        count[item.path] = count.get(item.path, 0) + 1
    # stable: a file's tests keep their order
    items.sort(key=lambda item: (-_SLOW_SECONDS.get(item.path.name, 0), -count[item.path], str(item.path)))
