"""nirl-mj: Neural Inverse Reinforcement Learning for a Robotino in MuJoCo.

The data path, one module each: ``spec`` (task files) -> ``layout``/``arena``
(procedural arenas) -> ``robot``/``drive`` (MJCF Robotino, omni-drive
kinematics) -> ``task`` (the dm_control composer task, ``make_env``) ->
``sensing`` (rays) -> ``features`` (phi(s), f(s, a)) -> ``experts``,
``demos``, ``trajectory`` (demonstrations and their file format) -> ``learn``
(NIRL, behaviour cloning) -> ``evaluate`` -> ``record``/``report``/``pipeline``
(Rerun, figures, the main job) -> ``cli`` (the ``nirl-mj`` command).
"""

import os

# Headless by default: without a display, GLFW (MuJoCo's default) fails; EGL
# renders offscreen through Mesa on CPU-only machines. Must precede mujoco.
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])

__version__ = "0.1.0"


def make_env(task="navigate", seed=None):
    """See :func:`nirl_mj.task.make_env` (imported lazily so that light modules stay light)."""
    from nirl_mj.task import make_env as _make_env

    return _make_env(task, seed)


__all__ = ["make_env", "__version__"]
