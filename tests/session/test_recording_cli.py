"""The offline commands on bags, run as installed: rig info, lts calibrate / slam run / prepare
with --topics, --start, --duration and --calib tf; bad input is one line naming the file, the topic
and what was expected, with exit status 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.session.ros1_bags import cloud, image, write_ros1_bag

BIN = Path(sys.executable).parent
T0 = 1_700_000_000_000_000_000


def run(*args: object, timeout: float = 300) -> subprocess.CompletedProcess:
    command, *rest = args
    return subprocess.run(
        [BIN / str(command), *map(str, rest)], capture_output=True, text=True, timeout=timeout
    )


def one_line_error(result: subprocess.CompletedProcess, *parts: str) -> str:
    """The error line of a command that refused its input (exit 2, no traceback); each of ``parts`` in it."""
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    (line,) = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    for part in parts:
        assert part in line, (part, line)
    return line


def test_rig_info_on_split_bags_says_where_times_come_from_and_which_topic_plays_which_role(
    layout_bags: dict,
) -> None:
    result = run("rig", "info", layout_bags["utmm_split"], "--json", "--topics", "ut-mm", "--start", "1")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    assert info["format"] == "ROS 1 bag" and info["finished"] is None
    assert info["roles"]["points"] == "/ouster/points" and info["roles"]["imu"] == "/ouster/imu"
    assert info["topics"]["/ouster/points"]["count"] == 20  # 10 Hz, from 1 s to the end at 3 s
    assert "stamps" in info["topics"]["/ouster/points"]


def test_prepare_reads_a_bag_with_its_own_calibration(
    layout_bags: dict, virtual_rig_scene: Path, tmp_path
) -> None:
    slam = tmp_path / "slam"
    slam.mkdir()
    truth = virtual_rig_scene / "ground_truth"
    (slam / "mesh.ply").write_bytes((truth / "mesh.ply").read_bytes())
    (slam / "trajectory.tum").write_bytes((truth / "trajectory_lidar.tum").read_bytes())
    scene = tmp_path / "scene"
    result = run(
        "lts", "prepare", layout_bags["livox_ros2"], "--calib", "tf", "--slam", slam, "--out", scene,
        "--topics", "image=/camera/image_raw,points=/livox/lidar", "--duration", "2", "--json",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["keyframes"] >= 3
    assert "/camera/image_raw: times from" in result.stderr  # the stamp source, once per topic
    assert json.loads((scene / "scene.json").read_text())["source"]["session"] == str(
        layout_bags["livox_ros2"]
    )


def test_calibrate_starts_from_tf_static_without_init(layout_bags: dict, tmp_path: Path) -> None:
    result = run("lts", "calibrate", layout_bags["newer_college"], "--out", tmp_path / "calib.yaml", "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["extrinsic_init"] == "/tf_static (os1_lidar -> camera_infra1_optical_frame)"
    assert report["extrinsic"]["verdict"] != "not run"


def _points_only(path: Path, stamps: list[int]) -> Path:
    return write_ros1_bag(
        path, [("/os/points", T0 + i * 100_000_000, cloud(s)) for i, s in enumerate(stamps)]
    )


def test_bad_recordings_are_one_line_errors(layout_bags: dict, tmp_path: Path) -> None:
    one_line_error(
        run("lts", "slam", "run", tmp_path / "nope.bag", "--out", tmp_path / "s"), "nope.bag", "no such"
    )
    cut = tmp_path / "cut.bag"
    data = layout_bags["utmm"].read_bytes()
    cut.write_bytes(data[: len(data) * 6 // 10])
    one_line_error(run("rig", "info", cut), str(cut), "cannot read the ROS 1 bag", "rosbag reindex")
    no_images = _points_only(tmp_path / "points.bag", [T0 + i for i in range(3)])
    one_line_error(
        run("lts", "calibrate", no_images, "--out", tmp_path / "c.yaml"),
        f"{no_images}: image: expected one image topic, found none",
        "/os/points (sensor_msgs/msg/PointCloud2, 3 messages)",
    )
    zero = _points_only(tmp_path / "zero.bag", [T0, 0, T0 + 2])
    one_line_error(
        run("lts", "slam", "run", zero, "--out", tmp_path / "s"),
        f"{zero}: /os/points: header stamp of message 2 is zero",
    )


def test_bad_topic_maps_are_one_line_errors(layout_bags: dict, tmp_path: Path) -> None:
    bag = layout_bags["velodyne_ros2_mcap"]
    one_line_error(
        run("lts", "slam", "run", bag, "--out", tmp_path / "s", "--topics", "points=/os_cloud_node/points"),
        f"{bag}: points: no point cloud topic '/os_cloud_node/points'; the recording has:",
        "/velodyne_points (sensor_msgs/msg/PointCloud2, 30 messages)",
    )
    one_line_error(
        run("rig", "info", bag, "--topics", "lidar=/velodyne_points"), "--topics: unknown role(s) lidar"
    )
    two = write_ros1_bag(
        tmp_path / "two.bag",
        [("/a/image", T0, image(T0)), ("/b/image", T0 + 1, image(T0 + 1)), ("/p", T0 + 2, cloud(T0 + 2))],
    )
    one_line_error(
        run("lts", "calibrate", "time", two),
        "expected one image topic, found 2: /a/image (sensor_msgs/msg/Image, 1 messages), /b/image",
        "--topics image=TOPIC",
    )


@pytest.mark.parametrize(
    "command", ["info", "calibrate session", "calibrate time", "slam run", "prepare", "reconstruct"]
)
def test_every_recording_command_documents_bags_topics_and_span(command: str) -> None:
    app = "rig" if command == "info" else "lts"
    result = run(app, *command.split(), "--help", timeout=60)
    text = " ".join(result.stdout.split())
    assert result.returncode == 0, result.stderr
    for part in ("--topics", "--start", "--duration", "ROS 1 .bag", "header stamp", "preset"):
        assert part in text, (command, part)


def test_unreadable_messages_are_one_line_errors(tmp_path: Path) -> None:
    from rig.session.livox_messages import register_livox_types
    from tests.session.ros1_bags import STORE, TYPES, header

    yuv = image(T0)
    yuv.encoding = "yuv422"
    bag = write_ros1_bag(
        tmp_path / "yuv.bag", [("/cam/image", T0, yuv), ("/os/points", T0 + 1, cloud(T0 + 1))]
    )
    one_line_error(
        run("lts", "calibrate", bag, "--out", tmp_path / "c.yaml"),
        str(bag),
        "/cam/image",
        "unsupported image encoding 'yuv422'",
    )
    register_livox_types(STORE)
    point = TYPES["livox_ros_driver/msg/CustomPoint"](
        offset_time=0, x=1.0, y=2.0, z=3.0, reflectivity=10, tag=0, line=0
    )
    livox = TYPES["livox_ros_driver/msg/CustomMsg"](
        header=header(T0, "livox_frame"),
        timebase=T0,
        point_num=2,
        lidar_id=0,
        rsvd=np.zeros(3, dtype=np.uint8),
        points=[point],
    )
    bag = write_ros1_bag(tmp_path / "livox.bag", [("/livox/lidar", T0, livox)])
    one_line_error(
        run("lts", "slam", "run", bag, "--out", tmp_path / "s"), str(bag), "/livox/lidar", "point_num=2"
    )


def test_a_bad_init_stops_reconstruct_before_any_stage(layout_bags: dict, tmp_path: Path) -> None:
    rough = tmp_path / "rough.yaml"
    rough.write_text("T_cam_lidar: [1, 2]\n")
    result = run("lts", "reconstruct", layout_bags["utmm"], "--init", rough, "--out", tmp_path / "run")
    one_line_error(result, str(rough), "camera: missing")
    assert "[calibrate]" not in result.stderr and not (tmp_path / "run").exists()
