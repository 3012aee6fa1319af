"""The time of a bag message: header stamp when sane, receive time otherwise, refusal when the
stamps are zero or go backwards (rig.session.stamps through BagRecording)."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from rig.errors import InputError
from rig.session import open_recording
from tests.session.ros1_bags import cloud, image, text, write_ros1_bag

T0 = 1_700_000_000_000_000_000
MS = 1_000_000


def _bag(path: Path, image_stamps: list[int], delay: int = 7 * MS) -> Path:
    """Images stamped ``image_stamps`` received ``delay`` after T0 + 100 ms steps, a cloud and a
    header-less message."""
    messages = [("/cam/image_raw", T0 + i * 100 * MS + delay, image(s)) for i, s in enumerate(image_stamps)]
    messages += [("/lidar/points", T0 + 3 * MS, cloud(T0)), ("/meta", T0 + 1 * MS, text("hello"))]
    return write_ros1_bag(path, sorted(messages, key=lambda m: m[1]))


def test_header_stamps_time_the_messages_and_the_source_is_logged_once(tmp_path: Path, caplog) -> None:
    stamps = [T0 + i * 100 * MS for i in range(5)]
    recording = open_recording(_bag(tmp_path / "a.bag", stamps))
    with caplog.at_level(logging.INFO, logger="rig.session.stamps"):
        got = list(recording.messages(["/cam/image_raw", "/meta"]))
        list(recording.messages(["/cam/image_raw"]))
    assert [m.t_host for m in got if m.topic == "/cam/image_raw"] == stamps
    assert all(m.t_device is None for m in got)
    assert [m.t_host for m in got if m.topic == "/meta"] == [T0 + 1 * MS]  # no header: receive time
    lines = [r.getMessage() for r in caplog.records]
    assert lines.count(f"{tmp_path / 'a.bag'}: /cam/image_raw: times from header stamps") == 1
    assert f"{tmp_path / 'a.bag'}: /meta: times from receive time (no header)" in lines
    summary = recording.topics()
    assert summary["/cam/image_raw"].stamps == "header stamps"
    assert (summary["/cam/image_raw"].first_t, summary["/cam/image_raw"].last_t) == (stamps[0], stamps[-1])
    assert summary["/meta"].stamps == "receive time (no header)"


def test_stamps_from_another_clock_give_way_to_the_receive_time(tmp_path: Path) -> None:
    since_power_on = [12 * 1_000_000_000 + i * 100 * MS for i in range(3)]
    recording = open_recording(_bag(tmp_path / "a.bag", since_power_on))
    frames = list(recording.frames("/cam/image_raw"))
    assert [f.t_host for f in frames] == [T0 + i * 100 * MS + 7 * MS for i in range(3)]
    assert "another clock" in recording.topics()["/cam/image_raw"].stamps


@pytest.mark.parametrize(
    ("stamps", "reason"),
    [
        ([T0, 0, T0 + 200 * MS], "header stamp of message 2 is zero"),
        ([T0, T0 + 200 * MS, T0 + 100 * MS], r"header stamps go backwards at message 3 \(by 100.000 ms\)"),
    ],
)
def test_zero_or_backward_stamps_refuse_the_topic_naming_file_and_topic(
    tmp_path: Path, stamps: list[int], reason: str
) -> None:
    bag = _bag(tmp_path / "bad.bag", stamps)
    recording = open_recording(bag)
    with pytest.raises(InputError, match=reason) as caught:
        list(recording.frames("/cam/image_raw"))
    assert str(caught.value).startswith(f"{bag}: /cam/image_raw: ")
    assert "\n" not in str(caught.value)
    assert recording.topics()["/cam/image_raw"].stamps.startswith(f"refused: {reason[:20]}")
    assert len(list(recording.scans("/lidar/points"))) == 1  # the other topics still read
