"""``rig record``: run drivers, one reader thread each, into a threaded session recorder.

Every driver's messages go to its topics (``image``, ``points``, ``imu`` by message type);
a camera model, when known, is written once as ``camera_info``. The recorder's status record
carries each device's health counters and clock estimate, so ``rig info`` can report them even
for a recording that was killed.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.camera import CameraModel
from rig.clock import ClockEstimator
from rig.drivers.base import DeviceError, Driver
from rig.messages import Frame, ImuSample, Scan
from rig.record_config import RigConfig
from rig.session.recorder import SessionRecorder


@dataclass
class Source:
    """A driver and the topics its messages go to (role → topic)."""

    driver: Driver
    topics: dict[str, str]
    camera: CameraModel | None = None


def silent_devices(summary: dict[str, Any]) -> list[str]:
    """One line for each device of a recording's ``summary`` (:meth:`Recording.run`) that sent
    nothing: a LiDAR streaming to another address, a blocked port, a camera another program holds."""
    return [
        f"{name} ({device['device_id']}) sent nothing in {summary['duration_s']:.1f} s"
        + (f": {device['error']}" if device.get("error") else ": check its cable, address and port")
        for name, device in summary.get("devices", {}).items()
        if device.get("received", 0) == 0 and device.get("packets", 0) == 0
    ]


def written_line(path: str | Path, written: dict[str, int]) -> str:
    """What a recording at ``path`` holds, for the log: each topic and its ``written`` count."""
    counts = ", ".join(f"{topic} {n}" for topic, n in sorted(written.items()))
    return f"wrote {path}: {counts or 'no messages'}"


def build_sources(config: RigConfig) -> list[Source]:
    """Drivers for the devices of a ``rig.yaml`` (nothing is opened yet)."""
    from rig.drivers.ld06 import Ld06Driver
    from rig.drivers.livox import LivoxDriver
    from rig.drivers.oak import OakDriver
    from rig.drivers.ouster import OusterDriver
    from rig.drivers.rplidar import RplidarDriver

    sources = []
    for d in config.devices:
        o = d.options
        clock = ClockEstimator(**config.clock)
        if d.kind == "oak":
            size = tuple(o.get("size", (640, 400)))
            driver: Driver = OakDriver.from_device(
                d.name,
                o.get("device_id"),
                (int(size[0]), int(size[1])),
                float(o.get("fps", 30)),
                o.get("imu_hz", 200),
                clock,
            )
        elif d.kind == "livox":
            driver = LivoxDriver(
                d.name,
                o.get("host", "0.0.0.0"),
                int(o.get("point_port", 56301)),
                o.get("imu_port", 56401),
                float(o.get("scan_period_s", 0.1)),
                split=o.get("split", "time"),
                clock=clock,
            )
        elif d.kind == "ld06":
            driver = Ld06Driver(d.name, str(o["port"]), o.get("model", "ld06"), o.get("baud"), clock)
        elif d.kind == "rplidar":
            driver = RplidarDriver(d.name, str(o["port"]), o.get("model", "a1"), o.get("baud"))
        else:
            driver = OusterDriver(d.name, o.get("hostname"), o.get("pcap"), o.get("meta"))
        sources.append(Source(driver, d.topics))
    return sources


def _role(message: Frame | Scan | ImuSample) -> str:
    return "image" if isinstance(message, Frame) else "points" if isinstance(message, Scan) else "imu"


class Recording:
    """Opens the sources, records until ``duration_s``, ``stop`` or every source has finished (a
    replayed recording at its end), and finishes the file.

    Args:
        sources: drivers and their topics.
        out: the ``.mcap`` to write.
        metadata: stored at the start (rig.yaml contents, scene, ...).
        recorder_options: passed to :class:`SessionRecorder` (queue_size, policy, ...).
    """

    def __init__(
        self,
        sources: list[Source],
        out: str | Path,
        metadata: dict[str, Any] | None = None,
        recorder_options: dict[str, Any] | None = None,
    ) -> None:
        self.sources = sources
        self.out = Path(out)
        self.metadata = metadata or {}
        self.recorder_options = recorder_options or {}
        self.errors: dict[str, str] = {}
        self.recorder: SessionRecorder | None = None
        self.started = 0.0
        #: The drivers whose camera model is written (once, with their first frame) or not wanted.
        self._camera_written = {
            s.driver.name for s in sources if s.camera is None or "camera_info" not in s.topics
        }

    def device_status(self) -> dict[str, Any]:
        """``{"devices": {name: {health counters, "device_id", "clock"}}}``."""
        return {
            "devices": {
                s.driver.name: {
                    **s.driver.health.as_dict(),
                    "device_id": s.driver.device_id(),
                    "clock": s.driver.clock_estimate(),
                    "error": self.errors.get(s.driver.name),
                }
                for s in self.sources
            }
        }

    def _read_loop(self, source: Source, stop: threading.Event) -> None:
        driver, recorder = source.driver, self.recorder
        assert recorder is not None
        while not stop.is_set() and recorder.recording:
            try:
                messages = driver.read(0.1)
            except (OSError, DeviceError) as exc:
                self.errors[driver.name] = f"{type(exc).__name__}: {exc}"
                return
            for m in messages:
                self._put(source, m)

    def _put(self, source: Source, m: Frame | Scan | ImuSample) -> None:
        """Queue ``m`` on its topic of ``source`` (none: dropped), after the source's camera model
        with its first frame, read or drained (a camera whose frames all came after the stop, as
        in a recording shorter than its clock fit, had no camera_info)."""
        assert self.recorder is not None
        topic = source.topics.get(_role(m))
        if topic is None:
            return
        name = source.driver.name
        if isinstance(m, Frame) and name not in self._camera_written:
            assert source.camera is not None
            self.recorder.put_camera_info(
                source.camera, m.t_host, m.t_device, source.topics["camera_info"], name
            )
            self._camera_written.add(name)
        self.recorder.put(m, topic, name)

    def run(
        self,
        duration_s: float | None,
        stop: threading.Event,
        on_tick: Callable[[dict[str, Any]], None] | None = None,
        after_open: Callable[[], None] | None = None,
        sources_done: Callable[[], bool] | None = None,
    ) -> dict[str, Any]:
        """Record; returns the summary (topics written, drops, device health, clocks, error).

        ``after_open`` runs once every driver is open (mock devices start sending there); the
        recording ends when ``sources_done()`` says so (mock devices that played their scene once),
        as it does when every driver is :attr:`~rig.drivers.base.Driver.finished`."""
        opened: list[Driver] = []
        try:
            for s in self.sources:
                s.driver.open()
                opened.append(s.driver)
                s.driver.start()
            if after_open is not None:
                after_open()
            device_ids = {s.driver.name: s.driver.device_id() for s in self.sources}
            self.recorder = SessionRecorder(
                self.out,
                metadata={**self.metadata, "device_ids": device_ids},
                status=self.device_status,
                **self.recorder_options,
            )
            threads = [
                threading.Thread(
                    target=self._read_loop, args=(s, stop), name=f"read-{s.driver.name}", daemon=True
                )
                for s in self.sources
            ]
            self.started = time.monotonic()
            for t in threads:
                t.start()
            while not stop.is_set() and self.recorder.recording:
                if duration_s is not None and time.monotonic() - self.started >= duration_s:
                    break
                if all(s.driver.finished for s in self.sources):  # recordings replayed to the end
                    break
                if sources_done is not None and sources_done():
                    break
                stop.wait(0.25)
                if on_tick is not None:
                    on_tick(self.summary())
            stop.set()
            for t in threads:
                t.join(5)
            for s in self.sources:
                for m in s.driver.drain():
                    self._put(s, m)
            elapsed = time.monotonic() - self.started
            self.recorder.close(self.device_status())
            return {**self.summary(), "duration_s": elapsed}
        finally:
            stop.set()
            for d in opened:
                try:
                    d.stop()
                finally:
                    d.close()

    def summary(self) -> dict[str, Any]:
        rec = self.recorder
        elapsed = time.monotonic() - self.started if self.started else 0.0
        stats = rec.stats() if rec is not None else {"written": {}, "dropped": {}, "bytes": 0, "error": None}
        return {
            "out": str(self.out),
            "elapsed_s": elapsed,
            "written": stats["written"],
            "rates_hz": {k: v / elapsed for k, v in stats["written"].items()} if elapsed > 0 else {},
            "dropped": stats["dropped"],
            "queue": rec.queue_depth() if rec is not None else 0,
            "bytes": stats["bytes"],
            "error": stats["error"],
            **self.device_status(),
        }
