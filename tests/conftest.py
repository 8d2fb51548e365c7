"""Test-wide set-up: headless rendering before any MuJoCo or dm_control import.

dm_control picks its OpenGL backend when first imported; a test module that
imports it before ``nirl_mj`` would otherwise get GLFW, which aborts without a
display.
"""

import os
from collections import Counter

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

# Longest processing time first: pytest-xdist hands out whole files in the order it is given
# (`--dist loadfile`, with `--no-loadscope-reorder` in pyproject.toml: its own order puts the files
# with most tests first, whatever they take), and a long file handed out last keeps one core busy
# while the others idle. The seconds are each file's total in CI at faf4f6c (its junit XML, on two
# cores); test_adversarial.py less the learning run of AIRL-absorbing dropped since. A rough order is
# enough. Then the files with most tests; the rest last.
_SLOW_SECONDS = {
    "test_experiments.py": 424,
    "test_warp_worlds.py": 421,
    "test_suite.py": 320,
    "test_adversarial.py": 277,
    "test_rl.py": 102,
    "test_reliability.py": 75,
    "test_plugins.py": 69,
    "test_pipeline.py": 52,
    "test_information_budget.py": 39,
}


def pytest_collection_modifyitems(items: list) -> None:
    count = Counter(item.path for item in items)
    # stable: a file's tests keep their order
    items.sort(key=lambda item: (-_SLOW_SECONDS.get(item.path.name, 0), -count[item.path], str(item.path)))
