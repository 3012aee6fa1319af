"""Session recording: ROS 2 messages (CDR) in a plain MCAP file.

The container is written with the ``mcap`` package in chunks, so a recorder that is killed leaves
a file whose complete chunks are all readable (see :class:`rig.session.SessionReader`).
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from types import TracebackType
from typing import Any

from mcap.writer import CompressionType, Writer

from rig.camera import CameraModel
from rig.messages import Frame, ImuSample, Scan
from rig.session import ros_messages as rm
from rig.version import package_version

#: Default topic names of a session recorded by this toolkit.
DEFAULT_TOPICS = {
    "image": "/camera/image/compressed",
    "camera_info": "/camera/camera_info",
    "points": "/lidar/points",
    "imu": "/imu/data",
}
#: Name of the MCAP metadata record holding the recording's description.
SESSION_METADATA = "lidar_ts.session"


class SessionWriter:
    """Write frames, scans, IMU samples and camera infos to ``path`` as a ROS 2 MCAP session.

    Use as a context manager; :meth:`close` finishes the file (summary, footer, end magic).

    Args:
        path: output ``.mcap`` file (overwritten).
        metadata: free-form description stored in the ``lidar_ts.session`` metadata record
            (rig configuration, device ids, ...); the software version is added.
        image_format: ``jpeg`` (default), ``png`` (lossless) or ``raw`` (``sensor_msgs/Image``).
        chunk_size: bytes per MCAP chunk: the most a crash can lose.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        metadata: dict[str, Any] | None = None,
        image_format: str = "jpeg",
        jpeg_quality: int = 95,
        chunk_size: int = 1 << 20,
    ) -> None:
        self.path = Path(path)
        self.image_format = image_format
        self.jpeg_quality = jpeg_quality
        self._file = self.path.open("wb")
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library=f"lidar-ts {package_version()}")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str, str]] = {}
        self.counts: Counter[str] = Counter()
        self._closed = False
        self._final_bytes = 0
        self.write_metadata(SESSION_METADATA, {**(metadata or {}), "software_version": package_version()})

    def write_metadata(self, name: str, data: dict[str, Any]) -> None:
        """Store a metadata record; values are JSON-encoded strings (MCAP metadata is str → str)."""
        self._writer.add_metadata(name, {str(k): json.dumps(v) for k, v in data.items()})

    def _channel(self, topic: str, msgtype: str, stamp_clock: str) -> int:
        known = self._channels.get(topic)
        if known is not None:
            channel_id, known_type, known_clock = known
            if (known_type, known_clock) != (msgtype, stamp_clock):
                raise ValueError(
                    f"topic {topic} was opened as {known_type} stamped by the {known_clock} clock; "
                    f"got {msgtype} stamped by the {stamp_clock} clock"
                )
            return channel_id
        if msgtype not in self._schemas:
            self._schemas[msgtype] = self._writer.register_schema(
                name=msgtype, encoding="ros2msg", data=rm.message_definition(msgtype).encode()
            )
        channel_id = self._writer.register_channel(
            topic=topic,
            message_encoding="cdr",
            schema_id=self._schemas[msgtype],
            metadata={"stamp_clock": stamp_clock},
        )
        self._channels[topic] = (channel_id, msgtype, stamp_clock)
        return channel_id

    def write_message(self, topic: str, msg: Any, t_host: int, t_device: int | None) -> None:
        """Write any ROS 2 message object from the session typestore, logged at ``t_host``."""
        if self._closed:
            raise ValueError(f"session {self.path} is closed")
        clock = "host" if t_device is None else "device"
        channel_id = self._channel(topic, msg.__msgtype__, clock)
        self._writer.add_message(
            channel_id,
            log_time=int(t_host),
            data=rm.serialize(msg),
            publish_time=int(t_host),
            sequence=self.counts[topic],
        )
        self.counts[topic] += 1

    def write_frame(
        self, frame: Frame, topic: str = DEFAULT_TOPICS["image"], frame_id: str = "camera"
    ) -> None:
        msg = rm.frame_to_msg(frame, frame_id, self.image_format, self.jpeg_quality)
        self.write_message(topic, msg, frame.t_host, frame.t_device)

    def write_camera_info(
        self,
        camera: CameraModel,
        t_host: int,
        t_device: int | None = None,
        topic: str = DEFAULT_TOPICS["camera_info"],
        frame_id: str = "camera",
    ) -> None:
        self.write_message(topic, rm.camera_to_msg(camera, t_host, t_device, frame_id), t_host, t_device)

    def write_scan(self, scan: Scan, topic: str = DEFAULT_TOPICS["points"], frame_id: str = "lidar") -> None:
        self.write_message(topic, rm.scan_to_msg(scan, frame_id), scan.t_host, scan.t_device)

    def write_imu(self, sample: ImuSample, topic: str = DEFAULT_TOPICS["imu"], frame_id: str = "imu") -> None:
        self.write_message(topic, rm.imu_to_msg(sample, frame_id), sample.t_host, sample.t_device)

    @property
    def bytes_written(self) -> int:
        """Bytes handed to the file so far (the open chunk is not counted until it is full)."""
        return self._final_bytes if self._file.closed else self._file.tell()

    def flush(self) -> None:
        """Push buffered bytes to the operating system, so a killed process loses only the open chunk."""
        self._file.flush()

    def close(self) -> None:
        """Finish the file: last chunk, summary and footer."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()
        finally:
            self._final_bytes = self._file.tell()
            self._file.close()

    def __enter__(self) -> SessionWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
