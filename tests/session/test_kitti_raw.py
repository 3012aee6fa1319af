"""KITTI raw drives read in place: a virtual-rig session written in KITTI's layout reads back as
the session (images, sweeps with their point times, IMU, calibration), the calibration follows
the devkit's projection, and broken drive folders are one-line errors."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from kitti_layout import R_RECT_00, write_calibration, write_kitti_drive
from truth_slam import write_truth_slam

from rig.calibration import Calibration, load_calibration
from rig.camera import CameraModel
from rig.errors import InputError
from rig.session import SessionReader, find_topics, open_recording
from rig.session.kitti_raw import kitti_cameras, parse_stamps
from rig.session.tf_static import recording_calibration
from rig.sim.config import SimConfig
from rig.sim.simulate import simulate
from rig.transforms import make_transform

LTS = Path(sys.executable).parent / "lts"
RIG = Path(sys.executable).parent / "rig"


@pytest.fixture(scope="module")
def spinning_room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The quick room seen by the simulator's spinning LiDAR (KITTI has a spinning Velodyne)."""
    out = tmp_path_factory.mktemp("spinning_room")
    simulate(SimConfig(lidar="spinning").quick(), out)
    return out


@pytest.fixture(scope="module")
def drive(spinning_room: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_kitti_drive(spinning_room, tmp_path_factory.mktemp("kitti"))


def test_stamps_are_read_to_the_nanosecond(tmp_path: Path) -> None:
    path = tmp_path / "timestamps.txt"
    path.write_text("2011-09-26 13:02:25.964389445\n2011-09-26 13:02:26.0743\n\n")
    np.testing.assert_array_equal(parse_stamps(path), [1317042145964389445, 1317042146074300000])
    path.write_text("2011-09-26 13:02:25.964389445\n13:02:26\n")
    with pytest.raises(InputError, match="line 2: '13:02:26' is not a time"):
        parse_stamps(path)


def test_calibration_projects_as_the_devkit_does(tmp_path: Path) -> None:
    """``P_rect_02 · R_rect_00 · Tr_velo_to_cam · X`` (the devkit's projection) and the rectified
    camera model after ``T_cam_velo`` land on the same pixels."""
    K = np.array([[721.5, 0, 609.6], [0, 721.5, 172.9], [0, 0, 1]])
    truth = make_transform(
        np.array([[0.0, -1, 0], [0, 0, -1], [1, 0, 0]]) @ cv2.Rodrigues(np.array([0.01, -0.02, 0.03]))[0],
        np.array([0.05, -0.08, -0.27]),
    )
    write_calibration(
        tmp_path,
        Calibration(CameraModel("pinhole", 1242, 375, K, []), truth),
        CameraModel("pinhole", 1242, 375, K, []),
    )
    cameras = kitti_cameras(tmp_path, [0, 2])
    np.testing.assert_allclose(cameras[2].T_cam_velo, truth, atol=1e-9)
    np.testing.assert_allclose(cameras[2].model.K, K)
    assert (cameras[2].model.width, cameras[2].model.height) == (1242, 375)

    fields = {
        line.split(":")[0]: np.array(line.split(":")[1].split(), float)
        for name in ("calib_cam_to_cam.txt", "calib_velo_to_cam.txt")
        for line in (tmp_path / name).read_text().splitlines()
        if not line.startswith("calib_time")
    }
    Tr = make_transform(fields["R"].reshape(3, 3), fields["T"])
    points = np.column_stack(
        [np.random.default_rng(0).uniform([5, -10, -2], [40, 10, 3], (50, 3)), np.ones(50)]
    )
    for number in (0, 2):
        devkit = (
            fields[f"P_rect_{number:02d}"].reshape(3, 4)
            @ make_transform(R_RECT_00, np.zeros(3))
            @ Tr
            @ points.T
        ).T
        camera = (cameras[number].T_cam_velo @ points.T).T[:, :3] @ cameras[number].model.K.T
        np.testing.assert_allclose(camera[:, :2] / camera[:, 2:], devkit[:, :2] / devkit[:, 2:], atol=1e-6)


def test_a_kitti_drive_reads_as_its_session(spinning_room: Path, drive: Path) -> None:
    recording = open_recording(drive)
    assert recording.format == "KITTI raw"
    topics = find_topics(recording)
    assert (topics.image, topics.camera_info, topics.points, topics.imu) == (
        "/kitti/camera_02/image", "/kitti/camera_02/camera_info", "/kitti/velodyne/points", "/kitti/oxts/imu",
    )  # fmt: skip
    truth = load_calibration(spinning_room / "ground_truth" / "calib.yaml")
    own = recording_calibration(recording, topics)  # what --calib tf gives
    np.testing.assert_allclose(own.T_cam_lidar, truth.T_cam_lidar, atol=1e-9)
    np.testing.assert_allclose(own.camera.K, truth.camera.K)
    assert own.camera.dist.size == 0

    session = SessionReader(spinning_room / "session.mcap")
    native = find_topics(session)
    offset = round(truth.time_offset_s * 1e9)
    frames, kitti_frames = list(session.frames(native.image)), list(recording.frames(topics.image))
    assert [f.t_host - offset for f in frames] == [f.t_host for f in kitti_frames]
    np.testing.assert_array_equal(recording.stamps(topics.image), [f.t_host for f in kitti_frames])
    rectified = truth.camera.undistorted()
    for frame, kitti in zip(frames[::20], kitti_frames[::20], strict=True):
        np.testing.assert_array_equal(kitti.image, truth.camera.undistort_image(frame.image, rectified))
    chosen = list(recording.frames_at(topics.image, np.array([3, 7])))
    assert [f.t_host for f in chosen] == [kitti_frames[3].t_host, kitti_frames[7].t_host]

    # Every simulated point comes back once, at its own time (from the azimuth alone) except the
    # points on the seam straight behind, which may land at either end of a sweep.
    scans = list(session.scans(native.points))
    times = np.concatenate([s.t_host + np.round(s.point_time_s * 1e9).astype(np.int64) for s in scans])
    kitti_scans = list(recording.scans(topics.points))
    assert len(kitti_scans) == len(scans) - 1
    for kitti in kitti_scans:
        inside = (times >= kitti.t_host) & (times < kitti.t_host + 100_000_000)
        want = np.sort(times[inside])
        got = kitti.t_host + kitti.point_time_s * 1e9
        assert got.size == want.size
        error = np.abs(got - want)
        assert np.median(error) < 1e3 and np.sum(error > 1e5) <= 32  # 1 µs; one column of 32 beams
    imu = list(recording.imu(topics.imu))
    assert len(imu) == len(kitti_scans) and all(s.angular_velocity.shape == (3,) for s in imu)


def test_camera_choice(drive: Path) -> None:
    grey = open_recording(drive, camera=0)
    topics = find_topics(grey)
    assert (topics.image, topics.camera_info) == ("/kitti/camera_00/image", "/kitti/camera_00/camera_info")
    assert next(iter(grey.frames(topics.image))).encoding == "mono8"
    with pytest.raises(InputError, match="no image_03 folder; the drive has cameras 0, 2"):
        open_recording(drive, camera=3)
    result = subprocess.run([RIG, "info", drive, "--camera", "0", "--json"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["roles"]["image"] == "/kitti/camera_00/image"


@pytest.fixture(scope="module")
def truth_slam(spinning_room: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_truth_slam(spinning_room, tmp_path_factory.mktemp("truth_slam"))


def _unlink_first_sweep(drive: Path) -> None:
    next((drive / "velodyne_points" / "data").glob("*.bin")).unlink()


@pytest.mark.parametrize(
    ("damage", "command", "expected"),
    [
        (
            lambda d: (d.parent / "calib_velo_to_cam.txt").unlink(),
            "prepare",
            "no calib_velo_to_cam.txt in the drive folder or its parent",
        ),
        (
            lambda d: (d.parent / "calib_cam_to_cam.txt").write_text("R_rect_00: 1 0 0 0 1 0 0 0 1\n"),
            "prepare",
            "calib_cam_to_cam.txt: P_rect_00: missing; expected 12 numbers",
        ),
        (lambda d: (d / "image_02" / "timestamps.txt").unlink(), "info", "image_02/timestamps.txt: missing"),
        (_unlink_first_sweep, "info", "28 *.bin files in data/ but 29 times in timestamps.txt"),
    ],
    ids=["no calibration", "no projection", "no timestamps", "counts differ"],
)
def test_a_broken_drive_is_a_one_line_error(
    drive: Path, truth_slam: Path, tmp_path: Path, damage, command: str, expected: str
) -> None:
    """``rig info`` reads the timestamps; the calibration is read where it is used (a user's own
    calib.yaml needs none in the folder)."""
    broken = tmp_path / drive.parent.name / drive.name
    shutil.copytree(drive.parent, broken.parent)
    damage(broken)
    args = (
        [RIG, "info", broken]
        if command == "info"
        else [LTS, "prepare", broken, "--calib", "tf", "--slam", truth_slam, "--out", tmp_path / "scene"]
    )
    result = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    assert expected in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_rig_info_lists_the_drive(drive: Path) -> None:
    result = subprocess.run([RIG, "info", drive, "--json"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    assert info["format"] == "KITTI raw"
    assert info["roles"]["image"] == "/kitti/camera_02/image"


@pytest.mark.slow
def test_a_kitti_drive_reconstructs_with_its_own_calibration(
    spinning_room: Path, drive: Path, tmp_path: Path
) -> None:
    run = tmp_path / "run"
    args = [LTS, "reconstruct", drive, "--out", run, "--calib", "tf", "--preset", "fast",
            "--iterations", "150", "--keyframe-interval", "0.2", "--gt", spinning_room / "ground_truth",
            "--json"]  # fmt: skip
    result = subprocess.run(args, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr[-2000:]
    metrics = json.loads(result.stdout)
    assert metrics["fscore"] > 0.8 and metrics["psnr"] > 12


def test_a_drive_too_short_for_a_test_view_stops_before_training(drive: Path, tmp_path: Path) -> None:
    """3 s at one keyframe per 0.5 s holds no 8th keyframe out: lts reconstruct says so after
    prepare instead of failing at evaluate after the whole training. (By default a drive this short
    gets one keyframe per 0.2 s, 16 of them, two held out.)"""
    args = [LTS, "reconstruct", drive, "--calib", "tf", "--out", tmp_path / "run", "--preset", "fast",
            "--keyframe-interval", "0.5"]  # fmt: skip
    result = subprocess.run(args, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr[-2000:]
    last_line = result.stderr.strip().splitlines()[-1]
    assert last_line.endswith("take keyframes more often (--keyframe-interval S)")
    assert not (tmp_path / "run" / "train").exists()
