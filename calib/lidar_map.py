"""The LiDAR map of a whole recording, for the multi-frame extrinsic: where the LiDAR was at every
moment, and the points of all its sweeps in one world frame.

The trajectory is the fallback mapper's odometry (scan-to-map VGICP on the raw sweeps, each pose
stamped when it holds, :class:`rig.lidar_odometry.SweepOdometry`); the sweeps are then de-skewed
with it and merged, one point per voxel. Calibration cannot wait for the mapper (it runs before
it, and ``rig`` → ``calib`` → ``slam_bridge``), but the odometry and the thinning are the same
code.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rig.deskew import deskewed_points
from rig.errors import InputError
from rig.lidar_odometry import SweepOdometry, thinned, usable_sweep, voxel_for_ranges
from rig.messages import Scan
from rig.trajectory import Trajectory

#: Sweeps are thinned to this many points before anything else (the mapper's default).
POINTS_PER_SWEEP = 32_000
MIN_RANGE_M = 0.2
MAX_RANGE_M = 60.0
#: The map keeps one point per voxel of this fraction of the odometry voxel (3.3 cm in the
#: virtual room, 12 cm on the 64-beam street), then at most MAP_POINTS of them, spread evenly.
MAP_VOXEL_PER_ODOMETRY_VOXEL = 1 / 3
MAP_POINTS = 120_000


@dataclass(eq=False)
class LidarMap:
    """A recording's LiDAR trajectory and merged point map.

    Attributes:
        trajectory: poses ``T_world_lidar`` on the LiDAR's host clock (world: the first sweep).
        points: ``(N, 3)`` float64 map points in the world frame.
    """

    trajectory: Trajectory
    points: np.ndarray


def build_lidar_map(scans: Sequence[Scan]) -> LidarMap:
    """Register every sweep (in time order), then merge them de-skewed into one map. Raises
    :class:`~rig.errors.InputError` with fewer than 2 usable sweeps."""
    used = [
        (scan, sweep[:2])
        for scan in scans
        if (sweep := usable_sweep(scan.points, scan.point_time_s, POINTS_PER_SWEEP, MIN_RANGE_M, MAX_RANGE_M))
        is not None
    ]
    if len(used) < 2:
        raise InputError(f"only {len(used)} usable LiDAR sweeps; the LiDAR map needs 2", field="scans")
    voxel = voxel_for_ranges(np.linalg.norm(used[0][1][0], axis=1))
    odometry = SweepOdometry(voxel, MAX_RANGE_M, MIN_RANGE_M)
    t_ns, poses = [], []
    for scan, (points, times) in used:
        pose, information = odometry.register(points, times)
        t_ns.append(int(scan.t_host) + round(information.held_s * 1e9))
        poses.append(pose)
    trajectory = Trajectory.from_poses(np.array(t_ns, dtype=np.int64), np.stack(poses))

    import small_gicp

    merged = []
    for scan, (points, times) in used:
        point_t_ns = int(scan.t_host) + np.round(times * 1e9).astype(np.int64)
        world = deskewed_points(points, point_t_ns, trajectory)
        # One thread: with more, the points come out in a thread-dependent order.
        merged.append(
            small_gicp.voxelgrid_sampling(
                world, voxel * MAP_VOXEL_PER_ODOMETRY_VOXEL, num_threads=1
            ).points()[:, :3]
        )
    cloud = small_gicp.voxelgrid_sampling(
        np.vstack(merged), voxel * MAP_VOXEL_PER_ODOMETRY_VOXEL, num_threads=1
    )
    points = np.asarray(cloud.points()[:, :3], dtype=np.float64)
    return LidarMap(trajectory, points[thinned(len(points), MAP_POINTS)])
