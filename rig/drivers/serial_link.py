"""A serial port that survives unplugging: reads bytes, notices loss, reopens, records the gap."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from rig.drivers.base import DeviceError, Health, now_ns


class SerialLink:
    """pyserial port with reconnect. ``read`` returns ``(bytes, t_host_ns of the last byte)``.

    When the port errors (device unplugged), the link closes it, stamps the loss, and retries every
    ``retry_s``; once back it counts a reconnect and appends ``[t_lost, t_back]`` to ``health.gaps``.
    ``on_connect`` runs after every (re)open, e.g. to send a start command.
    """

    def __init__(self, port: str, baud: int, health: Health, retry_s: float = 0.2) -> None:
        self.port = port
        self.baud = baud
        self.health = health
        self.retry_s = retry_s
        self.byte_ns = 10 * 1_000_000_000 // baud  # 8N1: 10 bits per byte
        self._serial: Any = None
        self._lost_at: int | None = None
        self._last_try = 0.0
        self.on_connect: Callable[[], None] | None = None

    @property
    def connected(self) -> bool:
        return self._serial is not None

    def open(self) -> None:
        import serial  # pyserial, imported only when a device is opened

        try:
            self._serial = serial.Serial(self.port, self.baud, timeout=0.05)
        except (serial.SerialException, OSError) as exc:
            raise DeviceError(f"cannot open serial port {self.port}: {exc}") from exc
        if self.on_connect is not None:
            try:
                self.on_connect()
            except Exception:
                self.close()
                raise

    def write(self, data: bytes) -> None:
        if self._serial is not None:
            self._serial.write(data)

    def read_exact(self, n: int, timeout_s: float) -> bytes:
        """Exactly ``n`` bytes or fewer on timeout (for request/response exchanges)."""
        out = bytearray()
        deadline = time.monotonic() + timeout_s
        while len(out) < n and time.monotonic() < deadline and self._serial is not None:
            out += self._serial.read(n - len(out))
        return bytes(out)

    def reset_input(self) -> None:
        if self._serial is not None:
            self._serial.reset_input_buffer()

    def read(self, timeout_s: float) -> tuple[bytes, int]:
        """Bytes available within ``timeout_s`` (empty while unplugged) and the host time they ended."""
        import serial

        if self._serial is None:
            self._try_reconnect(timeout_s)
            return b"", now_ns()
        try:
            self._serial.timeout = timeout_s
            data = self._serial.read(max(1, self._serial.in_waiting))
            if self._serial.in_waiting:
                data += self._serial.read(self._serial.in_waiting)
            return data, now_ns()
        except (serial.SerialException, OSError, TypeError):
            # TypeError: pyserial's in_waiting on a closed pty
            self._lost_at = now_ns()
            self.close()
            return b"", self._lost_at

    def _try_reconnect(self, timeout_s: float) -> None:
        wait = self._last_try + self.retry_s - time.monotonic()
        if wait > 0:
            time.sleep(min(wait, timeout_s))
            return
        self._last_try = time.monotonic()
        try:
            self.open()
        except DeviceError:
            return
        self.health.reconnects += 1
        self.health.gaps.append([self._lost_at or now_ns(), now_ns()])
        self._lost_at = None

    def close(self) -> None:
        if self._serial is not None:
            try:
                self._serial.close()
            finally:
                self._serial = None
