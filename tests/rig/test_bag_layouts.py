"""The test-support bag writer: every layout opens with rosbags and reads back as the session."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from bag_layouts import BASE_FRAME, DELAY_NS, LAYOUTS, SPLIT_PARTS, TF_STATIC, write_layout
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from rig.calibration import load_calibration
from rig.session import DEFAULT_TOPICS, SessionReader
from rig.session import ros_messages as rm
from rig.transforms import from_quaternion, invert

JPEG_LAYOUTS = ("utmm", "utmm_split", "velodyne_ros2_mcap")


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A quick virtual-rig session and its decoded frames, scans, IMU samples and camera."""
    from rig.sim.config import SimConfig
    from rig.sim.simulate import simulate

    out = tmp_path_factory.mktemp("quick_session")
    simulate(SimConfig().quick(), out)
    reader = SessionReader(out / "session.mcap")
    return {
        "path": out / "session.mcap",
        "image": list(reader.frames(DEFAULT_TOPICS["image"])),
        "points": list(reader.scans(DEFAULT_TOPICS["points"])),
        "imu": list(reader.imu(DEFAULT_TOPICS["imu"])),
        "camera": reader.camera_model(DEFAULT_TOPICS["camera_info"]),
        "T_cam_lidar": load_calibration(out / "ground_truth" / "calib.yaml").T_cam_lidar,
    }


def bag_paths(recording: Path, layout: str) -> list[Path]:
    return sorted(recording.glob("*.bag")) if LAYOUTS[layout].storage == "split" else [recording]


def read_back(paths: list[Path], layout: str) -> dict[str, list[tuple[int, Any, Any]]]:
    """Per role: ``(receive time, header frame id, converted message)`` of every message; role
    ``tf`` holds the /tf_static messages."""
    role_of = {topic: role for role, topic in LAYOUTS[layout].topics.items()} | {TF_STATIC: "tf"}
    out: dict[str, list[tuple[int, Any, Any]]] = {role: [] for role in role_of.values()}
    with AnyReader(paths, default_typestore=rm.typestore()) as reader:
        for connection, t_log, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            role, topic = role_of[connection.topic], connection.topic
            if role == "tf":
                out[role].append((t_log, None, msg))
                continue
            stamp = rm.stamp_ns(msg)
            if role == "image":
                value: Any = rm.msg_to_frame(msg, connection.msgtype, t_log, stamp, topic)
            elif role == "points":
                value = rm.msg_to_scan(msg, t_log, stamp, topic)
            elif role == "imu":
                value = rm.msg_to_imu(msg, t_log, stamp, topic)
            else:
                value = rm.msg_to_camera(msg)
            out[role].append((t_log, msg.header.frame_id, value))
    return out


def tf_T_cam_lidar(tf_msg: Any, camera_frame: str, lidar_frame: str) -> np.ndarray:
    """``T_cam_lidar`` from a /tf_static message whose transforms all hang off ``base_link``."""
    T_base = {}
    for t in tf_msg.transforms:
        assert t.header.frame_id == BASE_FRAME
        q, p = t.transform.rotation, t.transform.translation
        T_base[t.child_frame_id] = from_quaternion(np.array([q.x, q.y, q.z, q.w]), np.array([p.x, p.y, p.z]))
    return invert(T_base[camera_frame]) @ T_base[lidar_frame]


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_layout_reads_back_as_the_session(layout: str, session: dict[str, Any], tmp_path: Path) -> None:
    spec = LAYOUTS[layout]
    recording = write_layout(session["path"], tmp_path, layout)
    got = read_back(bag_paths(recording, layout), layout)

    frames = got["image"]
    assert len(frames) == len(session["image"])
    for (t_log, frame_id, frame), native in zip(frames, session["image"], strict=True):
        assert frame.t_device == native.t_host  # header stamps are the native host stamps
        assert t_log == native.t_host + DELAY_NS["image"]
        assert frame_id == spec.frame_ids["camera"]
        expected = native.image
        if frame.encoding == "mono8":
            expected = cv2.cvtColor(native.image, cv2.COLOR_BGR2GRAY)
        difference = np.abs(frame.image.astype(int) - expected.astype(int))
        if layout in JPEG_LAYOUTS:
            assert difference.mean() < 4.0  # JPEG quality 95 of a noisy 160x120 image
        else:
            assert difference.max() == 0

    scans = got["points"]
    assert len(scans) == len(session["points"])
    for (t_log, frame_id, scan), native in zip(scans, session["points"], strict=True):
        assert scan.t_device == native.t_host
        assert t_log == native.t_host + DELAY_NS["points"]
        assert frame_id == spec.frame_ids["lidar"]
        np.testing.assert_array_equal(scan.points, native.points)
        np.testing.assert_allclose(scan.point_time_s, native.point_time_s, rtol=0, atol=1e-7)

    imu = got["imu"]
    assert len(imu) == len(session["imu"])
    for (t_log, frame_id, sample), native in zip(imu, session["imu"], strict=True):
        assert (sample.t_device, t_log, frame_id) == (
            native.t_host,
            native.t_host + DELAY_NS["imu"],
            spec.frame_ids["imu"],
        )
        np.testing.assert_array_equal(sample.angular_velocity, native.angular_velocity)
        np.testing.assert_array_equal(sample.linear_acceleration, native.linear_acceleration)

    assert len(got["camera_info"]) == len(frames)
    camera = got["camera_info"][0][2]
    np.testing.assert_array_equal(camera.K, session["camera"].K)
    np.testing.assert_array_equal(camera.dist, session["camera"].dist)

    (tf,) = got["tf"]
    T = tf_T_cam_lidar(tf[2], spec.frame_ids["camera"], spec.frame_ids["lidar"])
    np.testing.assert_allclose(T, session["T_cam_lidar"], atol=1e-12)


def test_split_bags_each_open_alone_in_time_order(session: dict[str, Any], tmp_path: Path) -> None:
    paths = bag_paths(write_layout(session["path"], tmp_path, "utmm_split"), "utmm_split")
    assert len(paths) == SPLIT_PARTS
    spans = []
    for i, path in enumerate(paths):
        with AnyReader([path], default_typestore=rm.typestore()) as reader:
            topics = {c.topic for c in reader.connections}
            assert (TF_STATIC in topics) == (i == 0)
            image = [c for c in reader.connections if c.topic == LAYOUTS["utmm_split"].topics["image"]]
            times = [t for _, t, _ in reader.messages(connections=image)]
            spans.append((min(times), max(times)))
    assert all(a[1] < b[0] for a, b in pairwise(spans))


def test_livox_sqlite_bag_has_no_definitions_like_humble(session: dict[str, Any], tmp_path: Path) -> None:
    """A reader must bring the Livox types itself: the bag does not define them."""
    recording = write_layout(session["path"], tmp_path, "livox_ros2")
    with AnyReader([recording], default_typestore=rm.typestore()) as reader:
        assert all(not c.msgdef for c in reader.connections)
    with AnyReader([recording], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        lidar = [c for c in reader.connections if c.msgtype == "livox_ros_driver2/msg/CustomMsg"]
        _, _, raw = next(reader.messages(connections=lidar))
        with pytest.raises(KeyError):
            reader.deserialize(raw, lidar[0].msgtype)
