"""nirl-mj: Neural Inverse Reinforcement Learning for a Robotino in MuJoCo.

The data path, one package each: ``sim`` (task files, procedural arenas, the MJCF
Robotino and its omni-drive, the dm_control composer task, range rays) -> ``data``
(phi(s) and f(s, a), trajectories and their dataset format) -> ``experts``
(demonstrators) -> ``learn`` (NIRL, the IRL baselines, behaviour cloning) ->
``experiments`` (training, evaluation, compare/sweep/suite, the main job) ->
``inspect`` (Rerun recordings, videos, figures) -> ``cli`` (the ``nirl-mj``
command); ``gym`` is the Gymnasium face of the same task.
"""

import os

# Headless by default: without a display, GLFW (MuJoCo's default) fails; EGL
# renders offscreen through Mesa on CPU-only machines. Must precede mujoco.
os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])


def _check_osmesa() -> None:
    """dm_control loads the renderer MUJOCO_GL names when it is imported, by every command: without
    the OSMesa library that import fails deep in PyOpenGL ('NoneType' has no 'glGetError'). Say what
    is missing instead."""
    import ctypes.util

    if os.environ["MUJOCO_GL"] == "osmesa" and ctypes.util.find_library("OSMesa") is None:
        raise ImportError(
            "MUJOCO_GL=osmesa, but no OSMesa library is installed: install it (Debian: sudo apt-get "
            "install libosmesa6), or unset MUJOCO_GL to render offscreen through EGL (the default)"
        )


_check_osmesa()
from nirl_mj.sim.display import display_available  # noqa: E402 - after MUJOCO_GL is set; stdlib only

if os.environ["MUJOCO_GL"] == "glfw" and not display_available():
    # dm_control starts GLFW when imported, by every command: without a display it warns twice, and
    # nothing renders anyway (a renderer is refused with one line: inspect.video.check_gl_platform)
    import warnings

    warnings.filterwarnings("ignore", module="glfw")
# One BLAS thread per process: the learner's matrices are small, parallelism comes
# from processes (demos, experiments), and a multi-threaded BLAS sharing cores with
# them spins: measured 40x slower max-margin steps (12.6 s against 0.3 s per 20
# iterations) on a busy 2-core machine. Only effective if numpy is not imported yet;
# set OPENBLAS_NUM_THREADS=1 yourself when importing numpy before nirl_mj.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

__version__ = "0.1.0"


def make_env(task="navigate", seed=None):
    """See :func:`nirl_mj.sim.task.make_env` (imported lazily so that light modules stay light)."""
    from nirl_mj.sim.task import make_env as _make_env

    return _make_env(task, seed)


__all__ = ["make_env", "__version__"]

# The task file's rules, registered with the dataset reader (nirl_mj.data.dataset.TASK_RULES; the data
# layer cannot import the simulation's), so that every reader of a dataset checks its task records,
# the Gymnasium extra installed or not. Costs the task specs' import (~0.1 s), no simulator.
from nirl_mj.sim import spec as _spec  # noqa: E402, F401

# Gymnasium ids (nirl_mj/Navigate-v0, ...) whenever the optional extra is installed: Gymnasium 1.x
# finds an id only once registered. Costs Gymnasium's import (~70 ms), no simulator.
try:
    from nirl_mj.gym.registration import register_envs as _register_envs
except ModuleNotFoundError as _exc:
    if (_exc.name or "").partition(".")[0] != "gymnasium":
        raise
else:
    _register_envs()
