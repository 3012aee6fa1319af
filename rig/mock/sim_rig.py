"""The mock rig behind ``rig record --sim``: a virtual-rig scene played through fake devices.

- camera: :class:`FakeOakSource` (50 ppm drifting device clock, 3 ms arrival jitter) → OAK driver;
- 3D LiDAR + IMU: :class:`FakeLivox` on 127.0.0.1 → Livox driver;
- 2D LiDAR: a horizontal slice of the same scans as LD06 bytes on a pty (:class:`FakeSerialLidar`,
  optional corrupted bytes and unplug) → LD06 driver.

Topics are the session defaults (``/camera/...``, ``/lidar/points``, ``/imu/data``) plus
``/scan2d/points``, so a recording of a scene reads like the scene's own session.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rig.drivers.ld06 import Ld06Driver
from rig.drivers.livox import LivoxDriver
from rig.drivers.oak import OakDriver
from rig.messages import Scan
from rig.mock.device_clock import DriftingClock
from rig.mock.fake_oak import FakeOakSource
from rig.mock.livox_sender import FakeLivox
from rig.mock.scene import Scene, slice_2d
from rig.mock.serial_lidar import FakeSerialLidar
from rig.record import Source
from rig.session.writer import DEFAULT_TOPICS

SCAN2D_TOPIC = "/scan2d/points"
LD06_RATE_HZ = 10.0


class _LatestSlice:
    """The 2D slice of the newest scene scan at a given time (for the fake serial LiDAR)."""

    def __init__(self, scans: Iterator[tuple[int, Scan]]) -> None:
        self._scans = scans
        self._next = next(scans, None)
        self._current = slice_2d(self._next[1]) if self._next is not None else None

    def __call__(self, t_rel_ns: int) -> Any:
        while self._next is not None and self._next[0] <= t_rel_ns:
            self._current = slice_2d(self._next[1])
            self._next = next(self._scans, None)
        return self._current


@dataclass
class SimRig:
    """Fake devices and the drivers that read them. Call :meth:`start_devices` after the drivers opened."""

    scene: Scene
    sources: list[Source]
    livox: FakeLivox | None
    serial: FakeSerialLidar | None
    oak: FakeOakSource | None
    expected_rates_hz: dict[str, float] = field(default_factory=dict)

    def start_devices(self) -> None:
        if self.livox is not None:
            driver = next(s.driver for s in self.sources if isinstance(s.driver, LivoxDriver))
            ports = driver.bound_ports
            self.livox.point_port = ports[0]
            self.livox.imu_port = ports[1] if len(ports) > 1 else ports[0]
            self.livox.start()

    def stop_devices(self) -> None:
        for dev in (self.livox, self.serial):
            if dev is not None:
                dev.stop()

    def ground_truth(self) -> dict[str, Any]:
        """What the fakes did: corrupted packets, unplug intervals, clocks."""
        return {
            "scene": str(self.scene.dir),
            "oak_clock": None if self.oak is None else vars(self.oak.clock_spec),
            "serial_corrupted_packets": None if self.serial is None else self.serial.corrupted_packets,
            "serial_unplugged": None if self.serial is None else self.serial.unplugged,
            "expected_rates_hz": self.expected_rates_hz,
        }


def build_sim_rig(
    scene_dir: str | Path,
    work_dir: str | Path,
    corrupt_rate: float = 1e-4,
    unplug_at_s: float | None = None,
    unplug_for_s: float = 1.0,
    oak_drift_ppm: float = 50.0,
    oak_jitter_ms: float = 3.0,
) -> SimRig:
    """Fake devices fed by the scene in ``scene_dir`` (``session.mcap``) and their drivers.

    The serial LiDAR's pty link is created in ``work_dir``. Rates: camera, LiDAR and IMU at the
    scene's rates; the 2D LiDAR at 10 Hz.
    """
    scene = Scene(scene_dir)
    rates = scene.rates()
    sources: list[Source] = []
    oak = livox = serial = None
    expected: dict[str, float] = {}
    if "image" in scene.streams:
        oak = FakeOakSource(scene.frames(), clock=DriftingClock(oak_drift_ppm), jitter_ms=oak_jitter_ms)
        topics = {"image": DEFAULT_TOPICS["image"], "camera_info": DEFAULT_TOPICS["camera_info"]}
        sources.append(Source(OakDriver("camera", oak), topics, scene.camera()))
        expected[DEFAULT_TOPICS["image"]] = rates["image"]
    if "points" in scene.streams:
        imu = scene.imu() if "imu" in scene.streams else None
        livox = FakeLivox(scene.scans(), imu)
        period = 1.0 / rates["points"] if rates["points"] > 0 else 0.1
        topics = {"points": DEFAULT_TOPICS["points"], "imu": DEFAULT_TOPICS["imu"]}
        sources.append(Source(LivoxDriver("lidar", "127.0.0.1", 0, 0 if imu else None, period), topics))
        expected[DEFAULT_TOPICS["points"]] = rates["points"]
        if imu is not None:
            expected[DEFAULT_TOPICS["imu"]] = rates["imu"]
        link = Path(work_dir) / "ttyLD06"
        serial = FakeSerialLidar(
            link, _LatestSlice(scene.scans()), "ld06", LD06_RATE_HZ, corrupt_rate, unplug_at_s, unplug_for_s
        )
        serial.start()
        sources.append(Source(Ld06Driver("scan2d", str(link)), {"points": SCAN2D_TOPIC}))
        expected[SCAN2D_TOPIC] = LD06_RATE_HZ
    return SimRig(scene, sources, livox, serial, oak, expected)
