"""``rig record --sim`` end to end: rates, CRC errors, SIGTERM/SIGINT clean finish, SIGKILL salvage."""

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rig.mock.sim_rig import SimRig
from rig.session import recover, session_info
from tests.session.conftest import RATES

BIN = Path(sys.executable).parent


def rig(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([BIN / "rig", *map(str, args)], capture_output=True, text=True, timeout=timeout)


def info(path: Path) -> dict:
    result = rig("info", path, "--json")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def info_here(path: Path) -> dict:
    """``rig info --json`` without a process start (the CLI itself is checked above)."""
    return json.loads(json.dumps(session_info(path)))


def test_record_sim_rates_within_2_percent_and_crc_errors_counted(
    virtual_rig_scene: Path, tmp_path: Path
) -> None:
    out = tmp_path / "s.mcap"
    result = rig(
        "record", "--sim", virtual_rig_scene, "--out", out, "--duration", 5, "--corrupt-rate", 3e-4, "--json"
    )
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    report = info(out)
    assert not report["truncated"] and report["finished"]
    expected = summary["sim"]["expected_rates_hz"]
    assert expected["/camera/image/compressed"] == pytest.approx(RATES["image"])
    assert expected["/imu/data"] == pytest.approx(RATES["imu"])
    for topic, rate in expected.items():
        t = report["topics"][topic]
        span_s = (t["last_t"] - t["first_t"]) / 1e9
        measured = (t["count"] - 1) / span_s
        assert measured == pytest.approx(rate, rel=0.02), (topic, t, measured)
        assert t["count"] >= 0.9 * rate * 5
    errors = report["errors"]
    assert errors["dropped"] == {} and errors["write_error"] is None
    devices = errors["devices"]
    assert all(d["dropped"] == 0 and d["reconnects"] == 0 for d in devices.values()), devices
    corrupted = summary["sim"]["serial_corrupted_packets"]
    assert corrupted > 0 and 0 < devices["scan2d"]["crc_errors"] <= corrupted
    assert report["clock"]["camera"]["n_pairs"] > 100
    assert report["session"]["device_ids"]["camera"] == "FAKE-OAK-0001"
    assert summary["sim"]["shortfalls"] == [] and "warning" not in result.stderr


def test_record_sim_once_records_one_pass_and_stops(virtual_rig_scene: Path, tmp_path: Path) -> None:
    out = tmp_path / "once.mcap"
    result = rig("record", "--sim", virtual_rig_scene, "--once", "--out", out, "--json")
    assert result.returncode == 0, result.stderr
    scene, recorded = info_here(virtual_rig_scene / "session.mcap"), info_here(out)
    for topic in ("/camera/image/compressed", "/lidar/points", "/imu/data"):
        # Every message of the pass, none of a second one (looped stamps would stretch the span).
        assert recorded["topics"][topic]["count"] == scene["topics"][topic]["count"], topic
        span = [
            (t["last_t"] - t["first_t"]) / 1e9 for t in (recorded["topics"][topic], scene["topics"][topic])
        ]
        assert span[0] == pytest.approx(span[1], abs=0.02), (topic, span)
    assert json.loads(result.stdout)["duration_s"] < scene["duration_s"] + 2.0


@pytest.mark.parametrize(
    ("args", "says"),
    [
        ([], "--config/--sim: give exactly one of --config RIG.yaml or --sim SCENE_DIR"),
        (
            ["--config", "rig.yaml", "--once"],
            "--once: plays a simulated scene once; give the scene with --sim SCENE_DIR",
        ),
        (["--sim", "scene", "--duration", "-1"], "--duration: expected seconds > 0, got -1.0"),
    ],
)
def test_record_without_a_source_or_once_without_sim_is_one_line(
    tmp_path: Path, args: list[str], says: str
) -> None:
    result = rig("record", "--out", tmp_path / "s.mcap", *args)
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    assert result.stderr.strip().splitlines() == [f"error: {says}"], result.stderr
    assert not (tmp_path / "s.mcap").exists()


def test_a_topic_the_recorder_wrote_too_little_of_is_named() -> None:
    rig_ = SimRig(scene=None, sources=[], devices=None, oak=None)  # type: ignore[arg-type]
    rig_.expected_rates_hz = {"/lidar/points": 10.0, "/imu/data": 200.0}
    lines = rig_.shortfalls({"/lidar/points": 91, "/imu/data": 4000}, duration_s=20.0)
    assert len(lines) == 1 and lines[0].startswith("/lidar/points: 91 messages in 20.0 s (4.5 Hz)")
    assert "10 Hz" in lines[0]


def test_a_scene_played_once_is_judged_by_what_one_pass_holds() -> None:
    """3 s of scene take longer to record (devices starting, the last messages awaited): its 30
    sweeps in 3.8 s are all the fakes sent, not 79 % of 10 Hz."""
    rig_ = SimRig(scene=None, sources=[], devices=None, oak=None)  # type: ignore[arg-type]
    rig_.expected_rates_hz = {"/lidar/points": 10.0, "/imu/data": 200.0}
    rig_.pass_counts = {"/lidar/points": 30, "/imu/data": 601}
    assert rig_.shortfalls({"/lidar/points": 30, "/imu/data": 601}, duration_s=3.8) == []
    # Half a second of a 10 Hz device holds 4 or 5 messages, by where the first one fell.
    assert rig_.shortfalls({"/lidar/points": 4, "/imu/data": 100}, duration_s=0.53) == []
    lines = rig_.shortfalls({"/lidar/points": 20, "/imu/data": 601}, duration_s=3.8)
    assert len(lines) == 1 and lines[0].startswith("/lidar/points: 20 messages")


def _start(scene_dir: Path, out: Path) -> subprocess.Popen:
    proc = subprocess.Popen(
        [BIN / "rig", "record", "--sim", scene_dir, "--out", out, "--duration", "60"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and (not out.exists() or out.stat().st_size < 300_000):
        time.sleep(0.1)
    time.sleep(1.0)  # about 2 s of recording
    return proc


def _children(pid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def test_sigkill_leaves_a_file_rig_info_reads_and_calls_truncated(scene_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "killed.mcap"
    proc = _start(scene_dir, out)
    children = _children(proc.pid)  # the mock devices' process (and multiprocessing's tracker)
    assert children
    proc.kill()
    proc.wait(10)
    deadline = time.monotonic() + 5
    while any(Path(f"/proc/{c}").exists() for c in children) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(Path(f"/proc/{c}").exists() for c in children), "mock devices outlived the recorder"
    report = info_here(out)
    assert report["truncated"] and not report["finished"]
    assert report["messages"] > 50
    assert report["topics"]["/camera/image/compressed"]["count"] > 10
    assert report["errors"]["devices"]["camera"]["received"] > 0  # the last status record before the kill
    fixed = tmp_path / "fixed.mcap"
    salvage = recover(out, fixed)
    assert salvage["truncated"] and salvage["messages"] == report["messages"]
    assert not info_here(fixed)["truncated"]


@pytest.mark.parametrize("sig", [signal.SIGTERM, pytest.param(signal.SIGINT, marks=pytest.mark.slow)])
def test_sigterm_and_sigint_finish_the_file(scene_dir: Path, tmp_path: Path, sig: signal.Signals) -> None:
    out = tmp_path / "stopped.mcap"
    proc = _start(scene_dir, out)
    proc.send_signal(sig)
    assert proc.wait(20) == 0, proc.stderr.read().decode()
    report = info_here(out)
    assert not report["truncated"] and report["finished"]
    assert report["topics"]["/lidar/points"]["count"] > 5
