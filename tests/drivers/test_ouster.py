"""Ouster pcap decoding with ouster-sdk on the shared real captures (skipped without the extra)."""

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("ouster.sdk", reason="the `ouster` extra (ouster-sdk) is not installed")

from rig.drivers.ouster import OusterDriver, read_pcap

CAPTURES = [
    # (pcap, metadata, scans, pixels per scan)
    ("OS-0-32-U1_v2.2.0_1024x10.pcap", "OS-0-32-U1_v2.2.0_1024x10.json", 1, 32 * 1024),
    ("OS-1-128_v2.3.0_1024x10_lb_n3.pcap", "OS-1-128_v2.3.0_1024x10.json", 3, 128 * 1024),
]


@pytest.mark.parametrize(("pcap", "meta", "n_scans", "pixels"), CAPTURES)
def test_pcap_scans(real_data: Path, pcap: str, meta: str, n_scans: int, pixels: int) -> None:
    d = real_data / "ouster"
    scans = list(read_pcap(d / pcap, d / meta))
    assert len(scans) == n_scans
    for scan in scans:
        assert 0.5 * pixels < len(scan) <= pixels  # zero-range pixels dropped
        r = np.linalg.norm(scan.points, axis=1)
        assert r.min() > 0.1 and r.max() < 300  # metres
        # per-column times: a 10 Hz sweep spans just under 0.1 s
        assert scan.point_time_s.min() == 0 and 0.095 < scan.point_time_s.max() < 0.1
        assert len(np.unique(scan.point_time_s)) > 900  # many of the 1024 columns
    if n_scans > 1:
        stamps = np.diff([s.t_device for s in scans]) / 1e9
        np.testing.assert_allclose(stamps, 0.1, atol=0.002)


def test_driver_reads_pcap(real_data: Path) -> None:
    d = real_data / "ouster"
    driver = OusterDriver("os", pcap=str(d / CAPTURES[1][0]), meta=str(d / CAPTURES[1][1]))
    with driver:
        got = [m for _ in range(5) for m in driver.read()]
        assert driver.finished  # the pcap's end
    assert len(got) == 3 and driver.device_id() == "122201000998"
    assert driver.health.received == 3
    # Host stamps keep the pcap's spacing, however fast the frames decode.
    np.testing.assert_array_equal(np.diff([m.t_host for m in got]), np.diff([m.t_device for m in got]))


def test_rig_record_of_a_pcap_ends_with_it(real_data: Path, tmp_path: Path) -> None:
    """`rig record` of a pcap device stops when the pcap is replayed, without --duration, and the
    session's sweeps are 0.1 s apart as the sensor took them."""
    import subprocess
    import sys

    from rig.session import SessionReader

    d = real_data / "ouster"
    config = tmp_path / "rig.yaml"
    config.write_text(
        f"devices:\n  - {{name: os, kind: ouster, pcap: {d / CAPTURES[1][0]}, meta: {d / CAPTURES[1][1]}}}\n"
    )
    rig = Path(sys.executable).parent / "rig"
    out = tmp_path / "os.mcap"
    result = subprocess.run(
        [rig, "record", "--config", config, "--out", out], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr[-2000:]
    stamps = [scan.t_host for scan in SessionReader(out).scans("/os/points")]
    assert len(stamps) == 3
    np.testing.assert_allclose(np.diff(stamps) / 1e9, 0.1, atol=0.002)


def test_raw_packets_from_a_ros1_bag(real_data: Path) -> None:
    from rig.drivers.ouster import read_packet_bag

    bag = real_data / "ouster" / "512x10_raw.bag"
    (scan,) = read_packet_bag(bag, "/os_node0/lidar_packets", "/os_node0/metadata")
    # 32 packets of 16 columns: one full 128 x 512 frame (OS-0-128, 512x10); zero ranges dropped
    assert len(scan) == 28751 and len(np.unique(scan.point_time_s)) > 400
    r = np.linalg.norm(scan.points, axis=1)
    assert r.min() > 0.1 and r.max() < 50  # an indoor capture
    assert 0.095 < scan.point_time_s.max() < 0.1 and scan.t_device == 291159252580
    assert scan.t_host // 10**9 == 1723828414  # the bag's receive time
