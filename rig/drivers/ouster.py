"""Ouster LiDARs through ``ouster-sdk`` (the ``ouster`` extra): a live sensor or a pcap + metadata.

Each complete frame becomes a :class:`~rig.messages.Scan`: XYZ from the sensor's lookup table
(points with zero range dropped), intensity = reflectivity, per-point time from the per-column
timestamps. ``t_device`` is the first valid column's timestamp (sensor clock).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from rig.drivers.base import DeviceError, Driver, Message, now_ns
from rig.errors import InputError
from rig.messages import Scan


def frame_to_scan(frame: Any, xyz_lut: Any, t_host: int, lidar_id: str) -> Scan:
    """A Scan from one ouster ``LidarScan`` (``(H, W)`` fields, ``(W,)`` column timestamps)."""
    from ouster.sdk import core

    rng = frame.field(core.ChanField.RANGE)
    xyz = xyz_lut(frame)  # (H, W, 3) metres
    valid = rng > 0
    col_t = np.asarray(frame.timestamp, dtype=np.int64)
    cols = np.flatnonzero(col_t > 0)
    stamp = int(col_t[cols[0]]) if cols.size else 0
    t_grid = np.broadcast_to(col_t[None, :], rng.shape)
    valid &= t_grid >= stamp
    names = frame.fields
    refl = (
        frame.field(core.ChanField.REFLECTIVITY)
        if core.ChanField.REFLECTIVITY in names
        else np.zeros_like(rng)
    )
    return Scan(
        xyz[valid].astype(np.float32),
        ((t_grid[valid] - stamp) * 1e-9).astype(np.float32),
        refl[valid].astype(np.float32),
        t_host=t_host,
        t_device=stamp,
        lidar_id=lidar_id,
    )


def read_pcap(pcap: str | Path, meta: str | Path, lidar_id: str = "ouster") -> Iterator[Scan]:
    """Scans of a recorded pcap (``t_host`` = ``t_device``: a pcap holds no host clock of ours)."""
    from ouster.sdk import core
    from ouster.sdk.pcap import PcapFrameSetSource

    for path in (pcap, meta):
        if not Path(path).is_file():
            raise DeviceError(f"no such file: {path}")
    source = PcapFrameSetSource(str(pcap), meta=[str(meta)])
    try:
        lut = core.XYZLut(source.sensor_info[0])
        for frames in source:
            frame = frames[0]
            if frame is not None and frame.complete():
                scan = frame_to_scan(frame, lut, 0, lidar_id)
                scan.t_host = int(scan.t_device or 0)
                yield scan
    finally:
        source.close()


def read_packet_bag(
    bag: str | Path,
    packets_topic: str = "/os_node/lidar_packets",
    metadata_topic: str = "/os_node/metadata",
    lidar_id: str = "ouster",
) -> Iterator[Scan]:
    """Scans decoded from raw lidar packets in a ROS bag (``ouster_ros/PacketMsg``, ``buf``), with
    the sensor metadata JSON from a ``std_msgs/String`` topic. ``t_host`` = the bag time of the
    scan's first packet; only complete frames are returned."""
    from ouster.sdk import core

    from rig.session.foreign import raw_messages

    bag = Path(bag)
    meta = next((m for _, _, _, m in raw_messages(bag, {metadata_topic})), None)
    if meta is None:
        raise InputError("no sensor metadata in the bag", path=bag, field=metadata_topic)
    info = core.SensorInfo(meta.data)
    fmt, batcher, frame, lut = (
        core.PacketFormat(info),
        core.FrameBatcher(info),
        core.LidarFrame(info),
        core.XYZLut(info),
    )
    first_t = None
    for _, _, t_log, msg in raw_messages(bag, {packets_topic}):
        packet = core.LidarPacket(fmt)
        buf = np.asarray(msg.buf, dtype=np.uint8)
        if buf.size != packet.buf.size:
            raise InputError(f"packet of {buf.size} bytes; the metadata says {packet.buf.size}", path=bag)
        packet.buf[:] = buf
        if batcher.batch(packet, frame):  # a packet of the next frame: the previous one is done
            if frame.complete():
                yield frame_to_scan(frame, lut, first_t or t_log, lidar_id)
            first_t = None
        first_t = first_t or t_log
    if frame.complete():
        yield frame_to_scan(frame, lut, first_t or 0, lidar_id)


class OusterDriver(Driver):
    """A live Ouster sensor (``hostname``) or a pcap replayed as fast as it decodes (``pcap`` + ``meta``).

    A replayed frame is stamped on the host clock by the pcap's own clock: the host time of the
    first frame plus the sensor time since it, so frames keep their spacing however fast they
    decode (arrival times squeezed 3 frames of 0.1 s into 13 ms, and de-skewing with those
    stamps moved points by the wrong motion). The driver is :attr:`finished` at the pcap's end.
    """

    kind = "ouster"

    def __init__(
        self, name: str, hostname: str | None = None, pcap: str | None = None, meta: str | None = None
    ) -> None:
        super().__init__(name)
        if not hostname and not (pcap and meta):
            raise ValueError("give a sensor hostname, or a pcap and its metadata json")
        self.hostname, self.pcap, self.meta = hostname, pcap, meta
        self._source: Any = None
        self._iter: Iterator[Any] | None = None
        self._lut: Any = None
        self._sn = ""
        self._replay_origin: tuple[int, int] | None = None  # (host, sensor) ns of the first pcap frame
        self._replayed_all = False

    def open(self) -> None:
        try:
            from ouster.sdk import core, open_source
        except ImportError as exc:
            raise DeviceError("ouster-sdk is not installed (pip install 'lidar-ts[ouster]')") from exc
        try:
            if self.hostname:
                self._source = open_source(self.hostname)
            else:
                from ouster.sdk.pcap import PcapFrameSetSource

                self._source = PcapFrameSetSource(str(self.pcap), meta=[str(self.meta)])
        except (RuntimeError, ValueError, OSError) as exc:
            raise DeviceError(f"cannot open Ouster source {self.hostname or self.pcap}: {exc}") from exc
        info = self._source.sensor_info[0]
        self._sn = str(info.sn)
        self._lut = core.XYZLut(info)
        self._iter = iter(self._source)

    def device_id(self) -> str:
        return self._sn or self.name

    def read(self, timeout_s: float = 0.1) -> list[Message]:
        if self._iter is None:
            return []
        frames = next(self._iter, None)
        if frames is None:
            self._iter = None
            self._replayed_all = not self.hostname  # a pcap (the constructor asks for one or the other)
            return []
        frame = frames[0]
        self.health.packets += 1
        if frame is None or not frame.complete():
            self.health.dropped += 1
            return []
        self.health.received += 1
        scan = frame_to_scan(frame, self._lut, now_ns(), self.name)
        if not self.hostname:
            host, sensor = self._replay_origin = self._replay_origin or (scan.t_host, int(scan.t_device or 0))
            scan.t_host = host + int(scan.t_device or 0) - sensor
        return [scan]

    @property
    def finished(self) -> bool:
        return self._replayed_all

    def close(self) -> None:
        if self._source is not None:
            self._source.close()
            self._source = None
            self._iter = None
