"""Test-wide set-up: headless rendering before any MuJoCo or dm_control import.

dm_control picks its OpenGL backend when first imported; a test module that
imports it before ``nirl_mj`` would otherwise get GLFW, which aborts without a
display.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

# The test files that take longest, first: pytest-xdist hands out whole files in collection order
# (`--dist loadfile`), and the Warp file, last by name, kept one core busy for minutes after the
# other had finished.
_SLOWEST_FIRST = ("test_warp_worlds.py",)


def pytest_collection_modifyitems(items: list) -> None:
    items.sort(key=lambda item: item.path.name not in _SLOWEST_FIRST)  # stable: the rest keep their order
