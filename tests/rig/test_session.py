from pathlib import Path

import numpy as np
import pytest

from rig import CameraModel, Frame, ImuSample, InputError, Scan
from rig.session import DEFAULT_TOPICS, SESSION_METADATA, SessionReader, SessionWriter

CAMERA = CameraModel("pinhole", 64, 48, [[60, 0, 32], [0, 60, 24], [0, 0, 1]], [0.01, -0.02, 0.0, 0.0, 0.001])


def make_frame(i: int) -> Frame:
    rng = np.random.default_rng(i)
    image = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
    return Frame(
        image, t_host=1_000_000_000 + i * 33_333_333, t_device=5_000 + i * 33_333_000, camera_id="cam"
    )


def make_scan(i: int) -> Scan:
    rng = np.random.default_rng(100 + i)
    n = 500
    return Scan(
        rng.normal(size=(n, 3)).astype(np.float32),
        np.sort(rng.uniform(0, 0.1, n)).astype(np.float32),
        rng.uniform(0, 255, n).astype(np.float32),
        t_host=1_000_000_000 + i * 100_000_000,
        t_device=None,
        lidar_id="lidar",
    )


def write_session(path: Path, frames: int = 6, scans: int = 3) -> None:
    with SessionWriter(
        path, metadata={"rig": {"camera": "sim"}}, image_format="png", chunk_size=64 << 10
    ) as w:
        w.write_camera_info(CAMERA, t_host=1_000_000_000, t_device=5_000)
        for i in range(frames):
            w.write_frame(make_frame(i))
        for i in range(scans):
            w.write_scan(make_scan(i))
        w.write_imu(ImuSample(np.array([0.1, 0.2, 0.3]), np.array([0.0, 0.0, 9.81]), 1_000_000_123, 777))


def test_session_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    write_session(path)
    reader = SessionReader(path)
    frames = list(reader.frames(DEFAULT_TOPICS["image"]))
    assert len(frames) == 6
    for i, frame in enumerate(frames):
        expected = make_frame(i)
        assert np.array_equal(frame.image, expected.image)  # png is lossless
        assert (frame.t_host, frame.t_device) == (expected.t_host, expected.t_device)
    scans = list(reader.scans(DEFAULT_TOPICS["points"]))
    for i, scan in enumerate(scans):
        expected = make_scan(i)
        assert np.array_equal(scan.points, expected.points)
        assert np.array_equal(scan.intensity, expected.intensity)
        assert np.abs(scan.point_time_s - expected.point_time_s).max() < 1e-8
        assert scan.t_host == expected.t_host and scan.t_device is None
    (imu,) = reader.imu(DEFAULT_TOPICS["imu"])
    assert imu.t_device == 777 and imu.t_host == 1_000_000_123
    np.testing.assert_array_equal(imu.linear_acceleration, [0.0, 0.0, 9.81])
    camera = reader.camera_model(DEFAULT_TOPICS["camera_info"])
    np.testing.assert_array_equal(camera.K, CAMERA.K)
    np.testing.assert_array_equal(camera.dist, CAMERA.dist)
    assert reader.metadata()[SESSION_METADATA]["rig"] == {"camera": "sim"}
    topics = reader.topics()
    assert topics[DEFAULT_TOPICS["image"]].count == 6
    assert topics[DEFAULT_TOPICS["points"]].msgtype == "sensor_msgs/msg/PointCloud2"
    assert not reader.truncated


def test_truncated_session_reads_complete_chunks(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    write_session(path, frames=60, scans=0)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    reader = SessionReader(cut)
    frames = list(reader.frames(DEFAULT_TOPICS["image"]))
    assert reader.truncated
    assert 10 < len(frames) < 60
    for i, frame in enumerate(frames):
        assert np.array_equal(frame.image, make_frame(i).image)


def test_jpeg_frames_are_close(tmp_path: Path) -> None:
    path = tmp_path / "j.mcap"
    image = np.tile(np.linspace(0, 255, 64, dtype=np.uint8)[None, :, None], (48, 1, 3))
    with SessionWriter(path) as w:
        w.write_frame(Frame(image, 1, 2, "cam"))
    (frame,) = SessionReader(path).frames(DEFAULT_TOPICS["image"])
    assert np.abs(frame.image.astype(int) - image).mean() < 2.0


def test_not_an_mcap_file_is_a_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    path.write_bytes(b"hello world, not mcap")
    with pytest.raises(InputError, match="not an MCAP file"):
        SessionReader(path)
    with pytest.raises(InputError, match="no such session file"):
        SessionReader(tmp_path / "missing.mcap")
