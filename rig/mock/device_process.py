"""Mock devices in their own process, as real devices are: they do not share the recorder's GIL.

The child replays the scene through the fake serial LiDAR (at once, as an LD06 streams from
power-on) and, once told the ports to send to, the fake Livox; on stop it reports what it did.
It also stops by itself when its parent dies (a recorder killed with SIGKILL).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import threading
from pathlib import Path
from typing import Any

from rig.mock.livox_sender import FakeLivox
from rig.mock.scene import Scene, latest_slice
from rig.mock.serial_lidar import FakeSerialLidar

LD06_RATE_HZ = 10.0


def _watch_parent(parent_pid: int, stop: Any) -> None:
    """Stop when the recorder that started us dies (SIGKILL leaves no chance to tell us)."""
    while not stop.wait(0.2):
        if os.getppid() != parent_pid:
            stop.set()


def _main(
    parent_pid: int,
    scene_dir: str,
    link: str,
    serial_options: dict[str, Any],
    once: bool,
    ready: Any,
    go: Any,
    stop: Any,
    sent: Any,
    result: Any,
) -> None:
    threading.Thread(target=_watch_parent, args=(parent_pid, stop), daemon=True).start()
    scene = Scene(scene_dir, once)
    serial = FakeSerialLidar(
        link, latest_slice(scene.scans()), "ld06", LD06_RATE_HZ, **serial_options
    ).start()
    ready.set()
    livox = None
    try:
        while not stop.is_set():
            try:
                ports = go.get(timeout=0.1)
            except queue.Empty:
                continue
            imu = scene.imu() if "imu" in scene.streams else None
            livox = FakeLivox(scene.scans(), imu, "127.0.0.1", ports[0], ports[1]).start()
            break
        while not stop.wait(0.1):
            if livox is not None and not livox.sending:
                sent.set()
    finally:
        if livox is not None:
            livox.stop()
        serial.stop()
        result.put(
            {
                "serial_corrupted_packets": serial.corrupted_packets,
                "serial_packets": serial.packets_sent,
                "serial_revolutions": serial.revolutions_sent,
                "serial_unplugged": serial.unplugged,
                "livox_packets": None if livox is None else livox.packets_sent,
                "livox_scans": None if livox is None else livox.scans_sent,
            }
        )


class DeviceProcess:
    """The fake serial LiDAR and fake Livox of a scene, running in a child process."""

    def __init__(
        self, scene_dir: str | Path, link: str | Path, once: bool = False, **serial_options: Any
    ) -> None:
        ctx = mp.get_context("spawn")  # the parent has threads: never fork it
        self._ready, self._stop, self._sent = ctx.Event(), ctx.Event(), ctx.Event()
        self._go: Any = ctx.Queue()
        self._result: Any = ctx.Queue()
        self._process = ctx.Process(
            target=_main,
            args=(
                os.getpid(),
                str(scene_dir),
                str(link),
                serial_options,
                once,
                self._ready,
                self._go,
                self._stop,
                self._sent,
                self._result,
            ),
            name="rig-mock-devices",
            daemon=True,
        )
        self.report: dict[str, Any] = {}

    def start(self, timeout_s: float = 60.0) -> None:
        """Start the child; returns once the serial LiDAR's pty link exists."""
        self._process.start()
        if not self._ready.wait(timeout_s):
            self.stop()
            raise RuntimeError("mock devices did not start")

    def send_to(self, point_port: int, imu_port: int) -> None:
        """Start the fake Livox, sending to these UDP ports on 127.0.0.1."""
        self._go.put((point_port, imu_port))

    @property
    def livox_sent(self) -> bool:
        """Whether the fake Livox has sent its whole scene (only ever, when played once)."""
        return self._sent.is_set()

    def stop(self) -> dict[str, Any]:
        self._stop.set()
        try:
            self.report = self._result.get(timeout=10)
        except queue.Empty:
            self.report = {}
        self._process.join(10)
        if self._process.is_alive():
            self._process.kill()
        return self.report
