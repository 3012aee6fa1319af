"""Luxonis OAK cameras through depthai 3.x: colour frames and IMU with device and host stamps.

The depthai-facing part (:class:`DepthaiSource`) is small and cannot be tested here without a
device; the stamping logic (:class:`OakDriver`) is shared with the fake OAK of ``rig.mock``.
depthai stamps each message twice: ``getTimestampDevice()`` on the device clock and
``getTimestamp()`` already mapped by depthai to the host's steady clock (CLOCK_MONOTONIC on Linux,
the ``t_host`` clock). The driver keeps both, and also fits its own device→host estimate from the
arrival times so the session records how the device clock behaved.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from datetime import timedelta
from typing import Any, Protocol

import numpy as np

from rig.clock import ClockEstimator
from rig.drivers.base import DeviceClockDriver, DeviceError, Message, now_ns
from rig.messages import Frame, ImuSample
from rig.native_output import native_output_to_stderr

OAK_VENDOR_ID = 0x03E7


@dataclass(frozen=True)
class OakPacket:
    """What a source delivers: an image ``(H, W, 3)`` BGR or an IMU sample (``gyro``, ``acc`` ``(3,)``)."""

    t_device: int
    t_host_synced: int | None  # depthai's host-mapped stamp, None when the source has none
    t_arrival: int
    image: np.ndarray | None = None
    gyro: np.ndarray | None = None
    acc: np.ndarray | None = None


class OakSource(Protocol):
    def open(self) -> str:
        """Start streaming; returns the device id."""
        ...

    def get(self, timeout_s: float) -> list[OakPacket]: ...

    def close(self) -> None: ...


def _ns(delta: timedelta) -> int:
    return (delta.days * 86400 + delta.seconds) * 1_000_000_000 + delta.microseconds * 1000


def list_oak_devices() -> list[dict[str, str]]:
    """OAK devices depthai can see: ``[{"id", "name", "state", "protocol"}]`` (empty without depthai)."""
    with native_output_to_stderr():
        try:
            import depthai as dai
        except ImportError:
            return []
        return [
            {"id": d.getDeviceId(), "name": d.name, "state": d.state.name, "protocol": d.protocol.name}
            for d in dai.Device.getAllAvailableDevices()
        ]


class DepthaiSource:
    """A real OAK: colour camera (and IMU when the device has one) through depthai 3.x."""

    def __init__(self, device_id: str | None, size: tuple[int, int], fps: float, imu_hz: int | None) -> None:
        self.device_id, self.size, self.fps, self.imu_hz = device_id, size, fps, imu_hz
        self._pipeline: Any = None
        self._queues: dict[str, Any] = {}

    def open(self) -> str:
        with native_output_to_stderr():
            return self._open()

    def _open(self) -> str:
        import depthai as dai

        try:
            device = dai.Device(dai.DeviceInfo(self.device_id)) if self.device_id else dai.Device()
        except RuntimeError as exc:
            raise DeviceError(f"cannot open OAK {self.device_id or '(first found)'}: {exc}") from exc
        pipeline = dai.Pipeline(device)
        cam = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_A)
        out = cam.requestOutput(self.size, dai.ImgFrame.Type.BGR888i, fps=self.fps)
        self._queues["image"] = out.createOutputQueue(maxSize=8, blocking=False)
        if self.imu_hz and device.getConnectedIMU() not in ("", "NONE"):
            imu = pipeline.create(dai.node.IMU)
            imu.enableIMUSensor([dai.IMUSensor.ACCELEROMETER_RAW, dai.IMUSensor.GYROSCOPE_RAW], self.imu_hz)
            imu.setBatchReportThreshold(1)
            imu.setMaxBatchReports(10)
            self._queues["imu"] = imu.out.createOutputQueue(maxSize=50, blocking=False)
        pipeline.start()
        self._pipeline = pipeline
        return device.getDeviceId()

    def get(self, timeout_s: float) -> list[OakPacket]:
        out: list[OakPacket] = []
        for frame in self._queues["image"].tryGetAll():
            t = now_ns()
            out.append(
                OakPacket(
                    _ns(frame.getTimestampDevice()), _ns(frame.getTimestamp()), t, image=frame.getCvFrame()
                )
            )
        if "imu" in self._queues:
            for data in self._queues["imu"].tryGetAll():
                t = now_ns()
                for p in data.packets:
                    a, g = p.acceleroMeter, p.gyroscope
                    out.append(
                        OakPacket(
                            _ns(a.getTimestampDevice()),
                            _ns(a.getTimestamp()),
                            t,
                            gyro=np.array([g.x, g.y, g.z]),
                            acc=np.array([a.x, a.y, a.z]),
                        )
                    )
        if not out:
            time.sleep(min(timeout_s, 0.5 / self.fps))  # nothing yet: wait a little, never spin
        return out

    def close(self) -> None:
        if self._pipeline is not None:
            self._pipeline.stop()
            self._pipeline = None


class OakDriver(DeviceClockDriver):
    """An OAK (or anything speaking :class:`OakSource`): frames and IMU samples, stamped.

    ``t_host`` is depthai's host-synced stamp when the source gives one, else the device stamp
    mapped through the driver's own clock estimate (fed with device stamp / arrival pairs; messages
    wait in a :class:`HostStamper` for its first second).
    """

    kind = "oak"

    def __init__(self, name: str, source: OakSource, clock: ClockEstimator | None = None) -> None:
        super().__init__(name, clock)
        self.source = source
        self._device_id = ""

    @classmethod
    def from_device(
        cls,
        name: str,
        device_id: str | None = None,
        size: tuple[int, int] = (640, 400),
        fps: float = 30.0,
        imu_hz: int | None = 200,
        clock: ClockEstimator | None = None,
    ) -> OakDriver:
        """A driver for a real OAK (the first found when ``device_id`` is None)."""
        return cls(name, DepthaiSource(device_id, size, fps, imu_hz), clock)

    def open(self) -> None:
        self._device_id = self.source.open()

    def device_id(self) -> str:
        return self._device_id

    def read(self, timeout_s: float = 0.1) -> list[Message]:
        out: list[Message] = []
        for p in self.source.get(timeout_s):
            self.health.packets += 1
            self.clock.add(p.t_device, p.t_arrival)
            t_host = p.t_arrival if p.t_host_synced is None else p.t_host_synced
            if p.image is not None:
                message: Message = Frame(p.image, t_host, p.t_device, self.name)
            else:
                assert p.gyro is not None and p.acc is not None
                message = ImuSample(p.gyro, p.acc, t_host, p.t_device, f"{self.name}/imu")
            self.health.received += 1
            out.extend([message] if p.t_host_synced is not None else self.stamper.push(message))
        return out

    def close(self) -> None:
        self.source.close()
