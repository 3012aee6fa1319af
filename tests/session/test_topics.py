"""Each role's topic of a session, found by message type (rig.session.find_topics)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rig.errors import InputError
from rig.messages import Frame, ImuSample, Scan
from rig.session import DEFAULT_TOPICS, SessionReader, SessionWriter, find_topics


def _session(path: Path, images: list[str], clouds: list[str], imus: list[str]) -> SessionReader:
    writer = SessionWriter(path)
    for topic in images:
        writer.write_frame(Frame(np.zeros((4, 6, 3), dtype=np.uint8), 1_000, None, "camera"), topic)
    for topic in clouds:
        points = np.zeros((2, 3), dtype=np.float32)
        writer.write_scan(
            Scan(points, np.zeros(2, np.float32), np.zeros(2, np.float32), 1_000, None, "l"), topic
        )
    for topic in imus:
        writer.write_imu(ImuSample(np.zeros(3), np.zeros(3), 1_000, None, "imu"), topic)
    writer.close()
    return SessionReader(path)


def test_unique_topics_are_found_whatever_their_names(tmp_path: Path) -> None:
    reader = _session(tmp_path / "s.mcap", ["/cam/image/compressed"], ["/os/points"], ["/cam/imu"])
    topics = find_topics(reader)
    assert (topics.image, topics.points, topics.camera_info) == ("/cam/image/compressed", "/os/points", None)
    assert topics.imu is None  # an IMU is taken by its default name only: a camera's IMU is not the LiDAR's


def test_the_default_topic_wins_among_several_and_a_choice_must_exist(tmp_path: Path) -> None:
    reader = _session(
        tmp_path / "s.mcap", [DEFAULT_TOPICS["image"]], [DEFAULT_TOPICS["points"], "/scan2d/points"], []
    )
    assert find_topics(reader).points == DEFAULT_TOPICS["points"]
    assert find_topics(reader, points="/scan2d/points").points == "/scan2d/points"
    with pytest.raises(InputError, match="no point cloud topic '/nope'"):
        find_topics(reader, points="/nope")
    with pytest.raises(InputError, match="no IMU topic '/imu/data'"):
        find_topics(reader, imu="/imu/data")


def test_ambiguous_or_missing_topics_are_named(tmp_path: Path) -> None:
    reader = _session(tmp_path / "s.mcap", ["/a/image", "/b/image"], [], [DEFAULT_TOPICS["imu"]])
    candidates = r"found 2: /a/image \(sensor_msgs/msg/CompressedImage, 1 messages\), /b/image \("
    with pytest.raises(InputError, match=rf"expected one image topic, {candidates}.*--topics image=TOPIC"):
        find_topics(reader)
    topics = find_topics(reader, image="/b/image", require_points=False)
    assert (topics.image, topics.points, topics.imu) == ("/b/image", None, DEFAULT_TOPICS["imu"])
    with pytest.raises(InputError, match=r"one point cloud topic, found none \(the recording has: /a"):
        find_topics(reader, image="/b/image")
