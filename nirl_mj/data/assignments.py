"""``KEY=VALUE`` assignments as typed on a command line (``--set``, ``--config``), VALUE in TOML syntax."""

from __future__ import annotations

import tomllib
from typing import Any


def parse_assignment(text: str) -> tuple[str, Any] | None:
    """``(KEY, value)`` of ``KEY=VALUE``: VALUE read as TOML (``3``, ``[5, 5]``, ``"planar"``), a bare
    word as a string (``planar``); None if ``text`` has no ``=`` (the caller names what it expects)."""
    key, sep, value = text.partition("=")
    if not sep:
        return None
    try:
        return key.strip(), tomllib.loads(f"v = {value.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        return key.strip(), value.strip()
