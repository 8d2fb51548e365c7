"""Test-wide set-up: headless rendering before any MuJoCo or dm_control import.

dm_control picks its OpenGL backend when first imported; a test module that
imports it before ``nirl_mj`` would otherwise get GLFW, which aborts without a
display.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

import gc  # noqa: E402

import pytest  # noqa: E402


@pytest.fixture(autouse=True)
def _free_render_contexts_on_the_main_thread():
    """Collect each test's garbage on the main thread, where its EGL contexts are current.

    A test that renders can leave a dm_control ``MjrContext`` in a reference cycle. Collected later
    on another thread (an executor's manager thread, in a later test), it cannot be made current
    there, and pytest reports the ignored exception as a warning of that unrelated test."""
    yield
    gc.collect()
