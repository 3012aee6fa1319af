"""The messages calibration reads from a session, and the LiDAR points around a camera frame."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from calib.motion import imu_angular_velocity
from rig.camera import CameraModel
from rig.errors import InputError
from rig.messages import Frame, ImuSample, Scan
from rig.pointcloud_io import PointCloud
from rig.session import DEFAULT_TOPICS, Recording, SessionTopics, as_recording, find_topics

#: LiDAR time window (s) around a frame: a whole sweep when the gyro can de-skew it, a short
#: slice otherwise.
POINT_WINDOW_S = {"deskewed": 0.05, "raw": 0.02}


@dataclass(eq=False)
class SessionData:
    """The messages calibration needs from one session."""

    frames: list[Frame]
    scans: list[Scan]
    imu: list[ImuSample]
    camera: CameraModel | None
    path: Path
    topics: SessionTopics = field(default_factory=lambda: SessionTopics(**DEFAULT_TOPICS))


def load_session(path: Recording | str | Path, topics: dict[str, str] | None = None) -> SessionData:
    """Read frames, scans, IMU samples and the camera model (None if absent) from a recording
    (open, or its path); ``topics`` chooses a role's topic (keys of
    :class:`rig.session.SessionTopics`) over the recording's topic map (see
    :func:`rig.session.find_topics`)."""
    reader = as_recording(path)
    found = find_topics(reader, **(topics or {}), require_points=False)
    frames = list(reader.frames(found.image))
    scans = list(reader.scans(found.points)) if found.points else []
    imu = list(reader.imu(found.imu)) if found.imu else []
    camera = reader.camera_model(found.camera_info) if found.camera_info else None
    if not frames:
        raise InputError(f"no camera frames on {found.image}", path=reader.path, field="topics")
    return SessionData(frames, scans, imu, camera, reader.path, found)


def frame_times(data: SessionData) -> np.ndarray:
    """Host times ``(F,)`` (s) of the frames."""
    return np.array([f.t_host for f in data.frames], dtype=np.float64) * 1e-9


def frame_clouds(
    data: SessionData,
    indices: Sequence[int],
    time_offset_s: float,
    velocities: Sequence[np.ndarray] | None = None,
) -> list[PointCloud | None]:
    """For each frame index, the LiDAR points measured within ``POINT_WINDOW_S`` of the frame
    (LiDAR times shifted onto the camera clock), or None when no scan is near.

    With an IMU on the LiDAR, each point is rotated to where the LiDAR pointed at the frame's time
    (gyro rate at the frame, constant over the window). With ``velocities`` (the LiDAR's linear
    velocity ``(3,)`` m/s in its own frame at each frame's time), each point is also moved by
    where the LiDAR was; without, the translation in the window is left (up to v × 50 ms, and a
    tilt of flat targets, since a spinning LiDAR sweeps across them in time).
    """
    frame_t = frame_times(data)
    scan_t = np.array([s.t_host for s in data.scans], dtype=np.float64) * 1e-9 + time_offset_s
    gyro_t, gyro = imu_angular_velocity(data.imu)
    gyro_t = gyro_t + time_offset_s
    window = POINT_WINDOW_S["deskewed" if len(gyro_t) else "raw"]
    clouds: list[PointCloud | None] = []
    for k, index in enumerate(indices):
        t = frame_t[index]
        omega = np.array([np.interp(t, gyro_t, gyro[:, c]) for c in range(3)]) if len(gyro_t) else None
        points, intensity = [], []
        for j in np.flatnonzero(np.abs(scan_t - t) < 0.5):
            scan = data.scans[j]
            times = scan.t_host * 1e-9 + time_offset_s + np.asarray(scan.point_time_s, dtype=np.float64)
            near = np.abs(times - t) < window
            pts = np.asarray(scan.points, dtype=np.float64)[near]
            dt = times[near] - t
            if omega is not None:
                # Body rates: R(t)^T R(t_p) = exp(w (t_p - t)), applied to each point.
                pts = Rotation.from_rotvec(np.outer(dt, omega)).apply(pts)
            if velocities is not None:
                pts = pts + np.outer(dt, velocities[k])
            points.append(pts)
            intensity.append(np.asarray(scan.intensity, dtype=np.float32)[near])
        clouds.append(PointCloud(np.vstack(points), np.concatenate(intensity)) if points else None)
    return clouds
