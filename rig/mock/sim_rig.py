"""The mock rig behind ``rig record --sim``: a virtual-rig scene played through fake devices.

- camera: :class:`FakeOakSource` (50 ppm drifting device clock, 3 ms arrival jitter) → OAK driver;
- 3D LiDAR + IMU: :class:`FakeLivox` on 127.0.0.1 → Livox driver;
- 2D LiDAR: a horizontal slice of the same scans as LD06 bytes on a pty (:class:`FakeSerialLidar`,
  optional corrupted bytes and unplug) → LD06 driver.

The LiDAR fakes run in a child process (:class:`DeviceProcess`) like real devices; the fake OAK
is a source object inside the OAK driver. Topics are the session defaults (``/camera/...``,
``/lidar/points``, ``/imu/data``) plus ``/scan2d/points``, so a recording of a scene reads like the
scene's own session.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rig.drivers.ld06 import Ld06Driver
from rig.drivers.livox import LivoxDriver
from rig.drivers.oak import OakDriver
from rig.mock.device_clock import DriftingClock
from rig.mock.device_process import LD06_RATE_HZ, DeviceProcess
from rig.mock.fake_oak import FakeOakSource
from rig.mock.scene import Scene
from rig.record import Source
from rig.session.writer import DEFAULT_TOPICS

SCAN2D_TOPIC = "/scan2d/points"
#: A scene played once is over this long after its fakes sent their last message, so that the
#: drivers read what is still on its way (a UDP socket's queue, a jittered camera frame).
ONE_PASS_GRACE_S = 0.5


@dataclass
class SimRig:
    """Fake devices and the drivers that read them. :meth:`start_devices` runs after the drivers opened."""

    scene: Scene
    sources: list[Source]
    devices: DeviceProcess | None
    oak: FakeOakSource | None
    expected_rates_hz: dict[str, float] = field(default_factory=dict)
    #: Messages one pass of a scene played once holds, per topic (the fakes send no more).
    pass_counts: dict[str, int] = field(default_factory=dict)
    _sent_at: float | None = field(default=None, init=False, repr=False)

    def finished(self) -> bool:
        """Whether a scene played once is over: every fake has sent all of it, ``ONE_PASS_GRACE_S``
        ago; never for a looping scene. Meanwhile the fake 2D LiDAR spins on over the last scan, as
        on a robot standing at the end of its path."""
        if not self.scene.once:
            return False
        sent = (self.oak is None or self.oak.exhausted) and (self.devices is None or self.devices.livox_sent)
        if not sent:
            return False
        if self._sent_at is None:
            self._sent_at = time.monotonic()
        return time.monotonic() - self._sent_at >= ONE_PASS_GRACE_S

    def start_devices(self) -> None:
        livox = next((s.driver for s in self.sources if isinstance(s.driver, LivoxDriver)), None)
        if self.devices is not None and livox is not None:
            ports = livox.bound_ports
            self.devices.send_to(ports[0], ports[-1])

    def stop_devices(self) -> None:
        if self.devices is not None:
            self.devices.stop()

    def shortfalls(self, written: dict[str, int], duration_s: float, share: float = 0.8) -> list[str]:
        """One line for each topic the recorder wrote less than ``share`` of what the fakes sent
        over ``duration_s`` of recording (a recorder that falls behind loses messages): their rate
        over the whole recording, or one pass of the scene where that is less. One message more
        is allowed for where the first one fell (a 10 Hz device 0.5 s after it started: 4 or 5)."""
        lines = []
        for topic, rate in self.expected_rates_hz.items():
            count = written.get(topic, 0)
            if count + 1 < share * min(rate * duration_s, self.pass_counts.get(topic, math.inf)):
                lines.append(
                    f"{topic}: {count} messages in {duration_s:.1f} s ({count / duration_s:.1f} Hz), "
                    f"the mock devices sent {rate:.0f} Hz: the recorder fell behind or a device stopped"
                )
        return lines

    def ground_truth(self) -> dict[str, Any]:
        """What the fakes did: corrupted packets, unplug intervals, clocks, expected rates."""
        return {
            "scene": str(self.scene.dir),
            "oak_clock": None if self.oak is None else vars(self.oak.clock_spec),
            **(self.devices.report if self.devices is not None else {}),
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
    once: bool = False,
) -> SimRig:
    """Fake devices fed by the scene in ``scene_dir`` (``session.mcap``) and their drivers;
    ``once``: the scene is played once (:meth:`SimRig.finished`) instead of in a loop.

    Starts the device process (the serial LiDAR's pty link is created in ``work_dir``). Rates:
    camera, LiDAR and IMU at the scene's rates; the 2D LiDAR at 10 Hz.
    """
    scene = Scene(scene_dir, once)
    rates = scene.rates()
    sources: list[Source] = []
    oak = devices = None
    expected: dict[str, float] = {}
    one_pass: dict[str, int] = {}
    if "image" in scene.streams:
        # No fixed latency: the camera's recorded host stamps then keep the scene's camera-LiDAR
        # timing (the scene's own latencies are already in its host stamps).
        oak = FakeOakSource(
            scene.frames(), clock=DriftingClock(oak_drift_ppm), latency_ms=0.0, jitter_ms=oak_jitter_ms
        )
        topics = {"image": DEFAULT_TOPICS["image"], "camera_info": DEFAULT_TOPICS["camera_info"]}
        sources.append(Source(OakDriver("camera", oak), topics, scene.camera()))
        expected[DEFAULT_TOPICS["image"]] = rates["image"]
        one_pass[DEFAULT_TOPICS["image"]] = scene.streams["image"].count
    if "points" in scene.streams:
        has_imu = "imu" in scene.streams
        period = 1.0 / rates["points"] if rates["points"] > 0 else 0.1
        topics = {"points": DEFAULT_TOPICS["points"], "imu": DEFAULT_TOPICS["imu"]}
        sources.append(
            Source(
                LivoxDriver("lidar", "127.0.0.1", 0, 0 if has_imu else None, period, split="frame"), topics
            )
        )
        expected[DEFAULT_TOPICS["points"]] = rates["points"]
        one_pass[DEFAULT_TOPICS["points"]] = scene.streams["points"].count
        if has_imu:
            expected[DEFAULT_TOPICS["imu"]] = rates["imu"]
            one_pass[DEFAULT_TOPICS["imu"]] = scene.streams["imu"].count
        link = Path(work_dir) / "ttyLD06"
        devices = DeviceProcess(
            scene.dir,
            link,
            once,
            corrupt_rate=corrupt_rate,
            unplug_at_s=unplug_at_s,
            unplug_for_s=unplug_for_s,
        )
        devices.start()
        sources.append(Source(Ld06Driver("scan2d", str(link)), {"points": SCAN2D_TOPIC}))
        expected[SCAN2D_TOPIC] = LD06_RATE_HZ
    return SimRig(scene, sources, devices, oak, expected, one_pass if once else {})
