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
import os
import queue
import sys
from collections.abc import Callable

import dm_env

from nirl_mj.data.trajectory import Trajectory

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


def display_available() -> bool:
    """Whether an interactive window can open (a display on Linux; always elsewhere)."""
    return not sys.platform.startswith("linux") or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )


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
    if not display_available():
        raise RuntimeError(
            "teleop needs a display (DISPLAY is not set): run it on a desktop or with `ssh -X`; "
            "for demonstrations on a headless machine use `nirl-mj demos`"
        )
    import mujoco.viewer

    from nirl_mj.data.trajectory import TrajectoryRecorder
    from nirl_mj.sim.task import Outcome

    keys = KeyboardTeleop()
    task = env.task
    recorder = TrajectoryRecorder(task.spec.control.decision_period)
    physics = env.physics
    kept = 0
    with mujoco.viewer.launch_passive(
        physics.model.ptr, physics.data.ptr, key_callback=keys.on_key
    ) as viewer:
        for i in range(episodes):
            seed = seed_of(i)
            env.random_state.seed(seed)
            timestep = env.reset()
            keys.reset(env, timestep)
            recorder.start(timestep.observation)
            viewer.sync()
            command = None
            while viewer.is_running() and not timestep.last():
                item = keys.next(timeout=0.05)
                if isinstance(item, Command):
                    command = item
                    break
                if item is not None:
                    timestep = env.step(item)
                    recorder.step(item, timestep.observation)
                viewer.sync()
            if not viewer.is_running():
                break
            if command is Command.DISCARD or len(recorder) == 0:
                continue
            outcome = Outcome(int(timestep.observation["outcome"]))
            if outcome == Outcome.RUNNING:  # ended by Enter: as if the budget ran out
                outcome = Outcome.TIMEOUT
            on_trajectory(recorder.finish(outcome, seed, task.spec, task.spec.control.speed, keys.kind))
            kept += 1
    return kept
