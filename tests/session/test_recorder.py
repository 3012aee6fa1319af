"""Threaded recorder: bounded queue with counted drops, disk-full stop, status records; recover; replay."""

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from rig import ImuSample, InputError
from rig.session import SessionReader
from rig.session.info import session_info
from rig.session.recorder import STATUS_METADATA, SessionRecorder
from rig.session.recover import recover
from rig.session.replay import replay


def imu(i: int) -> ImuSample:
    return ImuSample(np.zeros(3), np.array([0.0, 0.0, 9.81]), 1_000_000_000 + i * 5_000_000, i)


@pytest.mark.parametrize("policy", ["drop-newest", "drop-oldest"])
def test_full_queue_drops_by_policy_and_counts(tmp_path: Path, policy: str) -> None:
    gate = threading.Event()
    rec = SessionRecorder(tmp_path / "s.mcap", queue_size=8, policy=policy)
    original = rec._write
    rec._write = lambda item: (gate.wait(5), original(item))  # a disk that cannot keep up
    accepted = [rec.put(imu(i), "/imu", "imu") for i in range(100)]
    assert rec.queue_depth() <= 8
    gate.set()
    rec.close()
    stats = rec.stats()
    assert stats["written"]["/imu"] + stats["dropped"]["/imu"] == 100
    assert stats["dropped"]["/imu"] >= 100 - 8 - 1
    if policy == "drop-newest":
        assert accepted[:8] == [True] * 8 and not any(accepted[10:])
    else:
        assert all(accepted)
    reader = SessionReader(tmp_path / "s.mcap")
    assert reader.topics()["/imu"].count == stats["written"]["/imu"]
    assert reader.metadata()[STATUS_METADATA]["recorder"]["dropped"] == {"/imu": stats["dropped"]["/imu"]}
    if policy == "drop-oldest":  # the newest survive
        assert max(m.t_device for m in reader.messages()) == 99


def test_disk_full_stops_with_clear_message_and_valid_file(tmp_path: Path) -> None:
    free = {"bytes": 10**9}
    rec = SessionRecorder(
        tmp_path / "s.mcap", chunk_size=4096, min_free_bytes=1 << 20, disk_free=lambda p: free["bytes"]
    )
    for i in range(200):
        rec.put(imu(i), "/imu", "imu")
    deadline = time.monotonic() + 5
    while rec.stats()["written"].get("/imu", 0) < 200 and time.monotonic() < deadline:
        time.sleep(0.01)
    free["bytes"] = 1000  # the disk fills up
    i = 200
    while rec.recording and time.monotonic() < deadline:
        rec.put(imu(i), "/imu", "imu")
        i += 1
        time.sleep(0.001)
    assert not rec.recording
    assert "disk almost full" in rec.error
    assert not rec.put(imu(i), "/imu", "imu")
    rec.close()
    info = session_info(tmp_path / "s.mcap")
    assert not info["truncated"] and info["finished"]
    assert info["topics"]["/imu"]["count"] >= 200
    assert "disk almost full" in info["errors"]["write_error"]


def test_truncated_file_recover_and_replay(tmp_path: Path) -> None:
    path = tmp_path / "s.mcap"
    rec = SessionRecorder(path, chunk_size=2048)
    for i in range(400):  # 2 s of 200 Hz IMU
        rec.put(imu(i), "/imu", "imu")
    rec.close()
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    info = session_info(cut)
    assert info["truncated"] and 0 < info["messages"] < 400
    fixed = tmp_path / "fixed.mcap"
    result = recover(cut, fixed)
    assert result["truncated"] and result["messages"] == info["messages"]
    fixed_info = session_info(fixed)
    assert not fixed_info["truncated"] and fixed_info["topics"] == info["topics"]
    with pytest.raises(InputError):
        recover(cut, cut)

    seen = []
    fast = replay(fixed, seen.append, rate=0)
    assert fast["messages"] == len(seen) == info["messages"]
    assert [m.t_device for m in seen] == list(range(len(seen)))
    timed = replay(path, lambda m: None, rate=10.0)  # 2 s of data at 10x: about 0.2 s
    assert timed["messages"] == 400
    assert 0.19 <= timed["wall_s"] < 0.6 and timed["span_s"] == pytest.approx(1.995)


def test_a_camera_whose_frames_all_come_at_the_drain_still_gets_its_camera_info(tmp_path: Path) -> None:
    """A camera that holds its frames back until its clock fit holds (rig.clock.HostStamper)
    releases them all at the end of a short recording: the camera model is written with the
    first of them as with a frame read during the recording (rig record --duration 0.5 wrote 17
    frames and no camera_info)."""
    from rig import CameraModel, Frame
    from rig.drivers.base import Driver
    from rig.record import Recording, Source

    class HeldBack(Driver):
        def open(self) -> None: ...
        def close(self) -> None: ...

        def read(self, timeout_s: float = 0.1) -> list:
            time.sleep(timeout_s)
            return []

        def drain(self) -> list:
            image = np.zeros((4, 6, 3), np.uint8)
            return [Frame(image, 1_000_000_000 + i * 33_000_000, i, "camera") for i in range(3)]

    K = np.array([[5.0, 0.0, 3.0], [0.0, 5.0, 2.0], [0.0, 0.0, 1.0]])
    camera = CameraModel("pinhole", 6, 4, K, np.zeros(5))
    topics = {"image": "/camera/image", "camera_info": "/camera/camera_info"}
    out = tmp_path / "held.mcap"
    summary = Recording([Source(HeldBack("camera"), topics, camera)], out).run(0.3, threading.Event())
    assert summary["written"] == {"/camera/camera_info": 1, "/camera/image": 3}
    assert SessionReader(out).camera_model("/camera/camera_info").size == (6, 4)
