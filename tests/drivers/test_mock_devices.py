"""Real drivers against mock devices: pty serial LiDARs (corruption, unplug), fake OAK clock, Livox UDP."""

import time
from pathlib import Path

import numpy as np
import pytest

from rig import Frame, ImuSample, Scan
from rig.drivers import livox_protocol as lp
from rig.drivers.ld06 import Ld06Driver
from rig.drivers.livox import LivoxDriver
from rig.drivers.oak import OakDriver
from rig.drivers.rplidar import RplidarDriver
from rig.mock.device_clock import DriftingClock
from rig.mock.fake_oak import FakeOakSource
from rig.mock.livox_sender import FakeLivox
from rig.mock.serial_lidar import FakeSerialLidar


def read_for(driver, seconds: float) -> list:
    out, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        out += driver.read(0.05)
    return out


def square_room(bins: int):
    def revolution(t_rel_ns: int) -> tuple[np.ndarray, np.ndarray]:
        angle = np.deg2rad(np.arange(bins) * 360.0 / bins)
        r = 2.0 / np.maximum(np.abs(np.cos(angle)), np.abs(np.sin(angle)))  # a 4 x 4 m square
        return r, np.full(bins, 100.0)

    return revolution


def test_ld06_corruption_counted_and_unplug_reconnects_with_gap(tmp_path: Path) -> None:
    fake = FakeSerialLidar(
        tmp_path / "ttyLD",
        square_room(450),
        "ld06",
        10.0,
        corrupt_rate=2e-4,
        unplug_at_s=1.0,
        unplug_for_s=0.5,
    )
    with fake:
        driver = Ld06Driver("ld", str(fake.link))
        with driver:
            scans = read_for(driver, 3.2) + driver.drain()
    h = driver.health
    assert h.reconnects == 1 and len(h.gaps) == 1
    lost, back = fake.unplugged[0]
    gap = h.gaps[0]
    assert lost - 50e6 <= gap[0] <= lost + 200e6 and back <= gap[1] <= back + 400e6
    assert 0 < h.crc_errors <= fake.corrupted_packets
    assert 22 <= len(scans) <= 27  # ~2.7 s of 10 Hz revolutions, partial ones dropped
    before = [s for s in scans if s.t_host < gap[0]]
    after = [s for s in scans if s.t_host > gap[1]]
    assert before and after
    scan = after[-1]
    assert 400 <= len(scan) <= 450
    r = np.hypot(scan.points[:, 0], scan.points[:, 1])
    assert r.min() == pytest.approx(2.0, abs=0.01) and r.max() == pytest.approx(2 * np.sqrt(2), abs=0.02)
    assert scan.point_time_s.min() >= 0 and scan.point_time_s.max() < 0.102  # stamps are whole ms


def test_rplidar_handshake_scan_and_reconnect(tmp_path: Path) -> None:
    fake = FakeSerialLidar(
        tmp_path / "ttyRP", square_room(360), "rplidar", 5.5, unplug_at_s=0.8, unplug_for_s=0.4
    )
    with fake:
        driver = RplidarDriver("rp", str(fake.link), "a1")
        with driver:
            scans = read_for(driver, 2.6)
    assert driver.info == fake.info and driver.device_health.status == "good"
    assert driver.health.reconnects == 1 and len(driver.health.gaps) == 1
    assert len(scans) >= 6
    assert all(s.t_device is None and len(s) == 360 for s in scans)
    angles = np.degrees(np.arctan2(-scans[-1].points[:, 1], scans[-1].points[:, 0])) % 360
    assert np.allclose(np.sort(angles), np.arange(360), atol=0.02)


def test_fake_oak_50ppm_3ms_jitter_clock_error_below_half_ms() -> None:
    frames = ((round(i * 1e9 / 30), Frame(np.zeros((8, 8, 3), np.uint8), 0, None, "c")) for i in range(10**6))
    source = FakeOakSource(frames, clock=DriftingClock(drift_ppm=50.0), latency_ms=1.0, jitter_ms=3.0)
    driver = OakDriver("oak", source)
    with driver:
        got = read_for(driver, 3.0)
    assert len(got) >= 55  # the first second is held back while the clock estimate settles
    errors = np.array([f.t_host - (source.true_capture[f.t_device] + source.latency_ns) for f in got])
    assert np.abs(errors).max() < 0.5e6, np.abs(errors).max()
    assert all(isinstance(f, Frame) and f.t_device is not None for f in got)


def test_livox_driver_receives_fake_sender_and_counts_lost_packets() -> None:
    rng = np.random.default_rng(0)

    def scans():
        for k in range(8):
            pts = rng.uniform(-5, 5, (960, 3))
            yield k * 100_000_000, Scan(pts, np.linspace(0, 0.099, 960), np.full(960, 50.0), 0, None)

    imu = ((k * 5_000_000, ImuSample(np.zeros(3), np.array([0, 0, 9.81]), 0, None)) for k in range(160))
    driver = LivoxDriver("lv", "127.0.0.1", 0, 0, 0.1)
    driver.open()
    try:
        fake = FakeLivox(scans(), imu, "127.0.0.1", *driver.bound_ports)
        with fake:
            got = read_for(driver, 1.4) + driver.drain()
    finally:
        driver.close()
    scans_got = [m for m in got if isinstance(m, Scan)]
    imu_got = [m for m in got if isinstance(m, ImuSample)]
    assert len(scans_got) == 8  # the 8th, still open when the stream ends, comes with drain()
    assert all(len(s) == 960 for s in scans_got)
    assert len(imu_got) >= 150 and driver.health.dropped == 0
    np.testing.assert_allclose(imu_got[0].linear_acceleration, [0, 0, 9.81], rtol=1e-6)
    # A gap in udp_cnt is counted as lost packets.
    packet = lp.encode_points(np.ones((2, 3)), np.ones(2), 10**10, 1000, 0, 0)
    before, last = driver.health.dropped, driver._last_cnt[1]
    for cnt in (last + 1, last + 2, last + 5):
        driver._on_datagram(packet[:7] + cnt.to_bytes(2, "little") + packet[9:], time.monotonic_ns())
    assert driver.health.dropped - before == 2
