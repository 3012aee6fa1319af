"""Topic maps (role=topic pairs, YAML files, presets, auto) and how they choose a recording's topics."""

from __future__ import annotations

from pathlib import Path

import pytest
from bag_layouts import LAYOUTS

from rig.errors import InputError
from rig.session import UT_MM_TOPICS, find_topics, open_recording, parse_topic_map
from rig.session.topic_map import NEWER_COLLEGE_TOPICS
from tests.session.ros1_bags import cloud, image, write_ros1_bag

T0 = 1_700_000_000_000_000_000


def test_the_forms_of_a_topic_map(tmp_path: Path) -> None:
    assert parse_topic_map("auto") == parse_topic_map(None) == {}
    assert parse_topic_map("ut-mm") == UT_MM_TOPICS
    assert parse_topic_map("image=/cam/image_raw/compressed, points=/os_cloud_node/points") == {
        "image": "/cam/image_raw/compressed",
        "points": "/os_cloud_node/points",
    }
    yaml_map = tmp_path / "topics.yaml"
    yaml_map.write_text("image: /cam/image\nimu: /imu\n")
    assert parse_topic_map(str(yaml_map)) == {"image": "/cam/image", "imu": "/imu"}


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("lidar=/points", "unknown role.s. lidar; expected some of image, camera_info, points, imu"),
        ("image=", "expected ROLE=TOPIC pairs"),
        ("nowhere", "unknown topic map 'nowhere': expected ROLE=TOPIC pairs, a YAML file, a preset"),
    ],
)
def test_a_bad_topic_map_is_one_line(spec: str, message: str) -> None:
    with pytest.raises(InputError, match=message):
        parse_topic_map(spec)


def test_a_yaml_map_with_an_unknown_role_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "topics.yaml"
    path.write_text("cam: /cam/image\n")
    with pytest.raises(InputError, match=rf"{path}: unknown role\(s\) cam"):
        parse_topic_map(str(path))


@pytest.mark.parametrize(("layout", "preset"), [("utmm", "ut-mm"), ("newer_college", "newer-college")])
def test_the_presets_name_the_layouts_topics(layout: str, preset: str, layout_bags: dict) -> None:
    recording = open_recording(layout_bags[layout], topic_map=parse_topic_map(preset))
    topics = find_topics(recording)
    assert {role: getattr(topics, role) for role in LAYOUTS[layout].topics} == LAYOUTS[layout].topics
    assert set(NEWER_COLLEGE_TOPICS.items()) <= set(LAYOUTS["newer_college"].topics.items())


def test_a_map_naming_a_missing_topic_lists_what_the_bag_has(layout_bags: dict) -> None:
    bag = layout_bags["utmm"]
    recording = open_recording(bag, topic_map={"points": "/velodyne_points"})
    with pytest.raises(InputError) as caught:
        find_topics(recording)
    text = str(caught.value)
    assert text.startswith(f"{bag}: points: no point cloud topic '/velodyne_points'; the recording has: ")
    assert "/ouster/points (sensor_msgs/msg/PointCloud2, 30 messages)" in text
    wrong_type = open_recording(bag, topic_map={"image": "/ouster/imu"})
    with pytest.raises(InputError, match="/ouster/imu holds sensor_msgs/msg/Imu; the image role expects"):
        find_topics(wrong_type)


def _two_cameras(path: Path) -> Path:
    messages = [
        (topic, T0 + i * 100_000_000 + k, image(T0 + i * 100_000_000))
        for i in range(3)
        for k, topic in enumerate(["/left/image_raw", "/right/image_raw"])
    ]
    messages += [("/os/points", T0 + 5, cloud(T0))]
    return write_ros1_bag(path, sorted(messages, key=lambda m: m[1]))


def test_auto_lists_each_candidate_and_an_option_or_the_map_chooses(tmp_path: Path) -> None:
    bag = _two_cameras(tmp_path / "two.bag")
    with pytest.raises(InputError) as caught:
        find_topics(open_recording(bag))
    assert str(caught.value) == (
        f"{bag}: image: expected one image topic, found 2: /left/image_raw (sensor_msgs/msg/Image, "
        "3 messages), /right/image_raw (sensor_msgs/msg/Image, 3 messages); choose with --topics image=TOPIC"
    )
    mapped = open_recording(bag, topic_map={"image": "/right/image_raw"})
    assert find_topics(mapped).image == "/right/image_raw"
    assert find_topics(mapped, image="/left/image_raw").image == "/left/image_raw"  # an option wins


def test_camera_info_and_imu_are_paired_by_namespace() -> None:
    from rig.session.topics import _nearest

    infos = ["/cam_a/camera_info", "/realsense/color/camera_info", "/realsense/depth/camera_info"]
    assert _nearest(infos, "/realsense/color/image_raw/compressed", unique=False) == infos[1]
    imus = ["/camera/imu", "/ouster/imu"]
    assert _nearest(imus, "/ouster/points", unique=True) == "/ouster/imu"
    assert _nearest(imus, "/velodyne_points", unique=True) is None  # no IMU shares its namespace
    assert _nearest(["/a/imu", "/a/imu2"], "/a/points", unique=True) is None  # a tie is no choice
