"""Test-wide set-up: headless rendering before any MuJoCo or dm_control import.

dm_control picks its OpenGL backend when first imported; a test module that
imports it before ``nirl_mj`` would otherwise get GLFW, which aborts without a
display.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])
