"""Keyboard teleoperation, headless: the key handling apart from the viewer."""

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
    monkeypatch.setattr(teleop.sys, "platform", "linux")
    assert main(["teleop", "--out", str(tmp_path / "human.npz")]) == 2
    assert "teleop needs a display" in capsys.readouterr().err
    assert not (tmp_path / "human.npz").exists()


@pytest.mark.parametrize("display", [":0", ""])
def test_display_detection(monkeypatch, display):
    monkeypatch.setattr(teleop.sys, "platform", "linux")
    monkeypatch.setenv("DISPLAY", display)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert teleop.display_available() == bool(display)
