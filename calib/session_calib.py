"""Calibrate from a recorded session: time offset from motion, then targetless extrinsic.

The camera model comes from the session's CameraInfo (or the initial calibration). The LiDAR
motion signal is the gyro of the IMU on the LiDAR's clock when the session has one (Livox,
Ouster and the virtual rig carry it in the LiDAR), otherwise KISS-ICP odometry.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from calib.motion import camera_angular_velocity, imu_angular_velocity, lidar_angular_velocity
from calib.pointcloud_io import PointCloud
from calib.targetless import ExtrinsicPair, refine_extrinsic
from calib.time_offset import TimeOffsetResult, estimate_time_offset
from rig.calibration import Calibration
from rig.camera import CameraModel
from rig.errors import InputError
from rig.messages import Frame, ImuSample, Scan
from rig.session import DEFAULT_TOPICS, SessionReader

#: Image + LiDAR pairs used for the extrinsic, and the LiDAR time window (s) around each frame:
#: a whole sweep when the gyro can de-skew it, a short slice otherwise.
EXTRINSIC_PAIRS = 6
POINT_WINDOW_S = {"deskewed": 0.05, "raw": 0.02}
LIDAR_MOTION = ("auto", "imu", "odometry")


@dataclass(eq=False)
class SessionData:
    """The messages calibration needs from one session."""

    frames: list[Frame]
    scans: list[Scan]
    imu: list[ImuSample]
    camera: CameraModel | None
    path: Path
    topics: dict[str, str] = field(default_factory=lambda: dict(DEFAULT_TOPICS))


def load_session(path: str | Path, topics: dict[str, str] | None = None) -> SessionData:
    """Read frames, scans, IMU samples and the camera model (None if absent) from a session."""
    topics = {**DEFAULT_TOPICS, **(topics or {})}
    reader = SessionReader(path)
    present = reader.topics()
    frames = list(reader.frames(topics["image"])) if topics["image"] in present else []
    scans = list(reader.scans(topics["points"])) if topics["points"] in present else []
    imu = list(reader.imu(topics["imu"])) if topics["imu"] in present else []
    camera = reader.camera_model(topics["camera_info"]) if topics["camera_info"] in present else None
    if not frames:
        raise InputError(f"no camera frames on {topics['image']}", path=path, field="topics")
    return SessionData(frames, scans, imu, camera, Path(path), topics)


def calibrate_time(
    data: SessionData, camera: CameraModel, lidar_motion: str = "auto"
) -> tuple[TimeOffsetResult, tuple[np.ndarray, np.ndarray]]:
    """Camera–LiDAR time offset of a session (see :mod:`calib.time_offset`), and the camera's
    angular speed signal (times ``(K,)`` s, speeds ``(K,)`` rad/s) it came from."""
    if lidar_motion not in LIDAR_MOTION:
        raise InputError(f"unknown {lidar_motion!r}; expected one of {LIDAR_MOTION}", field="lidar_motion")
    use_imu = lidar_motion == "imu" or (lidar_motion == "auto" and len(data.imu) > 0)
    if use_imu and not data.imu:
        raise InputError(f"no IMU samples on {data.topics['imu']}", path=data.path, field="topics")
    if not use_imu and not data.scans:
        raise InputError(f"no LiDAR scans on {data.topics['points']}", path=data.path, field="topics")
    t_cam, w_cam = camera_angular_velocity(data.frames, camera)
    t_lid, w_lid = imu_angular_velocity(data.imu) if use_imu else lidar_angular_velocity(data.scans)
    result = estimate_time_offset(t_cam, w_cam, t_lid, w_lid)
    result.extra["lidar_motion"] = "imu gyro" if use_imu else "KISS-ICP odometry"
    return result, (t_cam, np.linalg.norm(w_cam, axis=1))


def extrinsic_pairs(
    data: SessionData, time_offset_s: float, motion: tuple[np.ndarray, np.ndarray] | None = None
) -> list[ExtrinsicPair]:
    """``EXTRINSIC_PAIRS`` frames spread over the session, each with the LiDAR points measured
    within ``POINT_WINDOW_S`` of it (LiDAR times shifted onto the camera clock). With an IMU on the
    LiDAR, each point is rotated to where the LiDAR pointed at the frame's time (gyro rate at the
    frame, constant over the window; the translation in 50 ms of driving is left). With the
    camera's angular speed ``motion`` (times, speeds), each pair is the calmest frame of its stretch."""
    if not data.scans:
        return []
    frame_t = np.array([f.t_host for f in data.frames], dtype=np.float64) * 1e-9
    chosen = []
    for stretch in np.array_split(np.arange(len(frame_t)), EXTRINSIC_PAIRS + 2)[1:-1]:
        if not len(stretch):
            continue
        index = int(stretch[len(stretch) // 2])
        if motion is not None and len(motion[0]):
            speed = np.interp(frame_t[stretch], motion[0], motion[1])
            index = int(stretch[np.argmin(speed)])
        chosen.append(index)
    scan_t = np.array([s.t_host for s in data.scans], dtype=np.float64) * 1e-9 + time_offset_s
    gyro_t, gyro = imu_angular_velocity(data.imu)
    gyro_t = gyro_t + time_offset_s
    window = POINT_WINDOW_S["deskewed" if len(gyro_t) else "raw"]
    pairs = []
    for index in chosen:
        t = frame_t[index]
        points, intensity = [], []
        for j in np.flatnonzero(np.abs(scan_t - t) < 0.5):
            scan = data.scans[j]
            times = scan.t_host * 1e-9 + time_offset_s + np.asarray(scan.point_time_s, dtype=np.float64)
            near = np.abs(times - t) < window
            pts = np.asarray(scan.points, dtype=np.float64)[near]
            if len(gyro_t):
                omega = np.array([np.interp(t, gyro_t, gyro[:, k]) for k in range(3)])
                # Body rates: R(t)^T R(t_p) = exp(w (t_p - t)), applied to each point.
                pts = Rotation.from_rotvec(np.outer(times[near] - t, omega)).apply(pts)
            points.append(pts)
            intensity.append(np.asarray(scan.intensity, dtype=np.float32)[near])
        if points:
            pairs.append(
                ExtrinsicPair(
                    data.frames[index].image, PointCloud(np.vstack(points), np.concatenate(intensity))
                )
            )
    return pairs


def calibrate_session(
    path: str | Path,
    init: Calibration | None = None,
    lidar_motion: str = "auto",
    topics: dict[str, str] | None = None,
) -> tuple[Calibration, dict[str, Any]]:
    """Everything a session supports: camera model, time offset and (with ``init``'s rough
    ``T_cam_lidar``) the targetless extrinsic. Returns the calibration and a report."""
    data = load_session(path, topics)
    camera = data.camera or (init.camera if init is not None else None)
    if camera is None:
        raise InputError(
            "the session has no CameraInfo and no --init calibration was given",
            path=path,
            field="camera_info",
        )
    report: dict[str, Any] = {"camera_source": "session CameraInfo" if data.camera else "initial calibration"}
    calibration = Calibration(
        camera, init.T_cam_lidar.copy() if init else np.eye(4), init.time_offset_s if init else 0.0
    )

    time_result, motion = calibrate_time(data, camera, lidar_motion)
    report["time"] = time_result.to_json()
    if time_result.verdict == "ok":
        calibration.time_offset_s = time_result.time_offset_s

    if init is None:
        report["extrinsic"] = {
            "verdict": "not run",
            "reasons": ["targetless refinement needs a rough T_cam_lidar (--init)"],
        }
    else:
        pairs = extrinsic_pairs(data, calibration.time_offset_s, motion)
        result = refine_extrinsic(pairs, camera, init.T_cam_lidar)
        report["extrinsic"] = result.to_json()
        calibration.T_cam_lidar = result.T_cam_lidar
    calibration.quality = {"time": report["time"], "extrinsic": report["extrinsic"]}
    return calibration, report
