"""Others' recordings read in place with the interface of our sessions: every bag layout gives
the session's frames, sweeps and IMU samples; split bags read as one; a bare MCAP file; a time span."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from bag_layouts import LAYOUTS

from rig.session import BagRecording, SessionReader, TimeSpan, find_topics, open_recording


def _native(scene: Path) -> SessionReader:
    return SessionReader(scene / "session.mcap")


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_every_layout_reads_as_the_session(layout: str, layout_bags: dict, virtual_rig_scene: Path) -> None:
    recording = open_recording(layout_bags[layout])
    assert isinstance(recording, BagRecording)
    topics = find_topics(recording)
    assert {role: getattr(topics, role) for role in LAYOUTS[layout].topics} == LAYOUTS[layout].topics
    native = _native(virtual_rig_scene)
    native_topics = find_topics(native)
    for read in ("frames", "scans", "imu"):
        role = {"frames": "image", "scans": "points", "imu": "imu"}[read]
        got = list(getattr(recording, read)(getattr(topics, role)))
        want = list(getattr(native, read)(getattr(native_topics, role)))
        assert len(got) == len(want) > 0
        # timed by the header stamps (the native host stamps), not the later receive times
        assert [g.t_host for g in got] == [w.t_host for w in want], read
        if read == "scans":
            assert [len(g.points) for g in got] == [len(w.points) for w in want]
        if read == "frames":
            assert got[0].image.shape[:2] == want[0].image.shape[:2]
            assert got[0].encoding == ("mono8" if layout == "newer_college" else "bgr8")
    assert (
        recording.camera_model(topics.camera_info).size == native.camera_model(native_topics.camera_info).size
    )


def test_split_bags_read_as_one_recording(layout_bags: dict) -> None:
    folder = layout_bags["utmm_split"]
    parts = sorted(folder.glob("*.bag"))
    assert len(parts) == 3
    whole = [(m.topic, m.t_host) for m in open_recording(layout_bags["utmm"]).messages()]
    for paths in (folder, parts, parts[::-1]):  # merged in time order, whatever the order given
        assert [(m.topic, m.t_host) for m in open_recording(paths).messages()] == whole
    assert open_recording(folder).path == parts[0]


def test_a_bare_mcap_file_reads_like_its_rosbag2_folder(layout_bags: dict, tmp_path: Path) -> None:
    folder = layout_bags["velodyne_ros2_mcap"]
    (storage,) = folder.glob("*.mcap")
    assert open_recording(storage).path == folder  # a storage file in its folder opens the folder
    bare = tmp_path / "others.mcap"
    shutil.copyfile(storage, bare)
    recording = open_recording(bare)
    assert recording.format == "MCAP" and not recording.truncated
    assert recording.topic_types() == open_recording(folder).topic_types()
    got = sorted((m.t_host, m.topic) for m in recording.messages())  # file order breaks ties otherwise
    assert got == sorted((m.t_host, m.topic) for m in open_recording(folder).messages())
    topics = find_topics(recording)
    assert recording.camera_model(topics.camera_info).size == (160, 120)


def test_a_time_span_is_what_every_reader_sees(layout_bags: dict, virtual_rig_scene: Path) -> None:
    span = TimeSpan(1.0, 1.0)
    for recording in (
        open_recording(layout_bags["utmm"], span=span),
        SessionReader(virtual_rig_scene / "session.mcap", span=span),
    ):
        topics = find_topics(recording)
        frames = list(recording.frames(topics.image))
        everything = open_recording(recording.path)
        first = min(s.first_t for s in everything.topics().values())
        assert 28 <= len(frames) <= 31  # 30 Hz for one second
        assert recording.topic_types()[topics.image][1] == len(frames)
        assert all(first + 0.99e9 <= f.t_host <= first + 2.01e9 for f in frames)
        assert recording.camera_model(topics.camera_info).size == (160, 120)


def test_a_span_past_the_end_says_so(layout_bags: dict) -> None:
    from rig.errors import InputError

    recording = open_recording(layout_bags["utmm"], span=TimeSpan(100.0))
    with pytest.raises(InputError, match="no messages within --start 100"):
        find_topics(recording)
