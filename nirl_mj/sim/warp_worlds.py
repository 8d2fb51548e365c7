"""Many arenas at once: N worlds of one navigation task on MuJoCo Warp (the ``warp`` extra).

The dm_control task (:mod:`nirl_mj.sim.task`) stays the reference and the default; this module
steps N copies of its compiled model in one batch, each world with its own arena, on Warp's CPU
device or a GPU (``device="cuda"``). What every world does is the task's, piece by piece:

- **Arenas and starts** come from the reference task itself: a world that starts an episode in
  arena ``seed`` is given what ``env.reset()`` of the dm_control environment seeded ``seed``
  produced (the obstacle slots' poses, sizes and bounds as per-world model fields; qpos, qvel,
  ctrl). So both backends drive the same arena from the same state.
- **Actions** go through the same :class:`~nirl_mj.sim.drive.DriveController` into wheel
  commands, one per command period (default 10 ms): discrete ones through its batch form
  (:class:`~nirl_mj.sim.drive.BatchDriveController`, the same plans for every world at once),
  continuous ones through one controller per world; on the planar drive a kernel turns them into
  world-frame velocities at every period, as ``Robotino.wheel_commander``.
- **Outcomes** are checked when the task checks them: after every command period but the last
  (the task's last check falls one physics step before the decision's end), then, once the state
  is brought up to date at the end of the decision (``forward``, as the task's ``after_step``),
  again with the step budget. A contact without the floor is a collision, the base within the
  target radius an arrival, and either comes with a divergence check (tipped over, airborne, a
  state that is not finite: Warp raises no warnings to read). A world whose outcome is decided
  mid-decision takes one more physics step with its wheels stopped, as the task does, and is then
  held in that state (restored after every step) until its next episode, so its last observation
  is the task's. A world that has no episode yet (``outcomes`` -1) is held likewise.
- **Sensing**: the nine sensors' rays and the target ray through ``mujoco_warp.rays`` (group 0
  only, as ``mj_multiRay``), then the task's own numpy code (:func:`~nirl_mj.sim.sensing.
  sensor_readings`, :func:`~nirl_mj.sim.sensing.target_sight`, :mod:`nirl_mj.data.features`) on
  the batch.

Contact bits are one set for all worlds in Warp: every obstacle slot is armed
(:meth:`~nirl_mj.sim.arena.NavigationArena.arm_every_slot`); unused slots are parked far below
the floor, as on the CPU. Warp computes in float32 where the CPU task uses float64, and its
contact solver differs in the last digits: the two agree on phi(s) for the first decisions of
an episode and on almost every episode's outcome, not bit for bit (``tests/test_warp_worlds.py``
states the tolerance; ``bench/bench_backend.py`` measures it). Buffers are sized per world
(``contacts_per_world``, ``constraints_per_world``); Warp drops what overflows them, so an
overflow that Warp flags (``Data.overflow``) raises instead of simulating without them.

A limitation measured with mujoco-warp 3.17.0 (Warp 1.19, CPU device): Warp's Newton solver, the
task's, turns this model's state into NaN within about 16 steps of the robot resting on the floor
with its wheels stopped; MuJoCo's solver does not. The conjugate-gradient solver stays finite but
did not converge in the task's 100 iterations and parted from the CPU trajectories within a few
decisions, so the backend keeps Newton. A discrete action always moves the robot, and a finished
or idle world is held (above); a continuous policy that stops the robot for long ends its episode
as a physics error (the NaN is caught at the next check), where the CPU task would go on.

Supported: the ``tyre`` drive (the task's default) and the ``planar`` one (NIRL's training drive,
``train_drive``), discrete and continuous actions, static obstacles. Refused with a clear error:
the ``rollers`` drive (it runs, but measured on 2 arenas its many small roller contacts parted
from the CPU task's within an episode: one arena ended in a collision where the CPU task's robot
arrived); moving obstacles (moved in Python between periods); the memory guide
(``sensing.guide = "memory"``, a per-episode Python state).
"""

from __future__ import annotations

import copy
import functools
import math
import time
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import dm_env
import numpy as np

from nirl_mj.data import features
from nirl_mj.data.trajectory import Trajectory, TrajectoryRecorder
from nirl_mj.sim.drive import BODY_RADIUS, BatchDriveController, DriveController, body_twist
from nirl_mj.sim.episode import action_command
from nirl_mj.sim.robot import yaw_from_quat
from nirl_mj.sim.sensing import ray_angles, sensor_readings, target_sight
from nirl_mj.sim.spec import TaskSpec, load_task
from nirl_mj.sim.task import (
    AIRBORNE,
    UPRIGHT,
    Outcome,
    checked_actions,
    checked_twist,
    continuous_action_spec,
    make_env,
    wrap_angle,
)

ARENA_FIELDS = ("body_pos", "body_quat", "geom_size", "geom_aabb", "geom_rbound", "geom_rgba")
"""The model fields a layout writes (``NavigationArena.apply_layout``) that are held per world; its
contact bits are armed in every slot instead (``arm_every_slot``), and ``bvh_aabb`` is not kept."""

_STATE_FIELDS = ("qpos", "qvel", "ctrl", "geom_xpos", "geom_xmat")
"""Data fields a world's start copies from the reference. Warp computes the poses of geoms fixed to
the world once (``make_data``), not in every ``kinematics`` as MuJoCo does: the obstacle slots'
poses, which change with every arena, are copied with the state."""

SECONDS = {
    "resets": "mostly host: the reference task lays out each new arena, copied into the device, whose "
    "reset and forward pass are waited for (reset)",
    "commands": "host: each running world's drive plans its wheel commands (step)",
    "physics": "device: the commands copied in, the decision's physics steps and outcome checks, read "
    "back (step)",
    "rays": "device: the rays' origins and directions copied in, every world's rays cast, read back "
    "(sensing)",
    "features": "host: the poses read back, the rays' directions, then ranges, danger levels and phi(s) "
    "from the rays, on the batch (sensing)",
}
"""The parts of :attr:`WarpWorlds.seconds`: where a step's wall time goes, host or device."""

DEVICES = ("cpu", "cuda")
"""Warp's devices: its CPU device (slow: tests) or a CUDA GPU."""

IDLE = -1
""":attr:`WarpWorlds.outcomes` of a world that has not started an episode yet."""


def unsupported(spec: TaskSpec) -> list[str]:
    """What of ``spec`` the Warp backend does not simulate (empty: all of it)."""
    problems = []
    if spec.robot.drive == "rollers":
        problems.append('robot.drive = "rollers" (accepted: "tyre", "planar")')
    if spec.arena.moving_obstacles:
        problems.append(f"arena.moving_obstacles = {spec.arena.moving_obstacles} (accepted: 0)")
    if spec.sensing.guide == "memory":
        problems.append('sensing.guide = "memory" (accepted: "target")')
    return problems


def _import_warp():
    try:
        import mujoco_warp as mjw
        import warp as wp
    except ImportError as e:
        raise RuntimeError(
            f"the warp backend needs the optional extra: pip install -e '.[warp]' ({e})"
        ) from None
    # no start-up banner and no line per kernel module: Warp 1.19 reads log_level (quiet, before it,
    # is no longer read); warnings and errors still show
    wp.config.quiet = True
    wp.config.log_level = getattr(wp, "LOG_WARNING", 30)
    return wp, mjw


def check_device(device: str) -> None:
    """A clear ValueError unless Warp can run on ``device`` here (a known name; a GPU for "cuda")."""
    if device not in DEVICES:
        raise ValueError(f"device {device!r}: accepted: {', '.join(DEVICES)}")
    wp, _ = _import_warp()
    if device == "cuda" and not wp.is_cuda_available():
        raise ValueError("device 'cuda': Warp sees no CUDA GPU on this machine; accepted here: cpu")


class WarpWorlds:
    """N worlds of one task on MuJoCo Warp; every world runs its own episode.

    ``task`` is a task name, file or :class:`TaskSpec`; ``worlds`` the batch size N; ``device``
    ``"cuda"`` or ``"cpu"`` (Warp's CPU device: slow, for tests). ``contacts_per_world`` and
    ``constraints_per_world`` size Warp's buffers (an overflow raises RuntimeError, never drops
    contacts silently). ``graph``: replay each decision as a CUDA graph captured after the first
    (``None``: on ``cuda``, the default there; ``True`` only on ``cuda``). The first step compiles
    Warp's kernels (about a minute on the CPU, cached on disk afterwards).

    State, per world: :attr:`seeds` (the arena of its episode), :attr:`steps` (decisions taken),
    :attr:`outcomes` (an :class:`Outcome` value, or :data:`IDLE`) and :attr:`observation` (the
    task's observation keys, each with a leading world axis), and :attr:`seconds`, where the wall time
    of :meth:`step` and :meth:`reset` went.
    """

    def __init__(
        self,
        task: str | TaskSpec,
        worlds: int,
        device: str = "cuda",
        contacts_per_world: int = 32,
        constraints_per_world: int = 160,
        graph: bool | None = None,
    ) -> None:
        spec = load_task(task)
        problems = unsupported(spec)
        if problems:
            raise ValueError(f"task {spec.name}: the warp backend does not simulate {'; '.join(problems)}")
        if not isinstance(worlds, int | np.integer) or worlds < 1:
            raise ValueError(f"worlds must be a positive integer, got {worlds!r}")
        check_device(device)
        self._wp, self._mjw = wp, mjw = _import_warp()
        if graph and device != "cuda":
            raise ValueError(
                f"graph = True: CUDA graphs need device 'cuda', got {device!r}; accepted here: None, False"
            )
        # Python launches hundreds of kernels per physics step (10 ms a step with one world on an H100:
        # docs/PERFORMANCE.md); a CUDA graph of a whole decision replays them at once.
        self._graph_wanted = device == "cuda" if graph is None else bool(graph)
        self._graph: Any = None
        self.graph_error: str | None = None
        """Why the decision could not be captured as a CUDA graph (it then runs launch by launch)."""
        self._kernels = _kernels()
        self.spec, self.n, self.device = spec, int(worlds), device
        self._reference = make_env(spec)
        self._reference.reset()
        physics, task_ = self._reference.physics, self._reference.task
        self._m, self._d = physics.model.ptr, physics.data.ptr
        robot, arena = task_.robot, task_.root_entity
        self._base = int(physics.bind(robot.base_body).element_id)
        self._origin = int(physics.bind(robot.sensor_origin).element_id)
        self._ground = int(physics.bind(arena.ground_geom).element_id)
        self._qposadr = int(physics.bind(robot.pose_joints(physics)[0]).qposadr)
        self._planar = spec.robot.drive == "planar"
        actuators = np.asarray(physics.bind(robot.drive_actuators).element_id, dtype=int)
        if actuators.tolist() != list(range(actuators[0], actuators[0] + 3)):
            raise ValueError(f"the drive actuators must be three in a row, got ids {actuators.tolist()}")
        self._ctrl_start = int(actuators[0])
        self._wall_mask = np.asarray(arena.wall_mask(physics), dtype=bool)
        at_rest = {"contacts_per_world": (contacts_per_world, self._d.ncon),
                   "constraints_per_world": (constraints_per_world, self._d.nefc)}  # fmt: skip
        for name, (given, least) in at_rest.items():
            if given < least:
                raise ValueError(
                    f"{name} = {given}: the robot at rest already needs {least}; accepted: >= {least}"
                )
        model = copy.deepcopy(self._m)
        arena.arm_every_slot(physics, model)

        control = spec.control
        substeps = round(control.command_period / spec.physics_timestep)
        n_cmd = round(control.decision_period / control.command_period)
        # Physics steps of a decision after which the task checks the outcome (task._run_decision):
        # the end of every command period but the last, and one step before the decision's end.
        self._checks = {substeps * (k + 1) for k in range(n_cmd - 1)} | {substeps * n_cmd - 1}
        self._substeps, self._n_cmd = substeps, n_cmd
        self._command = action_command(spec)
        self._angles = ray_angles(spec.robot.rays_per_sensor)
        n_rays = self._angles.size + 1  # the last ray points at the target
        self._host_fields = {f: np.repeat(getattr(self._m, f)[None], self.n, axis=0) for f in ARENA_FIELDS}
        with wp.ScopedDevice(device):
            self._mw = mjw.put_model(model, batch_sizes={f: self.n for f in ARENA_FIELDS})
            # Every world starts as a copy of the reference's first episode, held (IDLE) until reset.
            self._dw = mjw.put_data(
                model, self._d, nworld=self.n, nconmax=contacts_per_world, njmax=constraints_per_world
            )
            self._commands = wp.zeros((n_cmd, self.n), dtype=wp.vec3)
            self._touched = wp.zeros(self.n, dtype=int)
            self._outcome_w = wp.full(self.n, IDLE, dtype=int)
            self._held = wp.zeros(self.n, dtype=int)  # 1 once a finished world's final state is kept
            self._kept_qpos = wp.zeros_like(self._dw.qpos)
            self._kept_qvel = wp.zeros_like(self._dw.qvel)
            self._target_w = wp.zeros(self.n, dtype=wp.vec2)
            self._start_z_w = wp.zeros(self.n, dtype=float)
            self._ray_pnt = wp.zeros((self.n, n_rays), dtype=wp.vec3)
            self._ray_vec = wp.zeros((self.n, n_rays), dtype=wp.vec3)
            self._ray_exclude = wp.full(n_rays, -1, dtype=int)
            self._ray_dist = wp.zeros((self.n, n_rays), dtype=float)
            self._ray_geom = wp.zeros((self.n, n_rays), dtype=int)
            self._ray_normal = wp.zeros((self.n, n_rays), dtype=wp.vec3)
        self._ray_host = (
            np.zeros((self.n, n_rays, 3), np.float32),
            np.zeros((self.n, n_rays, 3), np.float32),
        )
        """The rays' origins and directions on the host, (N, rays, 3) float32 each, refilled by each
        sensing."""
        convert = body_twist if self._planar else None  # the planar drive takes the body twist
        self._discrete = control.actions != "continuous"
        self._drive = (
            BatchDriveController(self.n, control.speed, control.decision_period, control.command_period,
                                 control.max_accel, convert)
            if self._discrete else _TwistDrives(self.n, spec, convert)
        )  # fmt: skip
        self.seeds = np.full(self.n, -1, dtype=np.int64)
        self.steps = np.zeros(self.n, dtype=np.int64)
        self.outcomes = np.full(self.n, IDLE, dtype=np.int32)
        self._targets = np.tile(np.asarray(task_.layout.target, dtype=np.float64), (self.n, 1))
        self._start_z = np.zeros(self.n)
        self.observation: dict[str, np.ndarray] = {}
        self.seconds = dict.fromkeys(SECONDS, 0.0)
        """Wall seconds spent so far, by part (:data:`SECONDS`); device parts end with a read back to
        the host, so they hold the device's work, not only its launch."""

    # -- episodes ----------------------------------------------------------------------

    def reset(self, worlds: Sequence[int], seeds: Sequence[int]) -> None:
        """Starts an episode in arena ``seeds[k]`` in world ``worlds[k]`` (the others keep theirs),
        then senses every world."""
        worlds = np.asarray(worlds, dtype=np.int64).reshape(-1)
        seeds = np.asarray(seeds, dtype=np.int64).reshape(-1)
        if worlds.shape != seeds.shape or np.any((worlds < 0) | (worlds >= self.n)):
            raise ValueError(f"reset: worlds (0..{self.n - 1}) and seeds must pair up, got {worlds}, {seeds}")
        wp, mjw, dw = self._wp, self._mjw, self._dw
        started = time.perf_counter()
        mask = np.zeros(self.n, dtype=bool)
        mask[worlds] = True
        with wp.ScopedDevice(self.device):
            mjw.reset_data(self._mw, dw, reset=wp.array(mask, dtype=bool))
            state = {name: getattr(dw, name).numpy() for name in _STATE_FIELDS}
            held = self._held.numpy()
            for w, seed in zip(worlds.tolist(), seeds.tolist(), strict=True):
                self._reference.random_state.seed(seed)
                self._reference.reset()
                for name, rows in self._host_fields.items():
                    rows[w] = getattr(self._m, name)
                for name, rows in state.items():
                    rows[w] = getattr(self._d, name).reshape(rows.shape[1:])
                self._targets[w] = self._reference.task.layout.target
                self._start_z[w] = self._d.xpos[self._base, 2]
                self._drive.reset([w])
                self.seeds[w], self.steps[w], self.outcomes[w], held[w] = seed, 0, int(Outcome.RUNNING), 0
            for name, rows in self._host_fields.items():
                getattr(self._mw, name).assign(rows)
            for name, rows in state.items():
                getattr(dw, name).assign(rows)
            self._held.assign(held)
            self._target_w.assign(self._targets.astype(np.float32))
            self._start_z_w.assign(self._start_z.astype(np.float32))
            self._outcome_w.assign(self.outcomes)
            mjw.forward(self._mw, dw)
            wp.synchronize_device(self.device)  # so that its kernels' time is counted here
        self.seconds["resets"] += time.perf_counter() - started
        self._sense()

    def step(self, actions: Sequence[Any]) -> None:
        """One decision in every running world: ``actions[w]`` an action 0..5 (or, on a task with
        continuous actions, the twist (forward m/s, yaw rate rad/s)); other worlds ignore theirs.
        Updates :attr:`outcomes`, :attr:`steps` and :attr:`observation`."""
        if len(actions) != self.n:
            raise ValueError(f"step: one action per world ({self.n}), got {len(actions)}")
        wp = self._wp
        started = time.perf_counter()
        running = self.outcomes == int(Outcome.RUNNING)
        commands = np.zeros((self._n_cmd, self.n, 3), dtype=np.float32)
        worlds = np.flatnonzero(running)
        self._drive.plan(worlds, checked_actions(actions, worlds) if self._discrete else actions, commands)
        dw = self._dw
        planned = time.perf_counter()
        self.seconds["commands"] += planned - started
        with wp.ScopedDevice(self.device):
            self._commands.assign(commands)
            self._run_decision()
            outcomes = self._outcome_w.numpy()
            overflow = dw.overflow.numpy() & _BUFFER_OVERFLOWS
        self.seconds["physics"] += time.perf_counter() - planned
        if overflow.any():
            contacts, rows = int(dw.nacon.numpy()[0]), int(dw.nefc.numpy().max())
            raise RuntimeError(
                f"Warp's buffers overflowed in {np.count_nonzero(overflow)} of {self.n} worlds (contacts "
                f"{contacts} of {dw.naconmax}, constraint rows up to {rows} of {dw.njmax} a world): raise "
                "contacts_per_world or constraints_per_world of WarpWorlds"
            )
        self.steps[running] += 1
        timeout = running & (outcomes == int(Outcome.RUNNING)) & (self.steps >= self.spec.step_budget)
        outcomes[timeout] = int(Outcome.TIMEOUT)
        if timeout.any():
            self._outcome_w.assign(outcomes)
        self.outcomes = outcomes.astype(np.int32)
        self._sense()

    @property
    def graphed(self) -> bool:
        """Whether decisions replay a captured CUDA graph (from the second decision on)."""
        return self._graph is not None

    def _run_decision(self) -> None:
        """The device work of one decision (its commands already in ``self._commands``): from the
        second decision on, the replay of a CUDA graph captured after the first, which loaded every
        kernel. The graph replays the same launches on the same arrays, which :meth:`reset` and
        :meth:`step` only ever write in place."""
        wp = self._wp
        if self._graph is not None:
            wp.capture_launch(self._graph)
            return
        self._decide()
        if self._graph_wanted and self.graph_error is None:
            try:
                with wp.ScopedCapture() as capture:
                    self._decide()
                self._graph = capture.graph
            except Exception as error:  # capture is an optimisation: launch by launch still works
                self.graph_error = f"{type(error).__name__}: {error}"
                warnings.warn(f"the decision runs without a CUDA graph: {self.graph_error}", stacklevel=3)

    def _decide(self) -> None:
        """Launches one decision's kernels: commands, physics steps, holds and the task's checks.
        No host read or allocation from host memory in here, so that it can be captured."""
        wp, mjw, dw, kernels, control = self._wp, self._mjw, self._dw, self._kernels, self.spec.control
        for s in range(1, self._substeps * self._n_cmd + 1):
            if (s - 1) % self._substeps == 0:
                k = (s - 1) // self._substeps
                wp.launch(kernels.command, dim=self.n, inputs=[
                    self._commands, k, self._outcome_w, int(self._planar), dw.qpos, self._qposadr + 2,
                    float(control.command_period), self._ctrl_start, dw.ctrl,
                ])  # fmt: skip
            mjw.step(self._mw, dw)
            wp.launch(kernels.hold, dim=self.n, inputs=[self._outcome_w, self._held, dw.qpos, dw.qvel,
                                                        self._kept_qpos, self._kept_qvel])  # fmt: skip
            if s in self._checks:
                self._judge(end_of_decision=False)
        mjw.forward(self._mw, dw)
        self._judge(end_of_decision=True)

    def _judge(self, end_of_decision: bool) -> None:
        """Sets the outcome of every running world whose state decides it (the task's checks)."""
        wp, dw, kernels = self._wp, self._dw, self._kernels
        self._touched.zero_()
        wp.launch(kernels.touches, dim=dw.naconmax, inputs=[dw.nacon, dw.contact.geom, dw.contact.worldid,
                                                             self._ground, self._touched])  # fmt: skip
        wp.launch(
            kernels.judge,
            dim=self.n,
            inputs=[
                self._touched, dw.xpos, dw.xmat, dw.qpos, self._base, self._target_w,
                float(self.spec.arena.target_radius), self._start_z_w, float(UPRIGHT), float(AIRBORNE),
                int(end_of_decision), self._ctrl_start, self._outcome_w, dw.ctrl,
            ],
        )  # fmt: skip

    # -- sensing -----------------------------------------------------------------------

    def _sense(self) -> None:
        """Casts every world's rays and builds its observation (the task's keys that a
        trajectory and a policy on phi(s) read)."""
        wp, mjw, dw, spec = self._wp, self._mjw, self._dw, self.spec
        started = time.perf_counter()
        # A state that went non-finite (a physics error) reads as zeros: no NaN reaches numpy below.
        qpos = np.nan_to_num(dw.qpos.numpy().astype(np.float64))
        origin = np.nan_to_num(dw.site_xpos.numpy()[:, self._origin].astype(np.float64))
        a = self._qposadr
        x, y = qpos[:, a], qpos[:, a + 1]
        if self._planar:  # slide x, slide y, hinge yaw
            yaw = qpos[:, a + 2]
        else:  # a free joint
            yaw = yaw_from_quat(*(qpos[:, a + i] for i in range(3, 7)))
        world = self._angles[None, :] + yaw[:, None]
        to_target = self._targets - origin[:, :2]
        target_distance = np.hypot(to_target[:, 0], to_target[:, 1])
        # computed in float64 as the task does, rounded once into the rays' float32 buffers (their
        # z components stay 0), which live as long as the worlds: no per-step allocation
        pnt, vec = self._ray_host
        vec[:, :-1, 0], vec[:, :-1, 1] = np.cos(world), np.sin(world)
        vec[:, -1, :2] = to_target / np.maximum(target_distance, 1e-9)[:, None]
        pnt[...] = origin[:, None, :]
        cast = time.perf_counter()
        with wp.ScopedDevice(self.device):
            self._ray_pnt.assign(pnt)
            self._ray_vec.assign(vec)
            world_only = wp.types.vector(6, dtype=float)(1, 0, 0, 0, 0, 0)  # geom group 0, as mj_multiRay
            mjw.rays(
                self._mw, dw, self._ray_pnt, self._ray_vec, world_only, True, self._ray_exclude,
                self._ray_dist, self._ray_geom, self._ray_normal,
            )  # fmt: skip
            dist = self._ray_dist.numpy().astype(np.float64)
            geom = self._ray_geom.numpy()
        read = time.perf_counter()
        self.seconds["rays"] += read - cast
        sensing = spec.sensing
        k = spec.robot.rays_per_sensor
        ranges, rays, wall = sensor_readings(
            dist[:, :-1], geom[:, :-1], self._wall_mask, k, sensing.range, BODY_RADIUS
        )
        visible = target_sight(geom[:, -1] >= 0, dist[:, -1], target_distance, BODY_RADIUS, sensing.range)
        bearing = np.arctan2(to_target[:, 1], to_target[:, 0]) - yaw
        danger = features.danger_levels(ranges, sensing.range, sensing.danger7_clearance)
        phi = features.state_features(danger, wall, features.target_region(bearing), visible)
        width, height = spec.arena.size
        pose = np.column_stack([np.clip(x, 0.0, width), np.clip(y, 0.0, height), yaw])
        self.observation = {
            "features": phi,
            "ranges": np.minimum(ranges, sensing.range),
            "rays": np.minimum(rays, sensing.range),
            "danger": danger,
            "wall": wall.astype(np.int8),
            "pose": pose,
            "target": self._targets.copy(),
            "target_distance": np.minimum(target_distance, math.hypot(width, height))[:, None],
            "target_bearing": wrap_angle(bearing)[:, None],
            "outcome": self.outcomes[:, None].copy(),
            "steps": self.steps[:, None].astype(np.int32),
        }
        self.seconds["features"] += (cast - started) + (time.perf_counter() - read)

    def world_observation(self, w: int) -> dict[str, np.ndarray]:
        """World ``w``'s observation, as the dm_env task's dict (the keys of :attr:`observation`)."""
        return {key: value[w] for key, value in self.observation.items()}

    # -- rollouts ----------------------------------------------------------------------

    def rollouts(self, agent: Any, seeds: Sequence[int]) -> list[Trajectory]:
        """Drives ``agent`` once in the arena of each seed, ``self.n`` episodes at a time (a world
        that finishes starts the next seed): the trajectories, in the order of ``seeds``.

        The agent must act on phi(s) alone (``agent.acts_on_features``: the reference policies,
        a learner's network), since one agent drives every world at once. On a task with
        continuous actions it answers with shares or a discrete action, as ``run_episode`` takes."""
        if not getattr(agent, "acts_on_features", False):
            raise ValueError(
                f"the warp backend drives agents that act on phi(s) alone (reference policies, learners' "
                f"networks); {getattr(agent, 'kind', type(agent).__name__)} reads more: use the cpu backend"
            )
        seeds = [int(s) for s in seeds]
        spec, period = self.spec, self.spec.control.decision_period
        out: list[Trajectory | None] = [None] * len(seeds)
        recorders = [TrajectoryRecorder(period, spec.control.actions) for _ in range(self.n)]
        episode = np.full(self.n, -1, dtype=np.int64)  # index into seeds, -1: no episode
        todo = iter(range(len(seeds)))

        def start(worlds: list[int]) -> None:
            pairs = [(w, i) for w, i in zip(worlds, todo, strict=False)]
            if not pairs:
                return
            self.reset([w for w, _ in pairs], [seeds[i] for _, i in pairs])
            for w, i in pairs:
                episode[w] = i
                timestep = _timestep(self.world_observation(w), first=True)
                agent.reset(None, timestep)
                recorders[w].start(timestep.observation)

        start(list(range(self.n)))
        idle = self._command(0)[1]  # what a world without an episode is handed (ignored)
        while (episode >= 0).any():
            active = np.flatnonzero(episode >= 0).tolist()
            taken, recorded = [idle] * self.n, {}
            if hasattr(agent, "act_batch"):  # one call for every world (reference policies, networks)
                chosen = agent.act_batch(self.observation["features"][active]).tolist()
            else:
                chosen = [agent.act(_timestep(self.world_observation(w))) for w in active]
            for w, action in zip(active, chosen, strict=True):
                recorded[w], taken[w] = self._command(action)
            self.step(taken)
            ended = []
            for w in active:
                recorders[w].step(recorded[w], self.world_observation(w))
                if self.outcomes[w] != int(Outcome.RUNNING):
                    i = int(episode[w])
                    out[i] = recorders[w].finish(
                        Outcome(int(self.outcomes[w])), seeds[i], spec, spec.control.speed, agent.kind
                    )
                    episode[w] = -1
                    ended.append(w)
            start(ended)
        return out  # type: ignore[return-value]


def _timestep(observation: dict, first: bool = False) -> dm_env.TimeStep:
    kind = dm_env.StepType.FIRST if first else dm_env.StepType.MID
    return dm_env.TimeStep(kind, None if first else 0.0, None if first else 1.0, observation)


_BUFFER_OVERFLOWS = 1 | 2 | 4 | 8 | 16
"""mujoco_warp's ``OverflowType`` bits of its buffers (NEFC, NJMAX_NNZ, BROADPHASE, NARROWPHASE, CCD):
what was dropped. The solver's iteration limits (the other bits) drop nothing."""


class _Kernels:
    """The Warp kernels of a decision (:func:`_kernels`)."""

    def __init__(self, command, touches, judge, hold) -> None:
        self.command, self.touches, self.judge, self.hold = command, touches, judge, hold


@functools.cache
def _kernels() -> _Kernels:
    """The Warp kernels of a decision, defined once warp is imported."""
    import warp as wp

    @wp.kernel
    def command(commands: wp.array2d(dtype=wp.vec3), k: int, outcome: wp.array(dtype=int), planar: int,
                qpos: wp.array2d(dtype=float), yaw_adr: int, dt: float, start: int,
                ctrl: wp.array2d(dtype=float)):  # fmt: skip
        # Robot.wheel_commander: the wheel speeds, or (planar) the body twist (vx, vy, wz) turned into
        # world-frame velocities with the yaw expected at the middle of the command period. A world
        # without a running episode gets stopped wheels.
        w = wp.tid()
        c = commands[k, w]
        if outcome[w] != 0:
            c = wp.vec3(0.0, 0.0, 0.0)
        elif planar != 0:
            yaw = qpos[w, yaw_adr] + 0.5 * c[2] * dt
            cy = wp.cos(yaw)
            sy = wp.sin(yaw)
            c = wp.vec3(cy * c[0] - sy * c[1], sy * c[0] + cy * c[1], c[2])
        for j in range(3):
            ctrl[w, start + j] = c[j]

    @wp.kernel
    def touches(nacon: wp.array(dtype=int), geom: wp.array(dtype=wp.vec2i), worldid: wp.array(dtype=int),
                ground: int, touched: wp.array(dtype=int)):  # fmt: skip
        # The task's _in_collision: any contact without the floor (wheels touch it through pairs only).
        c = wp.tid()
        if c >= nacon[0]:
            return
        g = geom[c]
        if g[0] != ground and g[1] != ground:
            touched[worldid[c]] = 1

    @wp.kernel
    def judge(touched: wp.array(dtype=int), xpos: wp.array2d(dtype=wp.vec3),
              xmat: wp.array2d(dtype=wp.mat33), qpos: wp.array2d(dtype=float), base: int,
              target: wp.array(dtype=wp.vec2), radius: float, start_z: wp.array(dtype=float),
              upright: float, airborne: float, end_of_decision: int, start: int,
              outcome: wp.array(dtype=int), ctrl: wp.array2d(dtype=float)):  # fmt: skip
        # The task's _check_outcome (and, at the end of a decision, after_step's divergence check):
        # 1 target, 2 collision, 4 physics error, as sim.task.Outcome. A decided world's wheels stop.
        w = wp.tid()
        if outcome[w] != 0:
            return
        p = xpos[w, base]
        diverged = xmat[w, base][2, 2] < upright or wp.abs(p[2] - start_z[w]) > airborne
        for j in range(qpos.shape[1]):
            if not wp.isfinite(qpos[w, j]):
                diverged = True
        dx = target[w][0] - p[0]
        dy = target[w][1] - p[1]
        arrived = wp.sqrt(dx * dx + dy * dy) <= radius
        decided = 0
        if touched[w] != 0 or arrived:
            if diverged:
                decided = 4
            elif touched[w] != 0:
                decided = 2
            else:
                decided = 1
        elif end_of_decision != 0 and diverged:
            decided = 4
        if decided != 0:
            outcome[w] = decided
            for j in range(3):
                ctrl[w, start + j] = 0.0

    @wp.kernel
    def hold(outcome: wp.array(dtype=int), held: wp.array(dtype=int), qpos: wp.array2d(dtype=float),
             qvel: wp.array2d(dtype=float), kept_qpos: wp.array2d(dtype=float),
             kept_qvel: wp.array2d(dtype=float)):  # fmt: skip
        # After each physics step: a world without a running episode keeps the state of its first step
        # with stopped wheels (the task's last step of a decided episode), restored after every later
        # one. So its final observation is the task's, and it never rests long enough to go NaN.
        w = wp.tid()
        if outcome[w] == 0:
            return
        if held[w] == 0:
            for j in range(qpos.shape[1]):
                kept_qpos[w, j] = qpos[w, j]
            for j in range(qvel.shape[1]):
                kept_qvel[w, j] = qvel[w, j]
            held[w] = 1
        else:
            for j in range(qpos.shape[1]):
                qpos[w, j] = kept_qpos[w, j]
            for j in range(qvel.shape[1]):
                qvel[w, j] = kept_qvel[w, j]

    return _Kernels(command, touches, judge, hold)


class _TwistDrives:
    """:class:`~nirl_mj.sim.drive.BatchDriveController`'s counterpart for continuous actions: one
    :class:`~nirl_mj.sim.drive.DriveController` per world (a twist seldom repeats: nothing to
    share), each twist checked as the task checks it."""

    def __init__(self, n: int, spec: TaskSpec, convert: Callable[[np.ndarray], np.ndarray] | None) -> None:
        self._drives = [DriveController() for _ in range(n)]
        self._bounds, self._control, self._convert = continuous_action_spec(spec), spec.control, convert

    def reset(self, worlds: Sequence[int]) -> None:
        """The worlds' last commands back to zero (an episode's start)."""
        for w in worlds:
            self._drives[w].reset()

    def plan(self, worlds: np.ndarray, actions: Sequence[Any], out: np.ndarray) -> None:
        """Writes world ``w``'s commands for its twist ``actions[w]`` (forward m/s, yaw rate rad/s)
        into ``out[:, w]`` (n_cmd, N, 3), for every ``w`` in ``worlds``."""
        c = self._control
        for w in worlds.tolist():
            twist = checked_twist(actions[w], self._bounds)
            plan = self._drives[w].plan_twist(twist, c.decision_period, c.command_period, c.max_accel)
            out[:, w] = self._convert(plan) if self._convert else plan
