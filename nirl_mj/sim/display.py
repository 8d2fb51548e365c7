"""Whether a window can open: what teleop's viewer and MUJOCO_GL=glfw render through (standard
library only: ``nirl_mj/__init__.py`` reads it before anything imports MuJoCo)."""

from __future__ import annotations

import os
import sys


def display_available() -> bool:
    """A display on Linux (``DISPLAY`` or ``WAYLAND_DISPLAY`` set); always elsewhere (macOS, Windows)."""
    return not sys.platform.startswith("linux") or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )
