"""The navigation task: a Robotino in a procedural arena, six discrete actions (or a continuous
twist, ``control.actions = "continuous"``).

One action holds for a decision period (default 0.5 s). Composer's own loop
calls Python hooks around every physics substep, which costs 40-60 % of the
simulation time for this model; so this task reports one composer substep per
control step and runs the other substeps itself in ``before_step``, in C
(``mj_step`` with ``nstep``). Where a contact or an arrival can happen within the
decision, it steps one command period (default 10 ms) at a time: per period it
sets the wheel commands, moves the moving obstacles and checks for collision and
arrival (and then divergence), so the outcome is decided at 10 ms resolution.
Where nothing is within reach (``_nothing_within_reach``), it steps each run of
equal commands in one call; the end of the decision checks every outcome either way.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Sequence

import dm_env
import mujoco
import numpy as np
from dm_control import composer
from dm_control.composer.observation import observable
from dm_env import specs

from nirl_mj.data import features
from nirl_mj.sim import observations
from nirl_mj.sim.arena import NavigationArena
from nirl_mj.sim.drive import BODY_RADIUS, DriveController, body_twist, max_yaw_rate
from nirl_mj.sim.environment import Environment
from nirl_mj.sim.layout import Layout, generate_layout
from nirl_mj.sim.memory import RayMemory
from nirl_mj.sim.robot import Robotino
from nirl_mj.sim.sensing import Rangefinders, RangeSensors, Scan
from nirl_mj.sim.spec import TaskSpec, load_task

_DIVERGENCE_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQPOS,
)


UPRIGHT = math.cos(math.radians(45.0))  # tilt beyond 45 degrees: tipped over
AIRBORNE = 0.25  # metres the base may rise or sink before it counts as flying


class Outcome(enum.IntEnum):
    """How an episode ended; the ``outcome`` observation holds it (RUNNING until the end)."""

    RUNNING = 0
    TARGET = 1
    COLLISION = 2
    TIMEOUT = 3
    PHYSICS_ERROR = 4  # diverged, tipped over or airborne: a failure (``NavigationTask.physics_error``)


class NavigationTask(composer.Task):
    """Reach the target without touching any obstacle or wall, within the step budget.

    Reward (for users of the dm_env interface; learners in this project do not
    read it): progress towards the target in units of one decision's travel,
    plus +1 on arrival and -1 on collision or divergence. Discount is 0 after
    arrival, collision or divergence and 1 on a timeout.
    """

    def __init__(self, spec: TaskSpec) -> None:
        self._spec = spec
        self.physics_error = ""  # why the last episode ended in a physics error (none yet)
        control = spec.control
        self._arena = NavigationArena(spec.arena)
        self._robot = Robotino(fidelity=spec.robot.drive, rays_per_sensor=spec.robot.rays_per_sensor)
        self._robot.attach_to(self._arena, self._arena.ground_geom)
        # Composer's base arena asks for noslip iterations; the drive models are
        # tuned without them and they cost about 20 % of the step time.
        self._arena.mjcf_model.option.noslip_iterations = 0
        # The ranges come from one mj_multiRay per decision (RangeSensors); the robot's
        # MJCF rangefinders (its only sensors) would cost more than the rest of a physics
        # step, at every step: compiled disabled, read on demand (rangefinder_rays).
        self._arena.mjcf_model.option.flag.sensor = "disable"
        self.set_timesteps(control_timestep=control.decision_period, physics_timestep=spec.physics_timestep)
        self._substeps_per_command = round(control.command_period / spec.physics_timestep)
        self._commands_per_decision = round(control.decision_period / control.command_period)
        self._drive = DriveController()
        self._continuous = control.actions == "continuous"
        self._budget = spec.step_budget
        # Composer reads the observables once before the first episode.
        self._layout: Layout | None = None
        self._steps = 0
        self._outcome = Outcome.RUNNING
        n_rays = features.N_SENSORS * spec.robot.rays_per_sensor
        self._scan = Scan(
            np.full(features.N_SENSORS, np.inf),
            np.full(n_rays, np.inf),
            np.zeros(features.N_SENSORS, bool),
            0.0,
            0.0,
            False,
        )
        self._pose = np.zeros(3)
        self._phi = np.zeros(features.N_FEATURES, dtype=np.float32)
        self._danger = np.zeros(features.N_SENSORS, dtype=np.int8)
        self._progress = 0.0
        # The sensor expert's memory, with its default stuck_steps (sim.memory.STUCK_STEPS): V is then
        # the sector that expert steers for (an expert built with another stuck_steps would drift apart).
        self._memory = RayMemory() if spec.sensing.guide == "memory" else None
        self._observables = self._make_observables()
        # Called with ``physics`` after every command period (default 10 ms) of a
        # decision when set, e.g. to render video frames at a fixed rate of simulated
        # time (nirl_mj.inspect.video). Setting it makes every decision run command by
        # command, which is the same physics step for step, only slower.
        self.command_hook: Callable[[object], None] | None = None

    # -- composer wiring -------------------------------------------------------------

    @property
    def root_entity(self) -> NavigationArena:
        return self._arena

    @property
    def robot(self) -> Robotino:
        return self._robot

    @property
    def spec(self) -> TaskSpec:
        return self._spec

    @property
    def physics_steps_per_control_step(self) -> int:
        # Composer steps once per control step; before_step runs the rest (module doc).
        return 1

    @property
    def observables(self):
        return self._observables

    def action_spec(self, physics) -> specs.DiscreteArray | specs.BoundedArray:
        """``DiscreteArray(6)``, or with ``control.actions = "continuous"`` a ``BoundedArray`` (2,):
        forward speed in [-speed, speed] m/s and yaw rate in [-w, w] rad/s, w the rate that turns
        60 degrees in one decision (:func:`~nirl_mj.sim.drive.max_yaw_rate`)."""
        if self._continuous:
            return continuous_action_spec(self._spec)
        return specs.DiscreteArray(num_values=features.N_ACTIONS, dtype=np.int64, name="action")

    def get_reward_spec(self) -> specs.Array:
        return specs.Array(shape=(), dtype=np.float64, name="reward")

    def get_discount_spec(self) -> specs.BoundedArray:
        return specs.BoundedArray(shape=(), dtype=np.float64, minimum=0.0, maximum=1.0, name="discount")

    def _make_observables(self) -> dict[str, observable.Observable]:
        width, height = self._spec.arena.size
        diagonal = math.hypot(width, height)
        obs = {
            "features": lambda physics: self._phi.copy(),
            "ranges": lambda physics: np.minimum(self._scan.ranges, self._spec.sensing.range),
            "rays": lambda physics: np.minimum(self._scan.rays, self._spec.sensing.range),
            "danger": lambda physics: self._danger.copy(),
            "wall": lambda physics: self._scan.wall.astype(np.int8),
            "pose": lambda physics: observations.arena_pose(self._pose, width, height),
            "target": lambda physics: np.asarray(self._spec.arena.target, dtype=np.float64),
            "target_distance": lambda physics: np.array([min(self._scan.target_distance, diagonal)]),
            "target_bearing": lambda physics: np.array([wrap_angle(self._scan.bearing)]),
            "outcome": lambda physics: np.array([self._outcome], dtype=np.int32),
            "steps": lambda physics: np.array([self._steps], dtype=np.int32),
        }
        bounds = observations.observation_specs(self._spec)
        return {name: observations.Bounded(fn, bounds[name]) for name, fn in obs.items()}

    # -- episode ---------------------------------------------------------------------

    def after_compile(self, physics, random_state) -> None:
        model, self._data = physics.model.ptr, physics.data.ptr
        self._model = model
        self._sensors = RangeSensors(
            model,
            self._arena.wall_mask(physics),
            self._spec.robot.rays_per_sensor,
            self._spec.sensing.range,
            BODY_RADIUS,
        )
        ray_gap = features.SECTOR_WIDTH / self._spec.robot.rays_per_sensor
        self._hidden_margin = 0.5 + (self._spec.sensing.range + BODY_RADIUS) * math.sin(ray_gap / 2)
        self._rangefinders = Rangefinders(
            model,
            physics.bind(self._robot.rangefinders).element_id,
            self._spec.sensing.range,
            BODY_RADIUS,
        )
        self._ground_id = physics.bind(self._arena.ground_geom).element_id
        base_id = physics.bind(self._robot.base_body).element_id
        self._base_xy = self._data.xpos[base_id, :2]  # a view: current after every step
        self._base_z = self._data.xpos[base_id, 2:3]  # views too: height and the body z axis' up part
        self._base_up = self._data.xmat[base_id, 8:9]
        self._origin_id = physics.bind(self._robot.sensor_origin).element_id

    def initialize_episode(self, physics, random_state) -> None:
        self._layout = generate_layout(self._spec.arena, random_state, robot_radius=BODY_RADIUS)
        self._arena.apply_layout(physics, self._layout)
        x, y = self._layout.start
        self._robot.set_pose(physics, x, y, self._layout.start_yaw)
        self._drive.reset()
        self._steps = 0
        self._outcome = Outcome.RUNNING
        self.physics_error = ""
        mujoco.mj_forward(self._model, self._data)
        self._start_z = float(self._base_z[0])
        self._distance = self._target_distance()
        self._sense(physics)

    def before_step(self, physics, action, random_state) -> None:
        control = self._spec.control
        if self._continuous:
            twist = checked_twist(action, continuous_action_spec(self._spec))
            wheel_commands = self._drive.plan_twist(
                twist, control.decision_period, control.command_period, control.max_accel
            )
        else:
            wheel_commands = self._drive.plan(
                checked_action(action), control.speed, control.decision_period, control.command_period,
                control.max_accel,
            )  # fmt: skip
        checked = self.command_hook is not None or not self._nothing_within_reach()
        self._run_decision(physics, wheel_commands, checked=checked)

    def _nothing_within_reach(self) -> bool:
        """True when no contact and no arrival can happen within this decision.

        That is: no moving obstacles, and both the nearest sensed obstacle and the
        target's rim are farther than the robot can travel in one decision (with
        20 % to spare) plus ``self._hidden_margin``, what the gaps between rays can
        hide (0.5 m, plus half the gap between neighbouring rays at full range: a
        box corner can poke at most that far between two rays). That bound holds for
        obstacles wider than the gap between rays where they stand; a thinner one can hide
        entirely (a 0.5 m wall end-on, beyond about 3.4 m: farther than a decision travels at
        5 m/s), and the end-of-decision check in after_step catches its contact.
        """
        if self._spec.arena.moving_obstacles:
            return False
        reach = 1.2 * self._spec.control.speed * self._spec.control.decision_period + self._hidden_margin
        if reach >= self._spec.sensing.range:
            return False  # beyond the sensing range nothing is known
        nearest = float(self._scan.rays.min())
        return nearest > reach and self._scan.target_distance - self._spec.arena.target_radius > reach

    def _run_decision(self, physics, wheel_commands: np.ndarray, checked: bool) -> None:
        """Steps the physics through one decision, (n_cmd, 3) wheel commands.

        Checked: one command period at a time, moving the moving obstacles and
        stopping once the outcome is decided. Unchecked: one ``mj_step`` call per
        run of equal commands (the same physics, step for step).
        """
        period = self._spec.control.command_period
        n_cmd = len(wheel_commands)
        if checked:
            starts = list(range(n_cmd))
        else:
            change = np.any(wheel_commands[1:] != wheel_commands[:-1], axis=1)
            if self._robot.fidelity == "planar":
                # Planar commands are world-frame velocities for the current heading:
                # while turning they change every period even if the wheel speeds do not.
                change |= body_twist(wheel_commands[:-1])[:, 2] != 0
            starts = [0, *(np.flatnonzero(change) + 1).tolist()]
        moving = self._spec.arena.moving_obstacles > 0
        command = self._robot.wheel_commander(physics, period)
        for k, j in zip(starts, [*starts[1:], n_cmd], strict=True):
            command(wheel_commands[k])
            if moving:
                self._arena.move_obstacles(physics, period * (j - k))
            # Composer takes the decision's very last substep itself.
            n = (j - k) * self._substeps_per_command - (1 if j == n_cmd else 0)
            if n:
                mujoco.mj_step(self._model, self._data, n)
            if self.command_hook is not None:
                self.command_hook(physics)
            if checked and self._check_outcome():
                # Decided: hold the robot still for composer's final substep (zero twist:
                # the command period does not matter).
                command(np.zeros(3))
                break

    def after_step(self, physics, random_state) -> None:
        self._steps += 1
        mujoco.mj_forward(self._model, self._data)
        previous = self._distance
        self._distance = self._target_distance()
        self._progress = (previous - self._distance) / (
            self._spec.control.speed * self._spec.control.decision_period
        )
        if self._outcome == Outcome.RUNNING and self._diverged():
            self._outcome = Outcome.PHYSICS_ERROR
        if self._outcome == Outcome.RUNNING:
            self._check_outcome()
        if self._outcome == Outcome.RUNNING and self._steps >= self._budget:
            self._outcome = Outcome.TIMEOUT
        self._sense(physics)

    def should_terminate_episode(self, physics) -> bool:
        return self._outcome != Outcome.RUNNING

    def get_reward(self, physics) -> float:
        bonus = {Outcome.TARGET: 1.0, Outcome.COLLISION: -1.0, Outcome.PHYSICS_ERROR: -1.0}
        return float(self._progress + bonus.get(self._outcome, 0.0))

    def get_discount(self, physics) -> float:
        return 1.0 if self._outcome in (Outcome.RUNNING, Outcome.TIMEOUT) else 0.0

    # -- state -----------------------------------------------------------------------

    @property
    def outcome(self) -> Outcome:
        """How the current episode ended so far."""
        return self._outcome

    @property
    def layout(self) -> Layout | None:
        """The arena of the current episode."""
        return self._layout

    @property
    def last_scan(self) -> Scan | None:
        """The sensor reading behind the latest observation."""
        return self._scan

    def rangefinder_rays(self, physics) -> np.ndarray:
        """The robot's MJCF rangefinders, computed now: clearance (metres, ``inf`` where
        nothing is within range) of every ray, shape (9 * rays_per_sensor,), in
        :func:`~nirl_mj.sim.sensing.camera_ray_angles`' order. Not used by the task (see
        :mod:`nirl_mj.sim.sensing`); for checks and visualisation."""
        return self._rangefinders.read(physics.data.ptr)

    def _target_distance(self) -> float:
        x, y = self._base_xy
        tx, ty = self._layout.target
        return math.hypot(tx - x, ty - y)

    def _check_outcome(self) -> bool:
        """Sets the outcome from the current contacts and position; True if decided.

        Divergence is looked for only once something is decided (and at the end
        of every decision): MuJoCo resets a diverged state, and the reset robot
        can seem to touch a wall, which must count as the divergence it is.
        """
        if self._in_collision():
            outcome = Outcome.COLLISION
        elif self._target_distance() <= self._spec.arena.target_radius:
            outcome = Outcome.TARGET
        else:
            return False
        self._outcome = Outcome.PHYSICS_ERROR if self._diverged() else outcome
        return True

    def _diverged(self) -> bool:
        """MuJoCo diverged, or the robot tipped over or left the floor (which its drive cannot
        cause in a sound simulation: too coarse a timestep for the speed, e.g. rollers at 5 m/s
        and 0.02 s); the reason is kept in :attr:`physics_error`."""
        if any(self._data.warning[w].number for w in _DIVERGENCE_WARNINGS):
            self.physics_error = "MuJoCo reported a diverged state (bad qpos/qvel/qacc)"
        elif self._base_up[0] < UPRIGHT:
            tilt = math.degrees(math.acos(float(np.clip(self._base_up[0], -1.0, 1.0))))
            self.physics_error = f"the robot tipped over ({tilt:.0f} degrees from upright)"
        elif abs(self._base_z[0] - self._start_z) > AIRBORNE:
            self.physics_error = f"the robot left the floor (base {self._base_z[0] - self._start_z:+.2f} m)"
        return bool(self.physics_error)

    def _in_collision(self) -> bool:
        # Wheels touch the floor only through explicit pairs and nothing else
        # touches the floor, so any contact without the floor is robot vs world.
        ncon = self._data.ncon
        if ncon == 0:
            return False
        # A contact holds the floor at most once: some contact lacks it iff fewer than ncon do.
        return int(np.count_nonzero(self._data.contact.geom == self._ground_id)) < ncon

    def _sense(self, physics) -> None:
        self._pose = self._robot.get_pose(physics)
        origin = self._data.site_xpos[self._origin_id]
        self._scan = self._sensors.scan(
            self._data, origin, float(self._pose[2]), np.asarray(self._layout.target)
        )
        sensing = self._spec.sensing
        self._danger = features.danger_levels(self._scan.ranges, sensing.range, sensing.danger7_clearance)
        region = features.target_region(self._guide_bearing())
        self._phi = features.state_features(self._danger, self._scan.wall, region, self._scan.target_visible)

    def _guide_bearing(self) -> float:
        """Where phi's sector V points (radians from the front): the target's bearing, or with
        ``sensing.guide = "memory"`` the memory's escape bearing while it says the robot is stuck.
        The memory reads what the sensor expert reads (pose, rays capped at the range, target)."""
        if self._memory is None:
            return self._scan.bearing
        width, height = self._spec.arena.size
        pose = observations.arena_pose(self._pose, width, height)
        rays = np.minimum(self._scan.rays, self._spec.sensing.range)
        if self._steps == 0:
            self._memory.reset(pose, np.asarray(self._spec.arena.target, dtype=np.float64), rays)
        self._memory.update(pose[:2], float(pose[2]), rays)
        if not self._memory.escaping:
            return self._scan.bearing
        return math.radians(self._memory.escape_bearing(pose[:2], float(pose[2])))


def wrap_angle(angle):
    """Angle in radians wrapped to (-pi, pi]: a float, or elementwise an array."""
    return math.pi - (math.pi - angle) % (2 * math.pi)


def checked_action(action) -> int:
    a = np.asarray(action)
    if a.shape != () or not np.issubdtype(a.dtype, np.integer) or not 0 <= int(a) < features.N_ACTIONS:
        raise ValueError(
            f"action must be one integer in 0..{features.N_ACTIONS - 1} "
            f"({', '.join(f'{i} {n}' for i, n in enumerate(features.ACTION_NAMES))}), got {action!r}"
        )
    return int(a)


def checked_actions(actions: Sequence, worlds: np.ndarray) -> np.ndarray:
    """The discrete actions ``actions[w]`` of the worlds ``worlds`` (K,), as an int64 array (K,),
    each accepted or refused as :func:`checked_action` does (whose error names a bad one). A numpy
    integer array, or actions that are all Python ints, are checked at once; anything else one
    action at a time."""
    if isinstance(actions, np.ndarray) and actions.ndim == 1 and np.issubdtype(actions.dtype, np.integer):
        chosen = picked = actions[worlds]
    else:
        picked = [actions[w] for w in np.asarray(worlds).tolist()]
        try:  # type() and not isinstance: a bool is refused, as checked_action refuses it
            chosen = np.array(picked, dtype=np.int64) if all(type(a) is int for a in picked) else None
        except OverflowError:
            chosen = None
        if chosen is None:
            return np.array([checked_action(a) for a in picked], dtype=np.int64)
    if chosen.size and not (chosen.min() >= 0 and chosen.max() < features.N_ACTIONS):
        return np.array([checked_action(a) for a in picked], dtype=np.int64)  # names the bad one
    return chosen.astype(np.int64)


def continuous_action_spec(spec: TaskSpec) -> specs.BoundedArray:
    """The continuous action of a task: (forward speed m/s, yaw rate rad/s), shape (2,)."""
    speed, yaw = spec.control.speed, max_yaw_rate(spec.control.decision_period)
    return specs.BoundedArray((2,), np.float64, [-speed, -yaw], [speed, yaw], name="action")


def action_scale(spec: TaskSpec) -> np.ndarray:
    """(m/s, rad/s) of a continuous action of 1, float64 (2,): the task's speed and the yaw rate that
    turns 60 degrees a decision. Continuous actions are recorded (datasets) and taken (Gymnasium) as
    shares of it in [-1, 1]; :func:`share_twist` turns a share into the twist the task takes."""
    return np.asarray(continuous_action_spec(spec).maximum, dtype=np.float64)


def share_twist(share, scale: np.ndarray) -> np.ndarray:
    """The twist (forward m/s, yaw rate rad/s) of the continuous action ``share`` (two numbers, clipped
    to [-1, 1]), in float64: ``clip(share, -1, 1) * scale``. The one computation of the episode loop
    (``sim.episode.run_episode``) and the Gymnasium environment (``gym.env.NavigationEnv.twist``), so
    the float32 shares a dataset holds replay bit for bit through either."""
    return np.clip(np.asarray(share, dtype=np.float64).reshape(-1), -1.0, 1.0) * scale


def checked_twist(action, bounds: specs.BoundedArray) -> tuple[float, float]:
    """A continuous action as (forward m/s, yaw rate rad/s), or a clear error. A value a float32
    rounding beyond a bound (Gymnasium and Stable-Baselines3 act in float32) counts as the bound."""
    accepted = (f"(forward speed m/s in [{bounds.minimum[0]:g}, {bounds.maximum[0]:g}], yaw rate rad/s in "
                f"[{bounds.minimum[1]:.4g}, {bounds.maximum[1]:.4g}])")  # fmt: skip
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        a = np.full(3, np.nan)
    if a.shape != (2,) or not np.all(np.isfinite(a)):
        raise ValueError(f"a continuous action is two finite numbers {accepted}, got {action!r}")
    slack = 1e-6 * np.abs(bounds.maximum)
    if np.any(a < bounds.minimum - slack) or np.any(a > bounds.maximum + slack):
        raise ValueError(f"continuous action {a.tolist()} out of range: accepted {accepted}")
    a = np.clip(a, bounds.minimum, bounds.maximum)
    return float(a[0]), float(a[1])


def make_env(
    task: str | TaskSpec = "navigate", seed: int | np.random.RandomState | None = None
) -> dm_env.Environment:
    """Builds the navigation environment.

    ``task`` is a name under ``tasks/``, a path to a TOML file, or a
    :class:`~nirl_mj.sim.spec.TaskSpec`; ``seed`` makes every episode's arena and
    the whole run reproducible. Observations: ``features`` (16,) phi(s),
    ``ranges`` (9,) clearance in metres (the sensing range where nothing is
    sensed), ``rays`` (9 * rays_per_sensor,) the same per ray (sensor-major,
    ray angles in :func:`nirl_mj.sim.sensing.ray_angles`), ``danger`` (9,) levels
    0..7, ``wall`` (9,) flags, ``pose`` (x, y, yaw) metres/radians, ``target``
    (x, y) metres, ``target_distance`` (1,) metres, ``target_bearing`` (1,) radians in
    (-pi, pi] counter-clockwise from the robot's front,
    ``outcome`` (1,) an :class:`Outcome`, ``steps`` (1,) decisions taken. Every spec is a
    ``BoundedArray`` with the observation's range (:mod:`nirl_mj.sim.observations`).
    """
    spec = load_task(task)
    return Environment(
        task=NavigationTask(spec),
        random_state=seed,
        recompile_mjcf_every_episode=False,
        raise_exception_on_physics_error=False,
        strip_singleton_obs_buffer_dim=True,
        legacy_step=False,
    )
