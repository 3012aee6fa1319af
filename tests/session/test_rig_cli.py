"""The ``rig`` commands: list, check (against a mock LD06), config errors, replay."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rig import InputError
from rig.mock.serial_lidar import FakeSerialLidar
from rig.record_config import parse_config

BIN = Path(sys.executable).parent


def rig(*args: object, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([BIN / "rig", *map(str, args)], capture_output=True, text=True, timeout=timeout)


def test_list_json_without_devices() -> None:
    result = rig("list", "--json")
    assert result.returncode == 0, result.stderr
    found = json.loads(result.stdout)
    assert found["usb"] == [] and found["oak"] == []  # no USB devices on this machine
    assert isinstance(found["serial_ports"], list)


def test_check_opens_a_mock_ld06_and_reports_health(tmp_path: Path) -> None:
    def revolution(t_rel_ns: int):
        return np.full(450, 3.0), np.full(450, 80.0)

    with FakeSerialLidar(tmp_path / "ttyLD", revolution, "ld06", 10.0) as fake:
        config = tmp_path / "rig.yaml"
        config.write_text(f"devices:\n  - {{name: scan2d, kind: ld06, port: {fake.link}}}\n")
        result = rig("check", "--config", config, "--messages", 2, "--timeout", 5, "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.splitlines()[-1])
    assert report["ok"] and report["devices"]["scan2d"]["messages"] >= 2


def test_check_reports_a_missing_device(tmp_path: Path) -> None:
    config = tmp_path / "rig.yaml"
    config.write_text("devices:\n  - {name: rp, kind: rplidar, port: /dev/does-not-exist}\n")
    result = rig("check", "--config", config, "--json")
    assert result.returncode == 1
    report = json.loads(result.stdout)
    assert not report["ok"] and "/dev/does-not-exist" in report["devices"]["rp"]["error"]


def test_bad_config_is_one_line_naming_the_field(tmp_path: Path) -> None:
    config = tmp_path / "rig.yaml"
    config.write_text("devices:\n  - {name: a, kind: ld06}\n")
    result = rig("record", "--config", config, "--out", tmp_path / "x.mcap", "--duration", 1)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "devices[0]" in result.stderr and "port" in result.stderr
    with pytest.raises(InputError, match=r"devices\[1\]\.kind"):
        parse_config({"devices": [{"name": "a", "kind": "oak"}, {"name": "b", "kind": "velodyne"}]})
    with pytest.raises(InputError, match="unknown option"):
        parse_config({"devices": [{"name": "a", "kind": "livox", "baud": 3}]})
    with pytest.raises(InputError, match=r"recorder\.min_free_mb: expected a positive number, got '1e12'"):
        parse_config({"devices": [{"name": "a", "kind": "oak"}], "recorder": {"min_free_mb": "1e12"}})
    with pytest.raises(InputError, match=r"recorder\.policy"):
        parse_config({"devices": [{"name": "a", "kind": "oak"}], "recorder": {"policy": "drop-all"}})
    cfg = parse_config({"devices": [{"name": "cam", "kind": "oak", "topics": {"image": "/img"}}]})
    assert cfg.devices[0].topics == {"image": "/img", "camera_info": "/cam/camera_info", "imu": "/cam/imu"}
    result = rig("record", "--out", tmp_path / "x.mcap")
    assert result.returncode == 2 and "--config" in result.stderr


def test_info_and_replay_json(tmp_path: Path) -> None:
    from tests.rig.test_session import write_session

    path = tmp_path / "s.mcap"
    write_session(path, frames=4, scans=2)
    report = json.loads(rig("info", path, "--json").stdout)
    assert report["topics"]["/camera/image/compressed"]["count"] == 4
    assert set(report) >= {"topics", "duration_s", "errors", "truncated"}
    result = rig("replay", path, "--rate", 0, "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["messages"] == 4 + 2 + 1 + 1
    missing = rig("info", tmp_path / "nope.mcap")
    assert missing.returncode == 2 and "no such session file" in " ".join(missing.stderr.split())


def test_record_from_config_with_two_serial_lidars(tmp_path: Path) -> None:
    def revolution(t_rel_ns: int):
        return np.full(360, 2.5), np.full(360, 90.0)

    ld = FakeSerialLidar(tmp_path / "ttyLD", revolution, "ld06", 10.0, corrupt_rate=1e-3)
    rp = FakeSerialLidar(tmp_path / "ttyRP", revolution, "rplidar", 5.5)
    out = tmp_path / "rec.mcap"
    with ld, rp:
        config = tmp_path / "rig.yaml"
        config.write_text(
            "devices:\n"
            f"  - {{name: front, kind: ld06, port: {ld.link}}}\n"
            f"  - {{name: back, kind: rplidar, port: {rp.link}, model: a1, topics: {{points: /back/scan}}}}\n"
            "clock: {window_s: 30}\n"
            "recorder: {queue_size: 64, chunk_mb: 0.25}\n"
        )
        result = rig("record", "--config", config, "--out", out, "--duration", 2.5, "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["written"]["/front/points"] >= 12 and summary["written"]["/back/scan"] >= 8
    assert (
        summary["devices"]["front"]["crc_errors"] > 0
        and summary["devices"]["back"]["device_id"] == rp.info.serial
    )
    report = json.loads(rig("info", out, "--json").stdout)
    assert report["session"]["rig_yaml"]["clock"] == {"window_s": 30}
    assert report["topics"]["/back/scan"]["count"] == summary["written"]["/back/scan"]
    assert not report["truncated"] and "warning" not in result.stderr


def test_a_device_that_sends_nothing_is_named_and_the_file_still_valid(tmp_path: Path) -> None:
    config = tmp_path / "rig.yaml"  # a Livox listening where nothing streams
    config.write_text(
        "devices:\n  - {name: lidar, kind: livox, host: 127.0.0.1, point_port: 0, imu_port: 0}\n"
    )
    out = tmp_path / "rec.mcap"
    result = rig("record", "--config", config, "--out", out, "--duration", 0.5)
    assert result.returncode == 0, result.stderr
    lines = result.stderr.strip().splitlines()
    assert lines[-2].startswith("warning: lidar (livox@127.0.0.1:") and "sent nothing in" in lines[-2]
    assert lines[-1] == f"wrote {out}: no messages"
    assert not json.loads(rig("info", out, "--json").stdout)["truncated"]


def test_full_disk_stops_with_a_message_a_valid_file_and_exit_1(tmp_path: Path) -> None:
    def revolution(t_rel_ns: int):
        return np.full(450, 2.0), np.full(450, 90.0)

    out = tmp_path / "full.mcap"
    with FakeSerialLidar(tmp_path / "ttyLD", revolution, "ld06", 10.0) as ld:
        config = tmp_path / "rig.yaml"
        # a reserve larger than any disk: the recorder sees a "full" disk at once
        config.write_text(
            f"devices:\n  - {{name: front, kind: ld06, port: {ld.link}}}\n"
            "recorder: {min_free_mb: 1.0e+12}\n"
        )
        result = rig("record", "--config", config, "--out", out, "--duration", 5, "--json")
    assert result.returncode == 1
    assert "disk almost full" in " ".join(result.stderr.split())
    assert "disk almost full" in json.loads(result.stdout)["error"]
    report = json.loads(rig("info", out, "--json").stdout)
    assert (
        not report["truncated"]
        and report["finished"]
        and "disk almost full" in report["errors"]["write_error"]
    )
