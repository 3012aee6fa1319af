"""LiDAR odometry on raw (not de-skewed) sweeps, each pose stamped when it holds.

:class:`SweepOdometry` is the fallback mapper's; :func:`sweep_information` is shared with the
time-offset calibration's KISS-ICP odometry (:mod:`calib.kiss_odometry`). Each sweep
is registered to a map of the sweeps before it by voxelized GICP (small_gicp's VGICP: every map
voxel a Gaussian of the points that fell in it, every sweep point with the covariance of its
neighbours), starting from a constant-velocity prediction. Plane-to-plane residuals do not care
where on a surface a LiDAR's rings fall; KISS-ICP's point-to-point ones do, and on a 64-beam
street they pulled each sweep towards the rings of the sweeps before it, i.e. towards standing
still: 78 sweeps of the virtual street (21.0 m, de-skewed with the true poses) gave a 20.86 m path
and 13.5 cm ATE at 0.36 m voxels (8.0 m at 1 m voxels), VGICP 21.02 m and 0.66 cm.

The sweeps are not de-skewed first: a de-skew needs the motion, and a constant-velocity guess is
wrong for a rig that pitches and rolls at a few Hz (KISS-ICP's made the virtual room's roll and
pitch rates lag the truth by 110–130 ms). The pose of a sweep left skewed holds at the time
:func:`sweep_information` finds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from rig.cpu_threads import cpu_threads
from rig.transforms import invert

#: The odometry voxel as a fraction of the 95th-percentile range of the first sweep. The time of
#: registration falls steeply with the voxel (it sets how many points are matched) and so does the
#: accuracy beyond a scene-dependent size. Virtual rig, one registration pass, ATE after alignment:
#: room (95th percentile 5.9 m) 0.10 / 0.13 / 0.165 m voxels: 0.83 / 0.89 / 0.91 cm at
#: 154 / 78 / 41 ms per sweep; 64-beam street (22 m): 0.33 / 0.5 / 0.6 m: 9.8 / 10.3 / 7.6 cm
#: over 20 s, but 0.6 m lost the car in the first 7.8 s (ATE 2.6 m). 1/60 gives 0.10 and 0.36 m.
VOXEL_PER_RANGE = 1 / 60
#: Neighbours of a point that give its surface normal (for :func:`sweep_information`).
NORMAL_NEIGHBOURS = 10
#: Source points whose times :func:`sweep_information` averages.
INFORMATION_SAMPLES = 1000
#: The map's voxels (each one Gaussian) are this many times the sweep's downsampling voxel.
MAP_VOXELS_PER_VOXEL = 3
#: Neighbours whose spread gives each sweep point its covariance.
COVARIANCE_NEIGHBOURS = 10
#: Map voxels not matched by the last this many sweeps are dropped (memory stays bounded).
MAP_HORIZON_SWEEPS = 100


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


#: Registration threads: one, for the same poses bit for bit on every run (the sweeps'
#: covariances use every core: they do not depend on the thread count). Parallel reductions
#: sum the normal equations in a thread-dependent order, and registration amplifies the last-bit
#: differences (the trajectory, the mesh and the training all changed from run to run).
ODOMETRY_THREADS = 1


def voxel_for_ranges(ranges: np.ndarray) -> float:
    """The odometry voxel (m) for sweeps whose first usable ranges are ``ranges`` ``(N,)`` (m):
    :data:`VOXEL_PER_RANGE` of their 95th percentile, within 0.1–1 m."""
    return float(np.clip(VOXEL_PER_RANGE * np.percentile(ranges, 95), 0.1, 1.0))


def thinned(count: int, budget: int) -> np.ndarray | slice:
    """Indices of at most about ``budget`` of ``count`` points, spread evenly over the sweep
    whatever its order: point ``i`` is kept where the fractional part of ``i`` times the golden
    ratio falls below ``budget / count`` (every k-th point would keep every k-th ring of a sweep
    stored column by column, as the virtual rig's and Ouster's are). All of them when
    ``count <= budget``."""
    if count <= budget:
        return slice(None)
    return np.flatnonzero(np.mod(np.arange(count) * 0.6180339887498949, 1.0) < budget / count)


def usable_sweep(
    points: np.ndarray, point_time_s: np.ndarray, budget: int, min_range: float, max_range: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """A sweep's points ``(N, 3)`` :func:`thinned` to ``budget`` and within ``(min_range,
    max_range)`` m, as float64, with their times ``(N,)`` s and ranges ``(N,)`` m; None when fewer
    than 100 remain."""
    chosen = thinned(len(points), budget)
    points = points[chosen].astype(np.float64)
    ranges = np.sqrt(np.einsum("ij,ij->i", points, points))
    keep = (ranges > min_range) & (ranges < max_range)
    if keep.sum() < 100:
        return None
    return points[keep], point_time_s[chosen][keep].astype(np.float64), ranges[keep]


def nearest_rotation(T: np.ndarray) -> np.ndarray:
    """``T`` ``(4, 4)`` with its rotation block projected onto the nearest rotation: products of
    poses drift from orthonormality, and composing a drifted pose with its transpose-inverse
    compounds the drift geometrically until the poses blow up."""
    U, _, Vt = np.linalg.svd(T[:3, :3])
    out = T.copy()
    out[:3, :3] = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    return out


class SweepOdometry:
    """Scan-to-map VGICP odometry (small_gicp) fed one sweep at a time.

    Args:
        voxel_size: the sweeps are downsampled to this voxel (m); the map's Gaussians are
            :data:`MAP_VOXELS_PER_VOXEL` times larger.
        max_range, min_range: points outside this range (m) are ignored.
    """

    def __init__(self, voxel_size: float, max_range: float, min_range: float = 0.0) -> None:
        import small_gicp

        self._gicp = small_gicp
        self.voxel_size, self.max_range, self.min_range = voxel_size, max_range, min_range
        self._map_voxel = MAP_VOXELS_PER_VOXEL * voxel_size
        self._map = small_gicp.GaussianVoxelMap(self._map_voxel)
        self._map.set_lru(horizon=MAP_HORIZON_SWEEPS, clear_cycle=10)
        self._poses: list[np.ndarray] = []  # the last two
        #: Per registered sweep: how far registration moved the pose from the prediction (m), and
        #: the fraction of the sweep's points that found a map voxel.
        self.corrections_m: list[float] = []
        self.inlier_fractions: list[float] = []

    def _prediction(self) -> np.ndarray:
        """The constant-velocity guess of the next pose ``(4, 4)`` (the last motion repeated)."""
        if len(self._poses) < 2:
            return self._poses[-1] if self._poses else np.eye(4)
        before, last = self._poses[-2], self._poses[-1]
        return nearest_rotation(last @ invert(before) @ last)

    def register_rigid(self, points: np.ndarray) -> np.ndarray:
        """Register points ``(N, 3)`` float64 of a sweep already de-skewed to one instant; returns
        the pose ``T_world_lidar`` ``(4, 4)`` at that instant (world: the first sweep's frame)."""
        return self._register(points)[0]

    def register(self, points: np.ndarray, point_time_s: np.ndarray) -> tuple[np.ndarray, SweepInformation]:
        """Register a sweep's raw points ``(N, 3)`` float64 (times ``(N,)`` s from the sweep
        stamp); returns the pose ``T_world_lidar`` ``(4, 4)`` and its :func:`sweep_information`
        (when the pose holds, how well it is constrained)."""
        pose, registered = self._register(points)
        return pose, sweep_information(registered, points, point_time_s)

    def _register(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Register a sweep's points ``(N, 3)`` to the map and add them to it: the pose ``(4, 4)``
        and the downsampled points ``(M, 3)`` (sensor frame) that were registered."""
        squared = np.einsum("ij,ij->i", points, points)
        inside = points[(squared >= self.min_range**2) & (squared <= self.max_range**2)]
        # The downsampling on one thread (with more, the points come out in a thread-dependent
        # order); the covariances on all: each point's is its own, so they come out the same.
        sweep = self._gicp.voxelgrid_sampling(inside, self.voxel_size, num_threads=1)
        threads = cpu_threads()
        self._gicp.estimate_covariances(
            sweep, self._gicp.KdTree(sweep, num_threads=threads), COVARIANCE_NEIGHBOURS, num_threads=threads
        )
        guess = self._prediction()
        if not self._poses:
            pose, inliers = guess, sweep.size()
        else:
            result = self._gicp.align(
                self._map, sweep, guess, max_correspondence_distance=self._map_voxel,
                num_threads=ODOMETRY_THREADS,
            )  # fmt: skip
            # (A copy: the array views memory that the result frees.)
            pose, inliers = nearest_rotation(np.array(result.T_target_source)), result.num_inliers
        self.corrections_m.append(float(np.linalg.norm(pose[:3, 3] - guess[:3, 3])))
        self.inlier_fractions.append(inliers / max(sweep.size(), 1))
        self._map.insert(sweep, pose)
        self._poses = [*self._poses[-1:], pose]
        return pose.copy(), sweep.points()[:, :3]
