"""Each keyframe's LiDAR points: the scans between its neighbouring keyframes, deskewed by the
trajectory and moved into its camera frame, kept where they project into the image."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from rig.calibration import Calibration
from rig.camera import CameraModel
from rig.deskew import deskewed_points
from rig.messages import Scan
from rig.trajectory import Trajectory
from rig.transforms import invert, transform_points
from slam_bridge.keyframe_selection import lidar_clock
from slam_bridge.scene import LIDAR_DIR, Keyframe

#: Points nearer than this along the camera's z are never depth (as in the z-buffer).
NEAR_M = 0.05


def keyframe_windows(t_ns: np.ndarray, interval_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The time window ``[lo, hi]`` ``(K,)`` each of keyframes at increasing stamps ``(K,)``: from the
    previous keyframe to the next one (``interval_s`` before the first and after the last)."""
    t_ns = np.asarray(t_ns, dtype=np.int64)
    margin = int(interval_s * 1e9)
    lo = np.concatenate([[t_ns[0] - margin], t_ns[:-1]])
    hi = np.concatenate([t_ns[1:], [t_ns[-1] + margin]])
    return lo, hi


def in_view(points_cam: np.ndarray, camera: CameraModel) -> np.ndarray:
    """Camera-frame points ``(N, 3)`` beyond :data:`NEAR_M` that project into the image ``(M, 3)`` float32."""
    front = points_cam[points_cam[:, 2] > NEAR_M]
    return front[camera.in_image(camera.project(front))].astype(np.float32)


def keyframe_lidar(
    scans: Iterable[Scan],
    trajectory: Trajectory,
    calibration: Calibration,
    keyframes: list[Keyframe],
    camera: CameraModel,
    interval_s: float,
) -> list[np.ndarray]:
    """Per keyframe (in time order), the points ``(N, 3)`` float32 in its camera frame of the scans
    stamped within its :func:`keyframe_windows` (on the camera clock), deskewed with the LiDAR
    ``trajectory`` (host clock) and seen by ``camera``. Scans are streamed; each is deskewed once."""
    lo, hi = keyframe_windows(np.array([k.t_ns for k in keyframes]), interval_s)
    lo, hi = lidar_clock(lo, calibration), lidar_clock(hi, calibration)
    T_cam_world = invert(np.stack([k.T_world_cam for k in keyframes]))
    chunks: list[list[np.ndarray]] = [[] for _ in keyframes]
    for scan in scans:
        first, stop = np.searchsorted(hi, scan.t_host), np.searchsorted(lo, scan.t_host, side="right")
        if first >= stop:
            continue
        world = deskewed_points(scan.points, scan.point_times_ns(host=True), trajectory)
        for n in range(first, stop):
            chunks[n].append(in_view(transform_points(T_cam_world[n], world), camera))
    return [np.concatenate(c) if c else np.zeros((0, 3), np.float32) for c in chunks]


def write_keyframe_lidar(
    out: Path, keyframes: list[Keyframe], points: list[np.ndarray], done: Callable[[], None]
) -> None:
    """Save each keyframe's points ``(N, 3)`` float32 as ``out/lidar/NAME.npy``; ``done()`` after each."""
    (out / LIDAR_DIR).mkdir(parents=True, exist_ok=True)
    for keyframe, cloud in zip(keyframes, points, strict=True):
        np.save(out / LIDAR_DIR / f"{keyframe.name}.npy", cloud)
        done()
