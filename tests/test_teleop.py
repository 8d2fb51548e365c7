"""Keyboard teleoperation, headless: the key handling apart from the viewer."""

import sys
import threading

import pytest

from nirl_mj.cli import main
from nirl_mj.experts import teleop
from nirl_mj.experts.teleop import KEYMAP, Command, KeyboardTeleop


def test_keymap_covers_every_action():
    assert set(KEYMAP.values()) == set(range(6))
    assert KEYMAP[teleop.KEY_UP] == 0 and KEYMAP[teleop.KEY_DOWN] == 5
    assert KEYMAP[teleop.KEY_KP[7]] == 2 and KEYMAP[teleop.KEY_KP[9]] == 4


def test_keys_become_actions_and_commands_in_order():
    keys = KeyboardTeleop()
    for code in (teleop.KEY_UP, ord("W"), teleop.KEY_KP[9], teleop.KEY_ENTER, teleop.KEY_BACKSPACE):
        keys.on_key(code)
    assert [keys.next(0) for _ in range(5)] == [0, 4, Command.KEEP, Command.DISCARD, None]


def test_act_waits_for_an_action_key_from_another_thread():
    keys = KeyboardTeleop()
    threading.Timer(0.05, keys.on_key, (teleop.KEY_ENTER,)).start()
    threading.Timer(0.1, keys.on_key, (teleop.KEY_LEFT,)).start()
    assert keys.act(None) == 1  # commands are skipped while an action is awaited


def test_reset_drops_keys_pressed_between_episodes():
    keys = KeyboardTeleop()
    keys.on_key(teleop.KEY_UP)
    keys.reset(None, None)
    assert keys.next(0) is None


def test_teleop_without_display_is_a_clear_error(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    assert main(["teleop", "--out", str(tmp_path / "human.npz")]) == 2
    assert "teleop needs a display" in capsys.readouterr().err
    assert not (tmp_path / "human.npz").exists()


@pytest.mark.parametrize("display", [":0", ""])
def test_display_detection(monkeypatch, display):
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setenv("DISPLAY", display)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert teleop.display_available() == bool(display)
    monkeypatch.setattr(sys, "platform", "darwin")  # a window opens without DISPLAY (GLFW on macOS)
    assert teleop.display_available()


class _FakeViewer:
    """mujoco.viewer's passive handle, headless: presses ``script[k]`` keys at the k-th sync."""

    def __init__(self, script: dict[int, list[int]], key_callback, close_at: int | None) -> None:
        self.script, self.key_callback, self.close_at, self.syncs = script, key_callback, close_at, 0

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        pass

    def sync(self) -> None:
        self.syncs += 1
        for code in self.script.get(self.syncs, []):
            self.key_callback(code)

    def is_running(self) -> bool:
        # Closes itself after 100 syncs (5 s of waiting for keys): a script that ran out never hangs.
        return self.syncs < (self.close_at or 100)


def _teleoperate(monkeypatch, script, close_at=None, episodes=2):
    import mujoco.viewer

    from nirl_mj.sim import spec
    from nirl_mj.sim.task import make_env

    monkeypatch.setattr(teleop, "display_available", lambda: True)

    def launch_passive(model, data, key_callback) -> _FakeViewer:
        return _FakeViewer(script, key_callback, close_at)

    monkeypatch.setattr(mujoco.viewer, "launch_passive", launch_passive)
    task = spec.replace(spec.load_task("navigate"), control={"step_budget": 4}, robot={"drive": "planar"})
    kept = []
    assert teleop.teleoperate(make_env(task), episodes, lambda i: 10 + i, kept.append) == len(kept)
    return kept


def test_enter_keeps_the_episode_so_far_and_backspace_drops_it(monkeypatch):
    up, left = teleop.KEY_UP, teleop.KEY_LEFT
    kept = _teleoperate(monkeypatch, {1: [up, left], 3: [teleop.KEY_ENTER], 4: [up, teleop.KEY_BACKSPACE]})
    assert len(kept) == 1  # the second episode was discarded
    (t,) = kept
    assert t.actions.tolist() == [0, 1] and t.outcome == "timeout" and t.demonstrator == "human"
    assert t.arena_seed == 10
    # Keys pressed between episodes do not count: Backspace comes at the second one's first sync.
    finished = _teleoperate(monkeypatch, {1: [up] * 4, 6: [teleop.KEY_BACKSPACE]})
    assert [len(t) for t in finished] == [4]  # the budget ended the first episode


def test_closing_the_window_ends_the_session(monkeypatch):
    assert _teleoperate(monkeypatch, {1: [teleop.KEY_UP]}, close_at=3) == []
