"""Range sensing: the nine infrared cones as MuJoCo rays, and the target's visibility.

Each sensor S_i covers a 40-degree cone centred on its direction and is sampled
by ``rays_per_sensor`` horizontal rays at the centres of equal sub-cones (for 5
rays: -16, -8, 0, 8, 16 degrees). All rays, plus one towards the target, are
cast in a single ``mj_multiRay`` call from the robot's centre at sensor height;
they see only geom group 0 (the world), so the robot never sees itself. A
reading is the clearance from the robot's outline: hit distance minus the body
radius, at least 0.

The robot model also carries the nine sensors as MJCF rangefinders
(``models/robotino/robotino.xml``: ``<rangefinder camera="S<i>_cone">``, one
camera per sensor whose image is one row of ``rays_per_sensor`` pixels spanning
the cone), so the model on its own has them (viewer, ``MjData.sensordata``).
The task does not read them, by measurement (docs/TASKS.md, "Range sensing"):

- MuJoCo computes them at every physics step: a step takes 84 us with them,
  11 us without (20 obstacles; ~4x fewer decisions/s); even once per decision
  they cost ~2-3x the ``mj_multiRay`` scan (a rangefinder casts without a
  cutoff and without the group filter);
- a rangefinder reports no geom id (the wall flags) and casts no target ray;
- a camera is a pinhole, so its rays pass through equally spaced pixel centres
  and are spaced equally in tangent, not in angle (for 5 rays -16.23, -8.28, 0,
  8.28, 16.23 degrees, :func:`camera_ray_angles`): no image row gives the
  equal sub-cones above, so reading them would change today's readings.

So the task compiles them with sensors disabled (physics steps skip them) and
:class:`Rangefinders` computes them on demand. With the same ray directions
(``RangeSensors(..., angles=camera_ray_angles(k))``) the two agree ray for ray
(tests/test_sensing.py). The cameras sit on the robot's vertical axis above the
wheels and below the lowest obstacle a task allows: a rangefinder ignores only
its own body and transparent geoms, and from the centre at sensor height the
rays cross the wheels (other bodies); walls and obstacles are vertical prisms,
so a horizontal ray meets them at the same distance at either height.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from nirl_mj.data import features

_WORLD_ONLY = np.array([1, 0, 0, 0, 0, 0], dtype=np.uint8)


@dataclass(frozen=True)
class Scan:
    """One reading of all sensors.

    ``ranges`` (9,) clearance in metres, ``inf`` where nothing is within range;
    ``rays`` (9 * rays_per_sensor,) the same for every ray, sensor-major;
    ``wall`` (9,) bool, the nearest hit of that sensor is a wall; ``bearing`` of
    the target in radians counter-clockwise from the front; ``target_distance``
    in metres from the robot's centre; ``target_visible`` the target is within
    sensing range and in line of sight.
    """

    ranges: np.ndarray
    rays: np.ndarray
    wall: np.ndarray
    bearing: float
    target_distance: float
    target_visible: bool


def ray_angles(rays_per_sensor: int) -> np.ndarray:
    """Ray directions relative to the robot's front, radians, shape (9 * rays_per_sensor,),
    sensor-major (the rays of S1 first), clockwise first within a sensor."""
    k = rays_per_sensor
    offsets = ((np.arange(k) + 0.5) / k - 0.5) * features.SECTOR_WIDTH
    return (features.SENSOR_ANGLES[:, None] + offsets[None, :]).ravel()


def camera_ray_angles(rays_per_sensor: int) -> np.ndarray:
    """Ray directions of the MJCF rangefinder cameras relative to the robot's front, radians,
    shape (9 * rays_per_sensor,), in :func:`ray_angles`' order: through the centres of
    ``rays_per_sensor`` equal pixels across an image plane that spans the 40-degree cone."""
    k = rays_per_sensor
    pixels = 2.0 * (np.arange(k) + 0.5) / k - 1.0  # pixel centres, -1..1 across the image
    offsets = np.arctan(pixels * math.tan(features.SECTOR_WIDTH / 2))
    return (features.SENSOR_ANGLES[:, None] + offsets[None, :]).ravel()


def cone_fovy(rays_per_sensor: int) -> float:
    """Vertical field of view in degrees (MJCF ``fovy``) of a camera with a one-row image of
    ``rays_per_sensor`` square pixels whose width spans the 40-degree cone."""
    return math.degrees(2.0 * math.atan(math.tan(features.SECTOR_WIDTH / 2) / rays_per_sensor))


def _clearance(dist: np.ndarray, hit: np.ndarray, body_radius: float, sensing_range: float) -> np.ndarray:
    """Clearance from the robot's outline (metres) of rays from its centre that hit at ``dist``
    (metres) where ``hit``; ``inf`` for a miss or beyond ``sensing_range``."""
    rays = np.where(hit, dist - body_radius, np.inf)
    return np.where(rays < sensing_range, np.maximum(rays, 0.0), np.inf)


def sensor_readings(
    dist: np.ndarray,
    geomid: np.ndarray,
    wall_mask: np.ndarray,
    rays_per_sensor: int,
    sensing_range: float,
    body_radius: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nine sensors' readings from their rays' hits: ``dist`` (..., 9 * rays_per_sensor) metres
    from the robot's centre and ``geomid`` (same shape, -1 for a miss) -> ``(ranges (..., 9), rays
    (..., 9 * rays_per_sensor), wall (..., 9))`` as :class:`Scan` holds them. Any leading batch
    shape: one robot (:class:`RangeSensors`) or many worlds (:mod:`nirl_mj.sim.warp_worlds`)."""
    rays = _clearance(dist, geomid >= 0, body_radius, sensing_range)
    batch = rays.shape[:-1]
    per_sensor = rays.reshape(*batch, features.N_SENSORS, rays_per_sensor)
    nearest = np.argmin(per_sensor, axis=-1)[..., None]
    ranges = np.take_along_axis(per_sensor, nearest, axis=-1)[..., 0]
    nearest_geom = np.take_along_axis(
        np.asarray(geomid).reshape(*batch, features.N_SENSORS, rays_per_sensor), nearest, axis=-1
    )[..., 0]
    wall = np.isfinite(ranges) & np.asarray(wall_mask, dtype=bool)[np.maximum(nearest_geom, 0)]
    return ranges, rays, wall


def target_sight(
    hit: np.ndarray | bool,
    dist: np.ndarray | float,
    target_distance: np.ndarray | float,
    body_radius: float,
    sensing_range: float,
) -> np.ndarray | bool:
    """Whether the target is seen: within ``sensing_range`` of the robot's outline (``target_distance``
    metres from its centre), and the ray towards it hits nothing (``hit``) nearer than the target
    (``dist`` metres). Scalars or arrays of any batch shape alike."""
    blocked = np.logical_and(hit, dist < target_distance)
    return np.logical_and(target_distance - body_radius <= sensing_range, np.logical_not(blocked))


class RangeSensors:
    """Casts the sensor rays for one compiled model.

    ``wall_mask`` (ngeom,) marks the geoms that are walls; ``sensing_range`` is
    measured from the robot's outline of radius ``body_radius`` (metres).
    ``angles`` (9 * rays_per_sensor,) radians replaces :func:`ray_angles`, e.g. with
    :func:`camera_ray_angles` to cast the MJCF rangefinders' rays.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        wall_mask: np.ndarray,
        rays_per_sensor: int,
        sensing_range: float,
        body_radius: float,
        angles: np.ndarray | None = None,
    ) -> None:
        self._model = model
        self._wall_mask = np.asarray(wall_mask, dtype=bool)
        self._k = rays_per_sensor
        self._range = sensing_range
        self._body_radius = body_radius
        self._angles = ray_angles(rays_per_sensor) if angles is None else np.asarray(angles, dtype=float)
        if self._angles.shape != (features.N_SENSORS * rays_per_sensor,):
            raise ValueError(
                f"angles: shape {self._angles.shape}, expected ({features.N_SENSORS * rays_per_sensor},)"
            )
        n = self._angles.size + 1  # the last ray points at the target
        self._vec = np.zeros((n, 3))
        self._geomid = np.empty(n, dtype=np.int32)
        self._dist = np.empty(n)
        self._cutoff = sensing_range + body_radius

    def scan(self, data: mujoco.MjData, origin: np.ndarray, yaw: float, target: np.ndarray) -> Scan:
        """Reads the sensors from ``origin`` (3,) world metres with heading ``yaw`` (radians)
        towards ``target`` (2,) world metres. Geometry must be current (``mj_kinematics``)."""
        n = self._angles.size
        world = self._angles + yaw
        self._vec[:n, 0] = np.cos(world)
        self._vec[:n, 1] = np.sin(world)
        to_target = np.asarray(target, dtype=np.float64) - origin[:2]
        target_distance = float(np.hypot(to_target[0], to_target[1]))
        self._vec[n, :2] = to_target / max(target_distance, 1e-9)
        mujoco.mj_multiRay(
            self._model,
            data,
            origin,
            self._vec.ravel(),
            _WORLD_ONLY,
            1,
            -1,
            self._geomid,
            self._dist,
            None,
            n + 1,
            self._cutoff,
        )
        ranges, rays, wall = sensor_readings(
            self._dist[:n], self._geomid[:n], self._wall_mask, self._k, self._range, self._body_radius
        )
        visible = target_sight(
            self._geomid[n] >= 0, self._dist[n], target_distance, self._body_radius, self._range
        )
        bearing = float(np.arctan2(to_target[1], to_target[0]) - yaw)
        return Scan(ranges, rays, wall, bearing, target_distance, bool(visible))


class Rangefinders:
    """Reads the robot's nine MJCF rangefinders on demand, as clearances like :class:`RangeSensors`.

    ``sensor_ids`` (9,) are the rangefinders S1..S9 of ``model``, each attached to a camera on
    the robot's vertical axis (so a ray's distance from the camera is its distance from the
    robot's centre); ``sensing_range`` and ``body_radius`` in metres as for :class:`RangeSensors`.
    A model may compile them with sensors disabled (the task does, so physics steps skip them):
    :meth:`read` computes them anyway.
    """

    def __init__(
        self, model: mujoco.MjModel, sensor_ids: np.ndarray, sensing_range: float, body_radius: float
    ) -> None:
        ids = np.asarray(sensor_ids, dtype=int)
        if ids.shape != (features.N_SENSORS,):
            raise ValueError(f"sensor_ids: shape {ids.shape}, expected ({features.N_SENSORS},)")
        if np.any(model.sensor_type[ids] != mujoco.mjtSensor.mjSENS_RANGEFINDER) or np.any(
            model.sensor_objtype[ids] != mujoco.mjtObj.mjOBJ_CAMERA
        ):
            raise ValueError("sensor_ids: every sensor must be a camera-attached rangefinder")
        cameras = model.sensor_objid[ids]
        if np.any(model.cam_pos[cameras, :2] != 0.0):
            raise ValueError("rangefinder cameras must sit on the robot's vertical axis (pos x = y = 0)")
        self._model = model
        adr, dim = model.sensor_adr[ids], model.sensor_dim[ids]
        self._index = np.concatenate([np.arange(a, a + k) for a, k in zip(adr, dim, strict=True)])
        self._range = sensing_range
        self._body_radius = body_radius

    def read(self, data: mujoco.MjData) -> np.ndarray:
        """Clearance of every ray in metres, ``inf`` where nothing is within range, shape
        (sum of the cameras' pixels,), sensor-major in :func:`camera_ray_angles`' order.
        Geometry must be current (``mj_kinematics``); writes ``data.sensordata``."""
        opt = self._model.opt
        flags = opt.disableflags
        opt.disableflags = flags & ~int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
        try:
            mujoco.mj_sensorPos(self._model, data)
        finally:
            opt.disableflags = flags
        dist = data.sensordata[self._index]
        return _clearance(dist, dist >= 0.0, self._body_radius, self._range)
