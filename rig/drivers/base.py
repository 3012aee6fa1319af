"""The driver interface: open / start / read / stop / close, with health counters.

A driver turns one device's output into :class:`~rig.messages.Frame`, :class:`~rig.messages.Scan`
and :class:`~rig.messages.ImuSample` messages stamped with ``t_device`` and ``t_host`` (ns).
Vendor libraries (depthai, pyserial, pyusb, ouster-sdk) are imported inside the driver methods,
never at module import, so the data model loads without them.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import asdict, dataclass, field
from types import TracebackType
from typing import Any

from rig.clock import ClockEstimator, HostStamper
from rig.messages import Frame, ImuSample, Scan

Message = Frame | Scan | ImuSample


class ParseError(ValueError):
    """Bytes that are not a valid packet of a sensor protocol (bad header, length or checksum)."""


class DeviceError(RuntimeError):
    """A device that cannot be opened or stops answering (unplugged, wrong port, no permission)."""


@dataclass
class Health:
    """Health counters of one driver.

    Attributes:
        received: messages delivered (frames, scans, IMU samples).
        packets: wire packets decoded.
        dropped: packets known lost (sequence gaps, incomplete frames).
        crc_errors: packets rejected by their checksum or check bits.
        reconnects: times the device was reopened after it went away.
        gaps: ``[t_host_lost, t_host_back]`` ns of each outage.
    """

    received: int = 0
    packets: int = 0
    dropped: int = 0
    crc_errors: int = 0
    reconnects: int = 0
    gaps: list[list[int]] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


class Driver(ABC):
    """One device. ``read`` returns the messages that became available within ``timeout_s``."""

    #: short kind name used in ``rig.yaml`` (``ld06``, ``rplidar``, ``livox``, ``oak``, ``ouster``).
    kind: str = ""

    def __init__(self, name: str) -> None:
        self.name = name
        self.health = Health()

    @abstractmethod
    def open(self) -> None:
        """Connect to the device (raises :class:`DeviceError` when it is not there)."""

    def start(self) -> None:
        """Start streaming (devices that stream from power-on need nothing)."""
        return None

    @abstractmethod
    def read(self, timeout_s: float = 0.1) -> list[Message]:
        """Messages that became available within ``timeout_s`` (possibly none)."""

    def drain(self) -> list[Message]:
        """Messages still held back (waiting for a clock estimate), released at the end of a run."""
        return []

    def stop(self) -> None:
        """Stop streaming."""
        return None

    @abstractmethod
    def close(self) -> None:
        """Release the device."""

    @property
    def finished(self) -> bool:
        """Whether the source has nothing more to send: a recording replayed to its end (a live
        device never finishes)."""
        return False

    def device_id(self) -> str:
        """A stable id of the device (serial number, port or address)."""
        return self.name

    def describe(self) -> dict[str, Any]:
        """What the device says about itself (model, firmware, health), where it says anything."""
        return {}

    def clock_estimate(self) -> dict[str, Any] | None:
        """The device→host clock estimate, when the device has a clock."""
        return None

    def __enter__(self) -> Driver:
        self.open()
        self.start()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()
        self.close()


class DeviceClockDriver(Driver):
    """A device with its own clock: its messages get ``t_host`` from an online device→host clock
    estimate (``clock``, fed by the driver), held back in ``stamper`` until the estimate settles.

    Args:
        clock: the estimator to feed (a fresh :class:`~rig.clock.ClockEstimator` when None).
    """

    def __init__(self, name: str, clock: ClockEstimator | None = None) -> None:
        super().__init__(name)
        self.clock = clock or ClockEstimator()
        self.stamper = HostStamper(self.clock)

    def drain(self) -> list[Message]:
        return self.stamper.flush()

    def clock_estimate(self) -> dict[str, Any] | None:
        estimate = self.clock.estimate()
        return None if estimate is None else estimate.as_dict()


def now_ns() -> int:
    """Host monotonic time in ns (the ``t_host`` clock)."""
    return time.monotonic_ns()
