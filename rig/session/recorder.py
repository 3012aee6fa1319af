"""Threaded session recording: producers enqueue messages, one thread serialises and writes them.

The queue is bounded. When the writer cannot keep up (slow disk, CPU busy with JPEG), messages are
dropped by policy and counted per topic, so memory never grows without bound. Free disk space is
checked as the file grows: below ``min_free_bytes`` recording stops and the file is finished
(summary and footer fit in the reserve), so a full disk still leaves a valid file. A write error
(``OSError``) stops recording the same way; if even finishing fails, ``rig recover`` salvages the
complete chunks.
"""

from __future__ import annotations

import queue
import shutil
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.camera import CameraModel
from rig.messages import Frame, ImuSample, Scan
from rig.session.writer import SessionWriter

#: Metadata record rewritten every ``status_every_s`` while recording, and once at the end.
STATUS_METADATA = "lidar_ts.status"
DROP_POLICIES = ("drop-newest", "drop-oldest")


@dataclass(frozen=True)
class _Item:
    topic: str
    message: Frame | Scan | ImuSample | tuple[CameraModel, int, int | None]
    frame_id: str


_IDLE: Any = object()  # what the writer loop sees when the queue stayed empty for a while


class SessionRecorder:
    """Write messages to ``path`` from a background thread.

    Args:
        path: output ``.mcap``.
        metadata: stored in the ``lidar_ts.session`` record at the start (rig.yaml, device ids).
        queue_size: most messages waiting to be written.
        policy: ``drop-newest`` (refuse the incoming message) or ``drop-oldest`` (evict the oldest).
        min_free_bytes: stop recording when the disk has less free space than this.
        status: called on the writer thread every ``status_every_s``; returns a dict stored as the
            ``lidar_ts.status`` metadata (health counters, clock estimates), so a killed recording
            still says how it went until then.
        disk_free: returns free bytes of the output's file system (replaceable in tests).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        metadata: dict[str, Any] | None = None,
        queue_size: int = 512,
        policy: str = "drop-newest",
        image_format: str = "jpeg",
        chunk_size: int = 1 << 20,
        min_free_bytes: int = 64 << 20,
        status: Callable[[], dict[str, Any]] | None = None,
        status_every_s: float = 1.0,
        disk_free: Callable[[Path], int] | None = None,
    ) -> None:
        if policy not in DROP_POLICIES:
            raise ValueError(f"unknown drop policy {policy!r}; expected one of {DROP_POLICIES}")
        self.path = Path(path)
        self.policy = policy
        self.min_free_bytes = min_free_bytes
        self._status = status
        self._status_every_s = status_every_s
        self._disk_free = disk_free or (lambda p: shutil.disk_usage(p.parent).free)
        self._queue: queue.Queue[_Item | None] = queue.Queue(maxsize=queue_size)
        self.dropped: Counter[str] = Counter()
        self.written: Counter[str] = Counter()
        self.error: str | None = None
        self._lock = threading.Lock()
        self._accepting = True
        self._writer = SessionWriter(
            self.path, metadata=metadata, image_format=image_format, chunk_size=chunk_size
        )
        self._check_disk()
        self._thread = threading.Thread(target=self._run, name="session-writer", daemon=True)
        self._thread.start()

    @property
    def recording(self) -> bool:
        """False once recording stopped (closed, disk full or a write error)."""
        return self._accepting

    @property
    def bytes_written(self) -> int:
        return self._writer.bytes_written

    def put(self, message: Frame | Scan | ImuSample, topic: str, frame_id: str) -> bool:
        """Queue a message for ``topic``; False when it was dropped (queue full or stopped)."""
        return self._put(_Item(topic, message, frame_id))

    def put_camera_info(
        self, camera: CameraModel, t_host: int, t_device: int | None, topic: str, frame_id: str
    ) -> bool:
        return self._put(_Item(topic, (camera, t_host, t_device), frame_id))

    def _put(self, item: _Item) -> bool:
        with self._lock:
            if not self._accepting:
                self.dropped[item.topic] += 1
                return False
            try:
                self._queue.put_nowait(item)
                return True
            except queue.Full:
                if self.policy == "drop-newest":
                    self.dropped[item.topic] += 1
                    return False
                oldest = self._queue.get_nowait()
                if oldest is not None:
                    self.dropped[oldest.topic] += 1
                self._queue.put_nowait(item)
                return True

    def queue_depth(self) -> int:
        return self._queue.qsize()

    def stats(self) -> dict[str, Any]:
        """Per-topic written and dropped counts, bytes written and the stop reason (if any)."""
        return {
            "written": dict(self.written),
            "dropped": dict(self.dropped),
            "bytes": self.bytes_written,
            "error": self.error,
            "policy": self.policy,
        }

    def _check_disk(self) -> None:
        free = self._disk_free(self.path)
        if free < self.min_free_bytes:
            self._stop(
                f"disk almost full: {free / 1e6:.1f} MB free at {self.path.parent} "
                f"(need {self.min_free_bytes / 1e6:.0f} MB)"
            )

    def _stop(self, reason: str) -> None:
        with self._lock:
            self._accepting = False
            if self.error is None:
                self.error = reason

    def _write(self, item: _Item) -> None:
        w, m = self._writer, item.message
        if isinstance(m, Frame):
            w.write_frame(m, item.topic, item.frame_id)
        elif isinstance(m, Scan):
            w.write_scan(m, item.topic, item.frame_id)
        elif isinstance(m, ImuSample):
            w.write_imu(m, item.topic, item.frame_id)
        else:
            camera, t_host, t_device = m
            w.write_camera_info(camera, t_host, t_device, item.topic, item.frame_id)
        self.written[item.topic] += 1

    def _write_status(self) -> None:
        if self._status is not None:
            self._writer.write_metadata(STATUS_METADATA, {**self._status(), "recorder": self.stats()})

    def _run(self) -> None:
        last_status = time.monotonic()
        last_bytes = self.bytes_written
        while True:
            try:
                item = self._queue.get(timeout=0.1)
            except queue.Empty:
                item = _IDLE
            if item is None:
                return
            try:
                if item is not _IDLE and self.error is None:
                    self._write(item)
                if self.bytes_written != last_bytes:  # a chunk went out: push it to the OS, check space
                    last_bytes = self.bytes_written
                    self._writer.flush()
                    self._check_disk()
                if time.monotonic() - last_status >= self._status_every_s and self.error is None:
                    last_status = time.monotonic()
                    self._write_status()
                    self._writer.flush()
            except OSError as exc:
                self._stop(f"write failed: {exc}")

    def close(self, final_metadata: dict[str, Any] | None = None, timeout_s: float = 30.0) -> None:
        """Write what is queued, the final status record, and finish the file."""
        with self._lock:
            self._accepting = False
        self._queue.put(None)
        self._thread.join(timeout_s)
        try:
            if self.error is None or not self.error.startswith("write failed"):
                self._writer.write_metadata(
                    STATUS_METADATA, {**(final_metadata or {}), "recorder": self.stats(), "finished": True}
                )
            self._writer.close()
        except OSError as exc:
            self.error = self.error or f"could not finish the file: {exc}"
