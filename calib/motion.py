"""Angular velocity of the rig over time, seen by the camera and on the LiDAR's clock.

Each source gives body-frame angular velocity vectors (rad/s) in its own sensor frame; the time
fit finds the rotation between the frames itself, so no extrinsic is needed.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
from scipy.ndimage import median_filter
from scipy.spatial.transform import Rotation

from calib.boards import to_gray
from calib.kiss_odometry import KissOdometry
from rig.camera import CameraModel
from rig.messages import Frame, ImuSample, Scan

#: How far apart (s) the compared frames are, by default (2 frames at 30 fps). A longer baseline
#: (:data:`LONG_PAIR_SPAN_S`) steadies the essential matrix of a hand-held camera that translates
#: while it turns, but tracks repetitive texture (a chessboard) across the wrong corners.
PAIR_SPAN_S = 1 / 15
LONG_PAIR_SPAN_S = 1 / 6
MAX_FEATURES = 400
MIN_TRACKS = 20
#: Rotations above this between compared frames (rad) are decomposition failures, not motion.
MAX_PAIR_ROTATION = 0.3
#: Spikes left by bad essential matrices are removed with a running median of this length.
MEDIAN_WINDOW = 5
#: Scans are thinned to about this many points before odometry (KISS-ICP voxelises them anyway).
ODOMETRY_POINTS = 6000
#: RANSAC threshold of the essential matrix, in normalised image units (about 1 px / focal).
_LK_PARAMS = {"winSize": (21, 21), "maxLevel": 3}


def _corners(gray: np.ndarray, camera: CameraModel) -> tuple[np.ndarray, np.ndarray] | None:
    """Corners to track in ``gray``: pixels ``(N, 1, 2)`` float32 (OpenCV's layout) and their
    normalised image coordinates ``(N, 2)``; None where there are too few."""
    corners = cv2.goodFeaturesToTrack(gray, MAX_FEATURES, 0.01, 7)
    if corners is None or len(corners) < MIN_TRACKS:
        return None
    return corners, camera.normalized_coordinates(corners.reshape(-1, 2))


def _pair_rotation(
    corners: tuple[np.ndarray, np.ndarray] | None, gray_a: np.ndarray, gray_b: np.ndarray, camera: CameraModel
) -> np.ndarray | None:
    """Rotation ``(3, 3)`` from frame a to frame b (``R_b_a``) from frame a's ``corners``
    (:func:`_corners`) tracked into b, or None without corners or enough tracks."""
    if corners is None:
        return None
    pixels, normalised = corners
    tracked, status, _ = cv2.calcOpticalFlowPyrLK(gray_a, gray_b, pixels, None, **_LK_PARAMS)
    good = status.ravel() == 1
    if good.sum() < MIN_TRACKS:
        return None
    xa = normalised[good]
    xb = camera.normalized_coordinates(tracked.reshape(-1, 2)[good])
    finite = np.all(np.isfinite(xa), axis=1) & np.all(np.isfinite(xb), axis=1)
    xa, xb = xa[finite], xb[finite]
    if len(xa) < MIN_TRACKS:
        return None
    threshold = 1.0 / camera.fx
    E, inliers = cv2.findEssentialMat(xa, xb, np.eye(3), cv2.RANSAC, 0.999, threshold)
    if E is None or E.shape != (3, 3):
        return None
    _, R, _, _ = cv2.recoverPose(E, xa, xb, np.eye(3), mask=inliers)
    return R


def frame_gap(stamps: np.ndarray, span_s: float = PAIR_SPAN_S) -> int:
    """How many frames apart (at least 1) the frames stamped ``stamps`` ``(N,)`` (ns) are compared:
    about ``span_s`` at their median rate."""
    frame_s = float(np.median(np.diff(stamps))) * 1e-9 if len(stamps) > 1 else 0.0
    return max(1, round(span_s / frame_s)) if frame_s > 0 else 1


def camera_angular_velocity(
    frames: Sequence[Frame], camera: CameraModel, spans_s: Sequence[float] = (PAIR_SPAN_S,)
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Angular velocity (rad/s, camera frame) from feature tracks and essential matrices, once for
    each of ``spans_s`` (each frame's corners are found once for all of them).

    Returns, per span, times ``(K,)`` (s, host clock, midpoints of frame pairs about that span
    apart) and vectors ``(K, 3)``; pairs without enough tracks are left out.
    """
    grays = [to_gray(f.image) for f in frames]
    stamps = np.array([f.t_host for f in frames], dtype=np.int64)
    gaps = [frame_gap(stamps, span_s) for span_s in spans_s]
    # OpenCV lets go of the GIL: the frames' corners and the pairs' rotations on every core
    # (the same results in the same order; 7.8 -> 5.3 s on the demo's 20 s room, two cores).
    first_frames = max(0, len(frames) - min(gaps, default=1))  # the frames that start a pair
    with ThreadPoolExecutor(max_workers=os.cpu_count()) as pool:
        corners = list(pool.map(lambda gray: _corners(gray, camera), grays[:first_frames]))

        def rotation(i: int, gap: int) -> np.ndarray | None:
            return _pair_rotation(corners[i], grays[i], grays[i + gap], camera)

        pair_rotations = [
            list(pool.map(rotation, range(len(frames) - gap), itertools.repeat(gap))) for gap in gaps
        ]
    signals = []
    for gap, rotations in zip(gaps, pair_rotations, strict=True):
        times, speeds = [], []
        for i, R in enumerate(rotations):
            j = i + gap
            dt = (stamps[j] - stamps[i]) * 1e-9
            if R is None or dt <= 0:
                continue
            # recoverPose gives R_b_a = exp(-w dt) for body angular velocity w.
            rotvec = -Rotation.from_matrix(R).as_rotvec()
            if np.linalg.norm(rotvec) > MAX_PAIR_ROTATION:
                continue
            times.append((stamps[i] + (stamps[j] - stamps[i]) / 2) * 1e-9)
            speeds.append(rotvec / dt)
        omega = np.asarray(speeds).reshape(-1, 3)
        if len(omega) >= MEDIAN_WINDOW:
            omega = median_filter(omega, size=(MEDIAN_WINDOW, 1), mode="nearest")
        signals.append((np.asarray(times), omega))
    return signals


def _odometry(scans: Sequence[Scan]) -> KissOdometry:
    """KISS-ICP odometry with a range and voxel size that suit these scans."""
    ranges = np.concatenate(
        [np.linalg.norm(s.points[:: max(1, len(s) // 500)], axis=1) for s in scans[:20]] or [[1.0]]
    )
    max_range = float(np.percentile(ranges, 99)) * 1.5
    # KISS-ICP's default voxel (range / 100), kept within what suits rooms and streets.
    return KissOdometry(float(np.clip(max_range / 100, 0.05, 1.0)), max_range)


def lidar_poses(scans: Sequence[Scan], backward: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """KISS-ICP odometry on raw sweeps (:class:`calib.kiss_odometry.KissOdometry`): pose times
    ``(J,)`` (s, host clock, when each pose holds) and poses ``(J, 4, 4)``, in scan order;
    ``backward`` runs the odometry from the last scan to the first."""
    odometry = _odometry(scans)
    used = [s for s in scans if len(s) >= 100]
    times, poses = np.zeros(len(used)), np.zeros((len(used), 4, 4))
    for k in reversed(range(len(used))) if backward else range(len(used)):
        scan = used[k]
        stride = max(1, len(scan) // ODOMETRY_POINTS)
        points = np.asarray(scan.points[::stride], dtype=np.float64)
        poses[k], information = odometry.register(
            points, np.asarray(scan.point_time_s, dtype=np.float64)[::stride]
        )
        times[k] = scan.t_host * 1e-9 + information.held_s
    return times, poses


def _rates(times: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Body angular velocity ``(J - 1, 3)`` between consecutive poses."""
    rel = np.einsum("nji,njk->nik", poses[:-1, :3, :3], poses[1:, :3, :3])
    return Rotation.from_matrix(rel).as_rotvec() / np.diff(times)[:, None]


def lidar_angular_velocity(scans: Sequence[Scan]) -> tuple[np.ndarray, np.ndarray]:
    """Angular velocity (rad/s, LiDAR frame) from KISS-ICP odometry: midpoint times ``(J - 1,)``
    and vectors ``(J - 1, 3)``.

    ICP pulls each pose toward KISS-ICP's constant-velocity prediction, so the roll and pitch
    rates of a run lag the motion (by 5–8 ms on the virtual rig) and those of a run backward in
    time lead it by about as much: the mean of both runs is used.
    """
    times, forward = lidar_poses(scans)
    if len(times) < 2:
        return np.zeros(0), np.zeros((0, 3))
    _, backward = lidar_poses(scans, backward=True)
    omega = (_rates(times, forward) + _rates(times, backward)) / 2
    return (times[:-1] + times[1:]) / 2, omega


def imu_angular_velocity(samples: Sequence[ImuSample]) -> tuple[np.ndarray, np.ndarray]:
    """Gyro angular velocity (rad/s, IMU frame): times ``(I,)`` (s, host clock), vectors ``(I, 3)``.

    For an IMU built into the LiDAR (Livox, Ouster, the virtual rig) this is the LiDAR clock's
    motion signal, and far less noisy than odometry differences.
    """
    times = np.array([s.t_host for s in samples], dtype=np.float64) * 1e-9
    omega = np.array([s.angular_velocity for s in samples], dtype=np.float64).reshape(-1, 3)
    return times, omega
