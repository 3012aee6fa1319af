"""LiDAR simulation: scan patterns, ray casting per point at the point's own time, noise.

A sweep lasts ``1 / rate_hz`` seconds and the rig moves meanwhile: every point is cast from the
sensor pose at its own time (to within 0.05 ms) and reported in the sensor frame of that time, as
a real LiDAR does, so a scan is skewed by the motion and deskewing matters.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from rig.errors import InputError
from rig.sim.motion import Motion
from rig.sim.world import World

LidarKind = Literal["mid360", "rosette", "spinning", "velodyne64", "velodyne32"]
#: Spinning LiDARs: beams, lowest and highest beam elevation (degrees), columns per turn.
SPINNING = {
    "spinning": (32, -22.5, 22.5, 1024),  # Ouster OS1-32-like
    "velodyne64": (64, -24.8, 2.0, 1024),  # HDL-64E's field (KITTI); half its columns at 10 Hz
    "velodyne32": (32, -30.0, 10.0, 1024),  # HDL-32E-like
}
LIDAR_KINDS: tuple[str, ...] = ("mid360", "rosette", *SPINNING)
# Mid-360-like vertical field of view (degrees).
_MID360_ELEVATION_DEG = (-7.0, 52.0)
#: Time step of the sensor poses a sweep's points are cast from (s).
POSE_STEP_S = 1e-4
#: Points whose ray meets the surface at a cosine below this are lost (grazing incidence).
MIN_COS_RETURN = 0.05


@dataclass(frozen=True)
class LidarModel:
    """Scan pattern and error model of a simulated LiDAR (frame: x forward, y left, z up).

    Attributes:
        kind: ``mid360`` (Livox Mid-360-like: non-repetitive, 360° around, -7° to 52° up; the
            default, as on most small robots), ``rosette`` (Livox Avia-like: two Risley prisms,
            non-repetitive, 70° circular field of view) or a spinning one (:data:`SPINNING`):
            ``spinning`` (Ouster OS1-32-like: 32 beams over ±22.5°), ``velodyne64`` (64 beams from
            -24.8° to +2°, as on KITTI's car) or ``velodyne32`` (32 beams from -30° to +10°).
        rate_hz: sweeps per second.
        points_per_scan: rays per sweep of the rosette (the spinning pattern has beams × columns).
        range_noise_m: standard deviation of the Gaussian range noise.
        dropout: probability that a return is lost.
        min_range_m, max_range_m: returns outside these ranges are lost.
    """

    kind: LidarKind = "mid360"
    rate_hz: float = 10.0
    points_per_scan: int = 20000
    range_noise_m: float = 0.015
    dropout: float = 0.02
    min_range_m: float = 0.1
    max_range_m: float = 40.0

    def __post_init__(self) -> None:
        if self.kind not in LIDAR_KINDS:
            raise InputError(
                f"unknown LiDAR {self.kind!r}; expected one of {', '.join(LIDAR_KINDS)}", field="lidar"
            )
        if self.range_noise_m < 0 or not 0 <= self.dropout < 1 or self.points_per_scan < 1:
            raise InputError(
                "need range noise >= 0, 0 <= dropout < 1 and points per scan >= 1", field="lidar"
            )

    @property
    def period_s(self) -> float:
        return 1.0 / self.rate_hz

    def pattern(self, t_start_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Unit ray directions ``(N, 3)`` and times ``(N,)`` in seconds after ``t_start_s`` of a sweep.

        The non-repetitive patterns follow absolute time, so consecutive sweeps cover different
        directions.
        """
        if self.kind == "mid360":
            step = self.period_s / self.points_per_scan
            t = np.arange(self.points_per_scan) * step
            # One turn of the mirror per sweep; elevations from a low-discrepancy sequence indexed by
            # absolute time, so that sweeps interleave instead of repeating.
            k = np.rint((t_start_s + t) / step).astype(np.int64)
            low, high = np.deg2rad(_MID360_ELEVATION_DEG)
            elevation = low + (high - low) * np.mod(k * 0.7548776662466927, 1.0)
            azimuth = 2 * np.pi * (t / self.period_s + np.mod(k * 0.5698402909980532, 1.0) / 360.0)
            dirs = np.column_stack(
                [np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)]
            )
            return dirs, t
        if self.kind == "rosette":
            t = np.arange(self.points_per_scan) * (self.period_s / self.points_per_scan)
            tau = t_start_s + t
            half_fov = np.deg2rad(35.2)
            # Counter-rotating prisms: a petal every 1/(f1 + f2) s, each turned by the golden angle
            # from the last (f1 / (f1 + f2) = 0.382), so petals never repeat and fill the field.
            w1, w2 = 2 * np.pi * 983.9, -2 * np.pi * 1592.1
            a = half_fov / 2 * (np.cos(w1 * tau) + np.cos(w2 * tau))
            b = half_fov / 2 * (np.sin(w1 * tau) + np.sin(w2 * tau))
            polar, azimuth = np.hypot(a, b), np.arctan2(b, a)
            dirs = np.column_stack(
                [np.cos(polar), np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth)]
            )
            return dirs, t
        beams, low, high, columns = SPINNING[self.kind]
        elevation = np.deg2rad(np.linspace(low, high, beams))
        column = np.repeat(np.arange(columns), beams)
        azimuth = -2 * np.pi * column / columns  # clockwise seen from above, as Ouster spins
        el = np.tile(elevation, columns)
        dirs = np.column_stack([np.cos(el) * np.cos(azimuth), np.cos(el) * np.sin(azimuth), np.sin(el)])
        return dirs, column * (self.period_s / columns)


@dataclass
class SimulatedScan:
    """One simulated sweep.

    Attributes:
        points: ``(N, 3)`` measured points in the LiDAR frame at each point's time.
        time_s: ``(N,)`` seconds after the sweep start.
        intensity: ``(N,)`` float32 return intensity in [0, 255].
        world_points: ``(N, 3)`` the true surface points hit (before range noise).
    """

    points: np.ndarray
    time_s: np.ndarray
    intensity: np.ndarray
    world_points: np.ndarray


def simulate_scan(
    world: World,
    motion: Motion,
    lidar: LidarModel,
    T_cam_lidar: np.ndarray,
    t_start_s: float,
    rng: np.random.Generator,
) -> SimulatedScan:
    """Sweep of ``lidar`` mounted at ``T_cam_lidar`` ``(4, 4)`` starting at ``t_start_s`` (s)."""
    dirs, t = lidar.pattern(t_start_s)
    # Sensor poses on a fine grid; each point takes the pose nearest its time (within POSE_STEP_S / 2).
    grid = np.minimum(
        t_start_s + np.arange(0.0, lidar.period_s + POSE_STEP_S, POSE_STEP_S), motion.duration_s
    )
    poses = motion.poses(grid, T_cam_lidar)[np.rint(t / POSE_STEP_S).astype(np.int64)]
    world_dirs = np.einsum("nij,nj->ni", poses[:, :3, :3], dirs)
    hits = world.raycaster.cast(poses[:, :3, 3], world_dirs, t_start_s + t)
    cos = np.abs(np.einsum("ij,ij->i", np.nan_to_num(hits.normal), world_dirs))
    keep = (
        hits.hit
        & (hits.distance >= lidar.min_range_m)
        & (hits.distance <= lidar.max_range_m)
        & (cos >= MIN_COS_RETURN)
        & (rng.random(len(t)) >= lidar.dropout)
    )
    hits = hits.subset(keep)
    measured = hits.distance + lidar.range_noise_m * rng.standard_normal(len(hits.distance))
    reflect = world.appearance.reflectivity(hits)
    intensity = np.clip(255.0 * reflect * np.sqrt(cos[keep]), 0.0, 255.0).astype(np.float32)
    return SimulatedScan(dirs[keep] * measured[:, None], t[keep], intensity, hits.points)
