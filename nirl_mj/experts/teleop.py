"""Human demonstrations: drive the robot from the keyboard in MuJoCo's viewer.

Key handling (:class:`KeyboardTeleop`) is kept apart from the viewer so that
it is tested headless; :func:`teleoperate` is the thin viewer loop. One key
press is one decision (0.5 s of simulated time), so the human can think between
decisions as the paper's demonstrators could. Letter keys are avoided: MuJoCo's
viewer uses nearly all of them.

====================  ==============================
key                   meaning
====================  ==============================
Up, keypad 8          forward
Left, keypad 4        turn left 30 degrees
keypad 7              turn left 60 degrees
Right, keypad 6       turn right 30 degrees
keypad 9              turn right 60 degrees
Down, keypad 2        backward
Enter                 end this episode now, keep it
Backspace             end this episode now, discard it
====================  ==============================
"""

from __future__ import annotations

import enum
import queue
from collections.abc import Callable
from typing import Any

import dm_env

from nirl_mj.data.trajectory import Trajectory
from nirl_mj.sim.display import display_available

# GLFW key codes (what mujoco.viewer's key_callback receives).
KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP = 262, 263, 264, 265
KEY_ENTER, KEY_BACKSPACE = 257, 259
KEY_KP = {n: 320 + n for n in range(10)}

KEYMAP: dict[int, int] = {
    KEY_UP: 0,
    KEY_KP[8]: 0,
    KEY_LEFT: 1,
    KEY_KP[4]: 1,
    KEY_KP[7]: 2,
    KEY_RIGHT: 3,
    KEY_KP[6]: 3,
    KEY_KP[9]: 4,
    KEY_DOWN: 5,
    KEY_KP[2]: 5,
}
"""GLFW key code -> action index 0..5."""


class Command(enum.Enum):
    """Episode commands a key can give besides an action."""

    KEEP = "keep"
    DISCARD = "discard"


_COMMANDS = {KEY_ENTER: Command.KEEP, KEY_BACKSPACE: Command.DISCARD}


class KeyboardTeleop:
    """Turns key presses (from any thread) into actions and commands, in order.

    It is also an :class:`~nirl_mj.experts.Expert` (kind ``"human"``) whose
    :meth:`act` waits for the next action key.
    """

    kind = "human"

    def __init__(self) -> None:
        self._queue: queue.Queue[int | Command] = queue.Queue()

    def on_key(self, keycode: int) -> None:
        """The viewer's key callback: queues the key's action or command; other keys are ignored."""
        if keycode in KEYMAP:
            self._queue.put(KEYMAP[keycode])
        elif keycode in _COMMANDS:
            self._queue.put(_COMMANDS[keycode])

    def next(self, timeout: float | None = None) -> int | Command | None:
        """The next action or command, or None if none came within ``timeout`` seconds."""
        try:
            return self._queue.get(timeout=timeout)
        except queue.Empty:
            return None

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        while self.next(timeout=0) is not None:  # keys pressed between episodes do not count
            pass

    def act(self, timestep: dm_env.TimeStep) -> int:
        while not isinstance(item := self.next(), int):
            pass
        return item


def require_display() -> None:
    """Refuses, in one line, where no window can open."""
    if not display_available():
        raise RuntimeError(
            "teleop needs a display (DISPLAY is not set): run it on a desktop or with `ssh -X`; "
            "for demonstrations on a headless machine use `nirl-mj demos`"
        )


class _ViewerAgent:
    """The human at the viewer as an :class:`~nirl_mj.sim.episode.Agent`: waits for the next
    key while keeping the window live; a command key or a closed window gives no action,
    which ends the episode (``command`` tells which)."""

    kind = KeyboardTeleop.kind

    def __init__(self, keys: KeyboardTeleop, viewer: Any) -> None:
        self.keys, self.viewer = keys, viewer
        self.command: Command | None = None

    def reset(self, env: dm_env.Environment, timestep: dm_env.TimeStep) -> None:
        self.keys.reset(env, timestep)
        self.command = None

    def act(self, timestep: dm_env.TimeStep) -> int | None:
        while self.viewer.is_running():
            item = self.keys.next(timeout=0.05)
            if isinstance(item, Command):
                self.command = item
                return None
            if item is not None:
                return item
            self.viewer.sync()
        return None


def teleoperate(
    env: dm_env.Environment,
    episodes: int,
    seed_of: Callable[[int], int],
    on_trajectory: Callable[[Trajectory], None],
) -> int:
    """Opens the viewer and records up to ``episodes`` human demonstrations.

    ``seed_of(i)`` gives the arena seed of episode i; every kept episode is
    passed to ``on_trajectory``. Returns the number kept. Closing the window
    ends the session.
    """
    require_display()
    import mujoco.viewer

    from nirl_mj.sim.episode import EpisodeAbandoned, run_episode

    physics = env.physics
    kept = 0
    keys = KeyboardTeleop()
    with mujoco.viewer.launch_passive(
        physics.model.ptr, physics.data.ptr, key_callback=keys.on_key
    ) as viewer:
        agent = _ViewerAgent(keys, viewer)
        for i in range(episodes):
            try:
                trajectory = run_episode(env, agent, seed_of(i), lambda *_: viewer.sync())
            except EpisodeAbandoned as ended:
                # Enter keeps the episode so far (as if its budget ran out), Backspace drops it.
                trajectory = ended.trajectory if agent.command is Command.KEEP else None
            if not viewer.is_running():
                break
            if trajectory is not None and len(trajectory):
                on_trajectory(trajectory)
                kept += 1
    return kept
