"""A virtual-rig session written as a KITTI raw "sync" drive, for the tests that read KITTI drives.

:func:`write_kitti_drive` lays a session out as KITTI ships a drive: rectified PNGs with
``timestamps.txt`` per camera, Velodyne ``.bin`` sweeps with ``timestamps.txt``,
``timestamps_start.txt`` and ``timestamps_end.txt``, OXTS packets, and the day's
``calib_cam_to_cam.txt`` / ``calib_velo_to_cam.txt`` beside the drive folder, built from the
session's ground-truth calibration.

The session's LiDAR must be the simulator's ``spinning`` one: it turns clockwise from straight
ahead, while a KITTI sweep runs clockwise from straight behind. The sweeps are therefore cut again
at the back (a KITTI sweep is the second half of one simulated sweep and the first half of the
next), which is what lets a reader recover each point's time from its azimuth alone.
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from rig.calibration import Calibration, load_calibration
from rig.camera import CameraModel
from rig.session import SessionReader, find_topics
from rig.transforms import invert, make_transform

DRIVE = "2011_09_26_drive_0001_sync"
#: The rectifying rotation of camera 0 written to ``R_rect_00`` (small, as KITTI's are).
R_RECT_00 = Rotation.from_euler("xyz", [0.4, -0.3, 0.2], degrees=True).as_matrix()
#: Camera 2's offset along x in rectified camera-0 coordinates (KITTI: about 6 cm).
BASELINE_M = 0.06


def stamp_text(t_ns: int) -> str:
    """``t_ns`` as KITTI writes a time: ``YYYY-MM-DD HH:MM:SS.fffffffff`` (UTC)."""
    seconds, fraction = divmod(int(t_ns), 1_000_000_000)
    return datetime.fromtimestamp(seconds, UTC).strftime("%Y-%m-%d %H:%M:%S") + f".{fraction:09d}"


def write_stamps(path: Path, stamps: np.ndarray) -> None:
    path.write_text("".join(stamp_text(t) + "\n" for t in stamps))


def _numbers(values: np.ndarray) -> str:
    return " ".join(f"{v:.12e}" for v in np.ravel(values))


def write_calibration(day: Path, calibration: Calibration, rectified: CameraModel) -> None:
    """The day's calibration files: camera 2 (colour) and camera 0 (grey) share the session
    camera's pose, ``BASELINE_M`` from the rectified reference; ``Tr_velo_to_cam`` follows."""
    K = rectified.K
    P = np.hstack([K, K @ np.array([[BASELINE_M], [0.0], [0.0]])])
    T_ref_cam = make_transform(np.eye(3), np.array([-BASELINE_M, 0, 0]))  # x_cam = x_ref + (B, 0, 0)
    T_cam0_velo = invert(make_transform(R_RECT_00, np.zeros(3))) @ T_ref_cam @ calibration.T_cam_lidar
    size = np.array([rectified.width, rectified.height], dtype=float)
    lines = [
        "calib_time: 09-Jan-2012 13:57:47",
        "corner_dist: 9.950000e-02",
        f"R_rect_00: {_numbers(R_RECT_00)}",
    ]
    for number in (0, 2):
        lines += [f"S_rect_{number:02d}: {_numbers(size)}", f"P_rect_{number:02d}: {_numbers(P)}"]
    (day / "calib_cam_to_cam.txt").write_text("\n".join(lines) + "\n")
    (day / "calib_velo_to_cam.txt").write_text(
        "calib_time: 15-Mar-2012 11:37:16\n"
        f"R: {_numbers(T_cam0_velo[:3, :3])}\nT: {_numbers(T_cam0_velo[:3, 3])}\n"
        "delta_f: 0.000000e+00 0.000000e+00\ndelta_c: 0.000000e+00 0.000000e+00\n"
    )


def write_kitti_drive(session_dir: Path, out: Path) -> Path:
    """``session_dir`` (``session.mcap`` + ``ground_truth/calib.yaml``) as ``out/2011_09_26/DRIVE``;
    returns the drive folder. Camera stamps move onto the LiDAR's clock (KITTI has one clock)."""
    calibration = load_calibration(session_dir / "ground_truth" / "calib.yaml")
    reader = SessionReader(session_dir / "session.mcap")
    topics = find_topics(reader)
    drive = out / "2011_09_26" / DRIVE
    rectified = calibration.camera.undistorted()
    drive.mkdir(parents=True)
    write_calibration(drive.parent, calibration, rectified)

    offset_ns = round(calibration.time_offset_s * 1e9)
    stamps = []
    for folder in ("image_00", "image_02"):
        (drive / folder / "data").mkdir(parents=True)
    for index, frame in enumerate(reader.frames(topics.image)):
        image = calibration.camera.undistort_image(frame.image, rectified)
        cv2.imwrite(str(drive / "image_02" / "data" / f"{index:010d}.png"), image)
        cv2.imwrite(
            str(drive / "image_00" / "data" / f"{index:010d}.png"), cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        )
        stamps.append(frame.t_host - offset_ns)
    for folder in ("image_00", "image_02"):
        write_stamps(drive / folder / "timestamps.txt", np.array(stamps))

    start = _write_sweeps(reader, topics.points, drive / "velodyne_points")
    _write_oxts(reader, topics.imu, drive / "oxts", start)
    return drive


def _write_sweeps(reader: SessionReader, topic: str, folder: Path) -> np.ndarray:
    """KITTI sweeps cut at the back between consecutive simulated sweeps; returns their starts."""
    (folder / "data").mkdir(parents=True)
    scans = list(reader.scans(topic))
    period = int(np.median(np.diff([s.t_host for s in scans])))
    times = np.concatenate([s.t_host + np.round(s.point_time_s * 1e9).astype(np.int64) for s in scans])
    cloud = np.vstack([np.column_stack([s.points, s.intensity / 255.0]) for s in scans]).astype("<f4")
    starts = np.array([s.t_host + period // 2 for s in scans[:-1]], dtype=np.int64)
    for index, begin in enumerate(starts):
        inside = (times >= begin) & (times < begin + period)
        cloud[inside][np.argsort(times[inside], kind="stable")].tofile(folder / "data" / f"{index:010d}.bin")
    write_stamps(folder / "timestamps_start.txt", starts)
    write_stamps(folder / "timestamps.txt", starts + period // 2)
    write_stamps(folder / "timestamps_end.txt", starts + period)
    return starts


def _write_oxts(reader: SessionReader, topic: str | None, folder: Path, sweep_starts: np.ndarray) -> None:
    """One OXTS packet per sweep (as in KITTI's sync data): the IMU sample nearest its middle."""
    if topic is None:
        return
    samples = list(reader.imu(topic))
    t = np.array([s.t_host for s in samples])
    (folder / "data").mkdir(parents=True)
    mids = sweep_starts + int(np.median(np.diff(sweep_starts))) // 2
    for index, mid in enumerate(mids):
        sample = samples[int(np.argmin(np.abs(t - mid)))]
        packet = np.zeros(30)
        packet[14:17], packet[20:23] = sample.linear_acceleration, sample.angular_velocity
        (folder / "data" / f"{index:010d}.txt").write_text(" ".join(f"{v:.9g}" for v in packet) + "\n")
    write_stamps(
        folder / "timestamps.txt", np.array([samples[int(np.argmin(np.abs(t - m)))].t_host for m in mids])
    )
