"""Omnidirectional drive of the Robotino: actions -> body twist -> wheel speeds.

Pure numpy (no MuJoCo), so planners and tests can use it without a simulator.

Conventions (match ``models/robotino/robotino.xml``):

- Body twist ``[vx, vy, wz]``: linear velocity in the robot frame (m/s; +x is
  the front, +y the left) and yaw rate (rad/s, positive = counter-clockwise =
  turning left).
- Wheel i sits at angle ``WHEEL_ANGLES[i]`` counter-clockwise from the front,
  ``WHEEL_DISTANCE`` from the centre. With a_i the outward radial unit vector
  its drive direction is d_i = z x a_i, and a positive wheel speed (rad/s) moves
  the wheel centre by ``WHEEL_RADIUS * omega_i`` along d_i (the hinge axis in
  the XML is -a_i). Hence ``omega_i = (d_i . v + L wz) / R``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "ACTIONS",
    "WHEEL_ANGLES",
    "WHEEL_DISTANCE",
    "WHEEL_RADIUS",
    "Action",
    "BODY_RADIUS",
    "BatchDriveController",
    "DriveController",
    "action_profile",
    "action_share",
    "body_twist",
    "max_yaw_rate",
    "rate_limit",
    "wheel_speeds",
]

BODY_RADIUS: float = 0.225
"""Radius of the Robotino's outline (m): Robotino 3 is 450 mm across. Ranges are
measured from it and planners inflate obstacles by it."""

WHEEL_RADIUS: float = 0.040
"""Omniwheel radius R (m), OpenRobotino API2 ``OmniDriveModel``."""

WHEEL_DISTANCE: float = 0.132
"""Distance L from the robot centre to each wheel centre (m)."""

WHEEL_ANGLES: np.ndarray = np.radians([60.0, 180.0, 300.0])
"""Wheel positions, counter-clockwise from the robot's front (rad), shape (3,)."""

# d_i = z x a_i with a_i = (cos t_i, sin t_i, 0).
_DRIVE_DIRECTIONS = np.stack([-np.sin(WHEEL_ANGLES), np.cos(WHEEL_ANGLES)], axis=1)
# omega = _IK @ [vx, vy, wz]; the 3x3 matrix is invertible for 3 wheels 120 deg apart.
_IK = np.column_stack([_DRIVE_DIRECTIONS, np.full(3, WHEEL_DISTANCE)]) / WHEEL_RADIUS
_FK = np.linalg.inv(_IK)
for _m in (_DRIVE_DIRECTIONS, _IK, _FK):
    _m.setflags(write=False)
WHEEL_ANGLES.setflags(write=False)


@dataclass(frozen=True)
class Action:
    """One discrete action: drive at ``direction * speed`` while turning by ``turn``.

    ``turn`` is in radians, positive = left (counter-clockwise).
    """

    index: int
    name: str
    turn: float
    direction: float


ACTIONS: tuple[Action, ...] = (
    Action(0, "forward", 0.0, 1.0),
    Action(1, "left30", math.radians(30.0), 1.0),
    Action(2, "left60", math.radians(60.0), 1.0),
    Action(3, "right30", -math.radians(30.0), 1.0),
    Action(4, "right60", -math.radians(60.0), 1.0),
    Action(5, "backward", 0.0, -1.0),
)
"""The six discrete actions, indexed 0..5."""


def _last_axis3(x: np.ndarray | list | tuple, what: str) -> np.ndarray:
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise ValueError(f"{what} must have shape (..., 3), got {arr.shape}")
    return arr


def wheel_speeds(twist: np.ndarray | list | tuple) -> np.ndarray:
    """Inverse kinematics: body twist -> wheel angular velocities.

    Args:
        twist: shape (..., 3), ``[vx, vy, wz]`` in the body frame (m/s, m/s, rad/s).

    Returns:
        Shape (..., 3), wheel speeds (rad/s) in the sign convention of the
        hinges in robotino.xml.
    """
    return _last_axis3(twist, "twist") @ _IK.T


def body_twist(wheel_speeds: np.ndarray | list | tuple) -> np.ndarray:
    """Forward kinematics, the exact inverse of :func:`wheel_speeds`.

    Args:
        wheel_speeds: shape (..., 3), wheel angular velocities (rad/s).

    Returns:
        Shape (..., 3), ``[vx, vy, wz]`` in the body frame (m/s, m/s, rad/s).
    """
    return _last_axis3(wheel_speeds, "wheel_speeds") @ _FK.T


def _check_action(action: int) -> Action:
    if isinstance(action, bool) or not isinstance(action, (int, np.integer)):
        raise ValueError(
            f"action must be an integer in 0..{len(ACTIONS) - 1} "
            f"({', '.join(f'{a.index}={a.name}' for a in ACTIONS)}), got {action!r}"
        )
    if not 0 <= int(action) < len(ACTIONS):
        raise ValueError(
            f"action must be one of 0..{len(ACTIONS) - 1} "
            f"({', '.join(f'{a.index}={a.name}' for a in ACTIONS)}), got {action}"
        )
    return ACTIONS[int(action)]


def _n_commands(period: float, cmd_dt: float) -> int:
    if not (cmd_dt > 0 and period > 0 and math.isfinite(period) and math.isfinite(cmd_dt)):
        raise ValueError(f"period and cmd_dt must be positive, got {period=} {cmd_dt=}")
    n = round(period / cmd_dt)
    if n < 1:
        raise ValueError(f"period {period} s is shorter than one command period {cmd_dt} s")
    return n


def _trapezoid_angle(t: np.ndarray, angle: float, total: float, accel: float) -> np.ndarray:
    """Cumulative angle (rad) at times t of a trapezoidal rate profile.

    The rate ramps up at ``accel`` (rad/s^2), holds, and ramps down so that it
    is zero again at ``total`` (s) and the integral is exactly ``|angle|``.
    """
    a = abs(angle)
    # a = accel * tr * (total - tr)  ->  the smaller root is the ramp time.
    tr = 0.5 * (total - math.sqrt(max(total * total - 4.0 * a / accel, 0.0)))
    peak = accel * tr
    up = 0.5 * accel * t**2
    hold = 0.5 * accel * tr**2 + peak * (t - tr)
    down = a - 0.5 * accel * (total - t) ** 2
    theta = np.where(t <= tr, up, np.where(t <= total - tr, hold, down))
    return math.copysign(1.0, angle) * theta


def action_profile(
    action: int,
    speed: float,
    period: float = 0.5,
    cmd_dt: float = 0.01,
    max_accel: float = 4.0,
) -> np.ndarray:
    """Body twist to command in each command period of one decision.

    Forward/backward: ``vx = +-speed``. Turns: ``vx = +speed`` plus a
    trapezoidal yaw-rate profile (ramp up, hold, ramp down, all inside the
    period) whose integral is exactly the turn angle. The yaw acceleration is
    the largest that keeps every wheel's rim acceleration from the yaw part,
    ``L * dwz/dt``, within ``max_accel``; that gives the lowest peak yaw rate.
    Each row is the average of the continuous profile over its command period,
    so a zero-order hold of the rows integrates to exactly the turn angle.

    Args:
        action: index 0..5 into :data:`ACTIONS`.
        speed: forward speed (m/s).
        period: decision period (s); ``n_cmd = round(period / cmd_dt)``.
        cmd_dt: command period (s).
        max_accel: rim acceleration limit (m/s^2).

    Returns:
        Shape (n_cmd, 3): ``[vx, vy, wz]`` (m/s, m/s, rad/s) per command period.

    Raises:
        ValueError: unknown action, bad periods, or the turn does not fit.
    """
    act = _check_action(action)
    n = _n_commands(period, cmd_dt)
    if not max_accel > 0:
        raise ValueError(f"max_accel must be positive (m/s^2), got {max_accel}")
    total = n * cmd_dt
    out = np.zeros((n, 3))
    out[:, 0] = act.direction * float(speed)
    if act.turn != 0.0:
        yaw_accel = max_accel / WHEEL_DISTANCE
        # A triangular profile (no hold) is the fastest possible turn.
        min_period = 2.0 * math.sqrt(abs(act.turn) / yaw_accel)
        if min_period > total + 1e-12:
            need_accel = 4.0 * abs(act.turn) / total**2 * WHEEL_DISTANCE
            raise ValueError(
                f"cannot turn {math.degrees(act.turn):.1f} deg in {total:.3f} s with "
                f"max_accel={max_accel} m/s^2 (yaw acceleration <= {yaw_accel:.2f} rad/s^2 "
                f"at L={WHEEL_DISTANCE} m): needs period >= {min_period:.3f} s "
                f"or max_accel >= {need_accel:.3f} m/s^2"
            )
        edges = np.arange(n + 1) * cmd_dt
        edges[-1] = total
        theta = _trapezoid_angle(edges, act.turn, total, yaw_accel)
        theta[0], theta[-1] = 0.0, act.turn  # exact ends, no rounding residue
        out[:, 2] = np.diff(theta) / cmd_dt
    return out


def max_yaw_rate(period: float) -> float:
    """The largest yaw rate (rad/s) of a continuous action: held for a whole decision of
    ``period`` seconds it turns 60 degrees, as the sharpest discrete action does."""
    return math.radians(60.0) / period


def action_share(action: int) -> np.ndarray:
    """The continuous action that stands for discrete ``action``: float32 (2,), the shares in
    [-1, 1] of the speed (its direction, +-1) and of :func:`max_yaw_rate` (its turn over 60
    degrees: 0, +-0.5, +-1). Held for a decision from cruise it drives as far, and turns about as far
    (29.2 and 56.5 degrees against 30 and 60: the wheels ramp to the held rate), as the discrete
    action, which ramps its yaw rate along a trapezoid instead of holding one."""
    act = _check_action(action)
    return np.array([act.direction, act.turn / math.radians(60.0)], dtype=np.float32)


def rate_limit(
    previous: np.ndarray | list | tuple,
    targets: np.ndarray | list | tuple,
    max_wheel_accel: float,
    cmd_dt: float,
) -> np.ndarray:
    """Rate-limit wheel-speed commands, one command period at a time.

    Starting from ``previous``, each command moves towards its target by at
    most ``max_wheel_accel * cmd_dt`` on every wheel. When a wheel would exceed
    the limit the whole 3-vector step is scaled down (not clipped per wheel),
    so the commanded body twist keeps its direction and the robot does not
    veer while it accelerates.

    Args:
        previous: shape (3,), wheel speeds before the first command (rad/s).
        targets: shape (n, 3), desired wheel speeds (rad/s).
        max_wheel_accel: rad/s^2 (a rim acceleration a in m/s^2 is a / R).
        cmd_dt: command period (s).

    Returns:
        Shape (n, 3), the limited wheel speeds (rad/s).
    """
    prev = _last_axis3(previous, "previous").reshape(3).copy()
    tgt = _last_axis3(targets, "targets").reshape(-1, 3)
    if not (max_wheel_accel > 0 and cmd_dt > 0):
        raise ValueError(f"max_wheel_accel and cmd_dt must be positive, got {max_wheel_accel=} {cmd_dt=}")
    max_step = max_wheel_accel * cmd_dt
    out = np.empty_like(tgt)
    for k in range(tgt.shape[0]):
        delta = tgt[k] - prev
        biggest = np.abs(delta).max()
        if biggest > max_step:
            delta *= max_step / biggest
        prev += delta
        out[k] = prev
    return out


class DriveController:
    """Turns discrete actions into rate-limited wheel-speed commands.

    Holds the last wheel command so consecutive decisions are continuous
    (forward -> backward takes time). Call :meth:`reset` at episode start.
    """

    _CACHE_SIZE = 4096

    def __init__(self, cache: dict | None = None) -> None:
        """``cache``: a plan memo to share between controllers (many worlds of one task); by default
        each controller has its own."""
        self._last = np.zeros(3)
        # A plan depends only on its arguments and the last command, and episodes
        # keep revisiting the same few states (cruising, turning from cruise):
        # memoising skips the per-period Python loop of rate_limit.
        self._plans: dict[tuple, np.ndarray] = {} if cache is None else cache

    @property
    def last(self) -> np.ndarray:
        """Shape (3,): the last wheel-speed command (rad/s), a copy."""
        return self._last.copy()

    def reset(self, wheel_speeds: np.ndarray | None = None) -> None:
        """Set the remembered command to zero (or to ``wheel_speeds``, rad/s)."""
        self._last = (
            np.zeros(3)
            if wheel_speeds is None
            else _last_axis3(wheel_speeds, "wheel_speeds").reshape(3).copy()
        )

    def plan(
        self,
        action: int,
        speed: float,
        period: float = 0.5,
        cmd_dt: float = 0.01,
        max_accel: float = 4.0,
    ) -> np.ndarray:
        """Wheel-speed commands for one decision: profile -> IK -> rate limit.

        Args: as :func:`action_profile` (speed m/s, period/cmd_dt s, max_accel m/s^2).

        Returns:
            Shape (n_cmd, 3) wheel speeds (rad/s), one row per command period.
        """
        key = (action, speed, period, cmd_dt, max_accel, self._last.tobytes())
        commands = self._plans.get(key)
        if commands is None:
            targets = wheel_speeds(action_profile(action, speed, period, cmd_dt, max_accel))
            commands = rate_limit(self._last, targets, max_accel / WHEEL_RADIUS, cmd_dt)
            commands.setflags(write=False)
            if len(self._plans) >= self._CACHE_SIZE:
                self._plans.clear()
            self._plans[key] = commands
        self._last = commands[-1].copy()
        return commands

    def plan_twist(
        self, twist: tuple[float, float], period: float, cmd_dt: float, max_accel: float
    ) -> np.ndarray:
        """Wheel-speed commands for one decision of a continuous action: ``twist`` (forward m/s,
        yaw rate rad/s), i.e. the body twist ``[forward, 0, yaw_rate]`` held for the decision ->
        IK -> the same rate limit as :meth:`plan` (so a turn starts with the wheels' acceleration
        ramp). Shape (n_cmd, 3) wheel speeds (rad/s), one row per command period."""
        forward, yaw_rate = twist
        targets = np.repeat(
            wheel_speeds([forward, 0.0, yaw_rate])[None, :], _n_commands(period, cmd_dt), axis=0
        )
        commands = rate_limit(self._last, targets, max_accel / WHEEL_RADIUS, cmd_dt)
        self._last = commands[-1].copy()
        return commands


class BatchDriveController:
    """:class:`DriveController` for N worlds at once, discrete actions only: a decision sorts the
    worlds by their (last command, action) pair, then costs a few numpy operations per distinct
    pair instead of Python per world (many worlds of one task share a handful: cruising, turning
    from cruise).

    Each world's last command is an index into the distinct last commands seen; a pair's plan is
    :meth:`DriveController.plan`'s, computed once (bit for bit the same), then passed through
    ``convert`` (e.g. :func:`body_twist` for the planar drive) and kept. The arguments after ``n``
    are :meth:`DriveController.plan`'s (speed m/s, period and cmd_dt s, max_accel m/s^2). Memory is
    bounded: past ``_CACHE_SIZE`` plans the memo is emptied and the last commands that no world
    holds are forgotten.
    """

    _CACHE_SIZE = 4096

    def __init__(
        self,
        n: int,
        speed: float,
        period: float,
        cmd_dt: float,
        max_accel: float,
        convert: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        self._args = (speed, period, cmd_dt, max_accel)
        self._convert = convert
        self._lasts: list[np.ndarray] = [np.zeros(3)]  # id -> last command (rad/s); id 0: at rest
        self._ids: dict[bytes, int] = {self._lasts[0].tobytes(): 0}
        self._plans: dict[int, tuple[np.ndarray, int]] = {}  # last id * actions + action -> (plan, next id)
        self._state = np.zeros(int(n), dtype=np.int64)  # each world's last command, by id

    def reset(self, worlds: np.ndarray | Sequence[int]) -> None:
        """The worlds' last commands back to zero (an episode's start)."""
        self._state[np.asarray(worlds, dtype=np.int64)] = 0

    def plan(self, worlds: np.ndarray, actions: np.ndarray, out: np.ndarray) -> None:
        """Writes the commands of world ``worlds[k]``'s action ``actions[k]`` into ``out[:, worlds[k]]``.

        ``worlds``: (K,) distinct world indices; ``actions``: (K,) integers 0..5; ``out``:
        (n_cmd, N, 3), wheel speeds (rad/s), or what ``convert`` makes of them (the planar drive's
        body twist: m/s, m/s, rad/s).
        """
        worlds, actions = np.asarray(worlds, dtype=np.int64), np.asarray(actions)
        if actions.shape != worlds.shape or not np.issubdtype(actions.dtype, np.integer) or (
            actions.size and not (0 <= actions.min() and actions.max() < len(ACTIONS))
        ):  # fmt: skip
            raise ValueError(f"BatchDriveController.plan: one action 0..{len(ACTIONS) - 1} per world "
                             f"({worlds.size}), got {actions!r}")  # fmt: skip
        if len(self._plans) >= self._CACHE_SIZE:
            self._forget()
        keys = self._state[worlds] * len(ACTIONS) + actions.astype(np.int64)
        order = np.argsort(keys, kind="stable")
        distinct, starts = np.unique(keys[order], return_index=True)
        for key, group in zip(distinct.tolist(), np.split(worlds[order], starts[1:]), strict=True):
            commands, following = self._plans.get(key) or self._new_plan(key)
            out[:, group] = commands[:, None, :]
            self._state[group] = following

    def _new_plan(self, key: int) -> tuple[np.ndarray, int]:
        last, action = divmod(key, len(ACTIONS))
        controller = DriveController()  # its own memo, dropped with it: the plans are kept here
        controller.reset(self._lasts[last])
        plan = controller.plan(action, *self._args)
        end = plan[-1].tobytes()
        if end not in self._ids:
            self._ids[end] = len(self._lasts)
            self._lasts.append(plan[-1].copy())
        self._plans[key] = (self._convert(plan) if self._convert else plan, self._ids[end])
        return self._plans[key]

    def _forget(self) -> None:
        """Empties the memo and keeps only the last commands some world holds (at rest first)."""
        held = np.unique(np.concatenate([[0], self._state]))
        self._state = np.searchsorted(held, self._state)
        self._lasts = [self._lasts[i] for i in held.tolist()]
        self._ids = {last.tobytes(): i for i, last in enumerate(self._lasts)}
        self._plans = {}
