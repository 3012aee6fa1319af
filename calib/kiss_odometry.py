"""KISS-ICP odometry for the time-offset calibration's LiDAR motion.

The fallback mapper registers with :class:`rig.lidar_odometry.SweepOdometry` (VGICP), which is far
more accurate on a 64-beam street. The time offset needs something else: *when* each pose holds.
Its poses are stamped at :func:`rig.lidar_odometry.sweep_information`'s time, a model of
point-to-surface ICP on a skewed sweep, and KISS-ICP's point-to-point registration follows that
model where VGICP does not: on the virtual room (seed 0, true offset 15.0 ms, the mean of a run
forward and one backward in time, see :func:`calib.motion.lidar_angular_velocity`) KISS-ICP gives
15.4 ms and VGICP 12.1 ms (forward 11.2, backward 13.1), whatever the map voxel (12.3–12.8 ms)
or the sweep thinning (12.9 ms), and with its jackknife spread of 1.4 ms it would claim ``ok``.
"""

from __future__ import annotations

import numpy as np

from rig.lidar_odometry import ODOMETRY_THREADS, SweepInformation, sweep_information

#: Map points kept per voxel (KISS-ICP's default is 20): only the motion between sweeps is needed.
#: On the virtual rig's 20 s room session (0.1 m voxels) the odometry over 200 sweeps took 16–17 s
#: instead of 20–57 s (shared 2 cores).
POINTS_PER_VOXEL = 3


class KissOdometry:
    """KISS-ICP odometry (de-skew off, :data:`POINTS_PER_VOXEL`) fed one sweep at a time.

    Args:
        voxel_size: KISS-ICP voxel size in metres.
        max_range: points farther (m) are ignored by KISS-ICP.
    """

    def __init__(self, voxel_size: float, max_range: float) -> None:
        from kiss_icp.config import KISSConfig
        from kiss_icp.kiss_icp import KissICP

        config = KISSConfig()
        config.data.max_range = max_range
        config.data.min_range = 0.0
        config.data.deskew = False
        config.mapping.voxel_size = voxel_size
        config.mapping.max_points_per_voxel = POINTS_PER_VOXEL
        # One thread, as for the mapper's odometry: parallel reductions make the poses differ in
        # the last bits from run to run. KISS-ICP's C++ sets the thread limit once per process.
        config.registration.max_num_threads = ODOMETRY_THREADS
        self._icp = KissICP(config)

    def register(self, points: np.ndarray, point_time_s: np.ndarray) -> tuple[np.ndarray, SweepInformation]:
        """Register a sweep's raw points ``(N, 3)`` float64 (times ``(N,)`` s from the sweep
        stamp); returns the pose ``T_world_lidar`` ``(4, 4)`` (world: the first sweep's frame) and
        its :func:`~rig.lidar_odometry.sweep_information`."""
        _, source = self._icp.register_frame(points, np.zeros(0))
        return self._icp.last_pose.copy(), sweep_information(np.asarray(source), points, point_time_s)
