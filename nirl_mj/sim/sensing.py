"""Range sensing: the nine infrared cones as MuJoCo rays, and the target's visibility.

Each sensor S_i covers a 40-degree cone centred on its direction and is sampled
by ``rays_per_sensor`` horizontal rays at the centres of equal sub-cones (for 5
rays: -16, -8, 0, 8, 16 degrees). All rays, plus one towards the target, are
cast in a single ``mj_multiRay`` call from the robot's centre at sensor height;
they see only geom group 0 (the world), so the robot never sees itself. A
reading is the clearance from the robot's outline: hit distance minus the body
radius.
"""

from __future__ import annotations

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
    sensor-major (the rays of S1 first)."""
    k = rays_per_sensor
    offsets = ((np.arange(k) + 0.5) / k - 0.5) * features.SECTOR_WIDTH
    return (features.SENSOR_ANGLES[:, None] + offsets[None, :]).ravel()


class RangeSensors:
    """Casts the sensor rays for one compiled model.

    ``wall_mask`` (ngeom,) marks the geoms that are walls; ``sensing_range`` is
    measured from the robot's outline of radius ``body_radius`` (metres).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        wall_mask: np.ndarray,
        rays_per_sensor: int,
        sensing_range: float,
        body_radius: float,
    ) -> None:
        self._model = model
        self._wall_mask = np.asarray(wall_mask, dtype=bool)
        self._k = rays_per_sensor
        self._range = sensing_range
        self._body_radius = body_radius
        self._angles = ray_angles(rays_per_sensor)
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
        rays = np.where(self._geomid[:n] >= 0, self._dist[:n] - self._body_radius, np.inf)
        rays = np.where(rays < self._range, np.maximum(rays, 0.0), np.inf)
        dist = rays.reshape(features.N_SENSORS, self._k)
        nearest = np.argmin(dist, axis=1)
        rows = np.arange(features.N_SENSORS)
        ranges = dist[rows, nearest]
        hit = np.isfinite(ranges)
        nearest_geom = self._geomid[:n].reshape(features.N_SENSORS, self._k)[rows, nearest]
        wall = hit & self._wall_mask[np.maximum(nearest_geom, 0)]
        blocked = self._geomid[n] >= 0 and self._dist[n] < target_distance
        visible = target_distance - self._body_radius <= self._range and not blocked
        bearing = float(np.arctan2(to_target[1], to_target[0]) - yaw)
        return Scan(ranges, rays, wall, bearing, target_distance, bool(visible))
