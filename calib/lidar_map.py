"""The LiDAR map of a whole recording, for the multi-frame extrinsic: where the LiDAR was at every
moment, and the points of all its sweeps in one world frame.

The sweeps are registered as the fallback mapper registers them
(:func:`rig.sweep_registration.registered_sweeps`: odometry on the raw sweeps, then the
de-skewed static points again), the points of moving things (that other sweeps see through,
:mod:`rig.dynamic_points`) set apart, and the rest merged, one point per voxel. Calibration cannot
wait for the mapper (it runs before it, and ``rig`` → ``calib`` → ``slam_bridge``), but the
registration, the thinning and the test for moving points are the same code.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rig.errors import InputError
from rig.lidar_odometry import thinned
from rig.messages import Scan
from rig.sweep_registration import RegistrationLog, SweepSettings, registered_sweeps
from rig.trajectory import Trajectory
from rig.transforms import transform_points

#: The map keeps one point per voxel of this fraction of the odometry voxel (3.3 cm in the
#: virtual room, 12 cm on the 64-beam street), then at most MAP_POINTS of them, spread evenly.
MAP_VOXEL_PER_ODOMETRY_VOXEL = 1 / 3
MAP_POINTS = 120_000
#: The moving points that hide the map in a camera frame are those measured this close to it
#: (half a sweep: a car crossing at 6 m/s moves 30 cm in that time).
MOVING_WINDOW_S = 0.05


@dataclass(eq=False)
class LidarMap:
    """A recording's LiDAR trajectory and merged point map.

    Attributes:
        trajectory: poses ``T_world_lidar`` on the LiDAR's host clock (world: the first sweep).
        points: ``(N, 3)`` float64 map points of what stood still, in the world frame.
        moving_points: ``(M, 3)`` float64 world points of moving things, where each was when
            measured, in time order.
        moving_t_ns: ``(M,)`` int64 their times (host clock).
    """

    trajectory: Trajectory
    points: np.ndarray
    moving_points: np.ndarray
    moving_t_ns: np.ndarray

    def moving_near(self, t_ns: int, window_s: float = MOVING_WINDOW_S) -> np.ndarray:
        """``(K, 3)`` the world points of moving things measured within ``window_s`` of ``t_ns``."""
        window = round(window_s * 1e9)
        start, stop = np.searchsorted(self.moving_t_ns, (t_ns - window, t_ns + window + 1))
        return self.moving_points[start:stop]


def build_lidar_map(scans: Sequence[Scan]) -> LidarMap:
    """Register every sweep (in time order) and merge them de-skewed into one map. Raises
    :class:`~rig.errors.InputError` with fewer than 2 usable sweeps."""
    log = RegistrationLog()
    poses, still, moving, moving_t_ns = [], [], [], []
    for sweep in registered_sweeps(scans, SweepSettings(), log):
        map_voxel = log.voxel_m * MAP_VOXEL_PER_ODOMETRY_VOXEL
        world = transform_points(sweep.pose, sweep.points)
        kept = world[~sweep.dynamic]
        still.append(kept[_one_per_voxel(kept, map_voxel)])
        moving.append(world[sweep.dynamic])
        moving_t_ns.append(sweep.point_t_ns[sweep.dynamic])
        poses.append(sweep.pose)
    if len(poses) < 2:
        raise InputError(f"only {len(log.poses)} usable LiDAR sweeps; the LiDAR map needs 2", field="scans")
    trajectory = Trajectory.from_poses(np.array(log.t_ns, dtype=np.int64), np.stack(poses))
    points = np.vstack(still)
    points = points[_one_per_voxel(points, map_voxel)]
    moving_t = np.concatenate(moving_t_ns)
    order = np.argsort(moving_t, kind="stable")
    return LidarMap(
        trajectory, points[thinned(len(points), MAP_POINTS)], np.vstack(moving)[order], moving_t[order]
    )


def _one_per_voxel(points: np.ndarray, voxel: float) -> np.ndarray:
    """Sorted indices ``(V,)`` of the first of ``points`` ``(N, 3)`` in each occupied voxel.

    A measured point, not the voxel's mean (small_gicp's and open3d's down-sampling): a mean
    over a voxel that straddles an edge (a kerb, a corner, a post against a wall) floats off both
    surfaces, and edges are what the photo-consistency sees. On the virtual street, whose boxes
    are aligned with the world axes, means made the cost at the true extrinsic depend on how the
    voxel grid fell: 0.0062 with the street's axes, 0.0114 with the first sweep's (0.0068 and
    0.0096 with measured points)."""
    keys = np.floor(points / voxel).astype(np.int64)
    keys -= keys.min(axis=0)
    span = keys.max(axis=0) + 1
    flat = (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]
    return np.sort(np.unique(flat, return_index=True)[1])
