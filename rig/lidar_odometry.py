"""LiDAR odometry with KISS-ICP on raw (not de-skewed) sweeps, each pose stamped when it holds.

Used by the time-offset calibration (the LiDAR clock's motion) and the fallback mapper. KISS-ICP's
own de-skew is left off: it moves each point to the sweep's last point (versions 1.x) with the
previous sweep's motion, which is wrong for a rig that pitches and rolls at a few Hz. On the
virtual rig's room it made the roll and pitch rates lag the truth by 110–130 ms (yaw by 5 ms) and
left the mapper's roll and pitch 0.40° / 0.32° rms off the truth (0.07° / 0.05° without). The pose
of a sweep left skewed holds at the time :func:`sweep_information` finds (~12 ms before the sweep
middle there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

#: Neighbours of a point that give its surface normal (for :func:`sweep_information`).
NORMAL_NEIGHBOURS = 10
#: Source points whose times :func:`sweep_information` averages.
INFORMATION_SAMPLES = 1000
#: Map points kept per voxel (KISS-ICP's default is 20): only the motion between sweeps is needed.
#: On the virtual rig's 20 s room session (0.1 m voxels) the time-offset odometry over 200 sweeps
#: took 16–17 s instead of 20–57 s (shared 2 cores), and the mapper's roll / pitch / yaw went from
#: 0.15 / 0.08 / 0.23° to 0.12 / 0.07 / 0.14° rms, ATE 1.04 to 0.86 cm, its odometry 48 to 20 s.
#: 3 instead of 5 (200 sweeps, 0.1 m voxels, one registration pass): room ATE 0.86 -> 0.83 cm,
#: corridor 0.98 -> 0.81 cm, registration 39 % less time.
ODOMETRY_POINTS_PER_VOXEL = 3


@dataclass(frozen=True)
class SweepInformation:
    """What a registered sweep's geometry says about its pose.

    Attributes:
        held_s: when the pose holds, s from the sweep stamp (:func:`sweep_information`).
        translation_information: ``(3,)`` eigenvalues (ascending, summing to 1) of the mean ``n nᵀ``
            of the surface normals: how well the surfaces pin down translation along each of
            their principal directions (a long corridor or an open road leaves one near 0).
        weakest_direction: ``(3,)`` unit vector (sensor frame) of the smallest of them.
    """

    held_s: float
    translation_information: np.ndarray
    weakest_direction: np.ndarray


def sweep_information(source: np.ndarray, points: np.ndarray, times: np.ndarray) -> SweepInformation:
    """When the ICP pose of a sweep that was not de-skewed holds, and how well its surfaces
    constrain translation.

    The time is that of ``points`` ``(N, 3)`` (times ``(N,)``) averaged over the registered subset
    ``source`` ``(M, 3)`` (each matched to its nearest point of ``points``), each weighted by its
    rotational information ``|p × n|²`` (``n``: the local surface normal). At most
    :data:`INFORMATION_SAMPLES` source points (evenly strided) are used: a weighted mean time needs
    no more, and the normals of all of them cost more than the registration itself on a 64-beam
    sweep."""
    if len(source) == 0 or len(points) < NORMAL_NEIGHBOURS:  # too few points for normals
        return SweepInformation(float(np.mean(times)), np.zeros(3), np.array([1.0, 0.0, 0.0]))
    source = source[:: -(-len(source) // INFORMATION_SAMPLES)]
    # An unbalanced tree builds in half the time and answers these few queries as fast.
    tree = cKDTree(points, balanced_tree=False, compact_nodes=False)
    rows = tree.query(source)[1]
    p = points[rows]
    _, neighbours = tree.query(p, k=NORMAL_NEIGHBOURS)
    local = points[neighbours] - points[neighbours].mean(axis=1, keepdims=True)
    normals = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))[1][:, :, 0]
    eigenvalues, directions = np.linalg.eigh(normals.T @ normals / len(normals))
    weight = np.sum(np.cross(p, normals) ** 2, axis=1)
    if weight.sum() <= 0:  # no rotational information at all: plain mean
        held_s = float(np.mean(times[rows]))
    else:
        held_s = float(np.average(times[rows], weights=weight))
    return SweepInformation(held_s, eigenvalues, directions[:, 0])


#: KISS-ICP threads: one, for the same poses bit for bit on every run (see SweepOdometry).
ODOMETRY_THREADS = 1


class SweepOdometry:
    """KISS-ICP odometry (de-skew off, :data:`ODOMETRY_POINTS_PER_VOXEL`) fed one sweep at a time.

    Args:
        voxel_size: KISS-ICP voxel size in metres.
        max_range, min_range: points outside this range (m) are ignored by KISS-ICP.
    """

    def __init__(self, voxel_size: float, max_range: float, min_range: float = 0.0) -> None:
        from kiss_icp.config import KISSConfig
        from kiss_icp.kiss_icp import KissICP

        config = KISSConfig()
        config.data.max_range = max_range
        config.data.min_range = min_range
        config.data.deskew = False
        config.mapping.voxel_size = voxel_size
        config.mapping.max_points_per_voxel = ODOMETRY_POINTS_PER_VOXEL
        # One thread: KISS-ICP's parallel reductions sum in a thread-dependent order, so with two
        # threads the same sweeps gave poses differing by ~5e-16 per run, which registration then
        # amplifies (the trajectory, the mesh and training all changed from run to run). Its C++
        # sets the thread limit once per process (a static tbb::global_control at the first
        # registration built), so every odometry here must ask for the same count. Costs ~20 %.
        config.registration.max_num_threads = ODOMETRY_THREADS
        self._icp = KissICP(config)

    def register(self, points: np.ndarray, point_time_s: np.ndarray) -> tuple[np.ndarray, SweepInformation]:
        """Register a sweep's raw points ``(N, 3)`` float64 (times ``(N,)`` s from the sweep
        stamp); returns the pose ``T_world_lidar`` ``(4, 4)`` (world: the first sweep's LiDAR
        frame) and its :func:`sweep_information` (when the pose holds, how well it is constrained)."""
        _, source = self._icp.register_frame(points, np.zeros(0))
        return self._icp.last_pose.copy(), sweep_information(np.asarray(source), points, point_time_s)

    @property
    def threshold_m(self) -> float:
        """KISS-ICP's adaptive correspondence threshold now (m): the spread of the difference
        between its constant-velocity prediction and the registered poses so far."""
        return float(self._icp.adaptive_threshold.get_threshold())

    def register_rigid(self, points: np.ndarray) -> np.ndarray:
        """Register points ``(N, 3)`` float64 of a sweep already de-skewed to one instant; returns
        the pose ``T_world_lidar`` ``(4, 4)`` at that instant."""
        self._icp.register_frame(points, np.zeros(0))
        return self._icp.last_pose.copy()
