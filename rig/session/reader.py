"""Reading sessions: every complete record of an MCAP file, even a truncated one."""

from __future__ import annotations

import json
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.records import Channel, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from zstandard import ZstdError

from rig.camera import CameraModel
from rig.errors import InputError
from rig.messages import Frame, ImuSample, Scan
from rig.session import ros_messages as rm

#: What reading a damaged MCAP raises: the reader's own errors, short reads, a length field too
#: large for an index (OverflowError) or an allocation (MemoryError), a chunk that does not
#: decompress (ZstdError) or whose CRC does not match (McapError).
CORRUPTION_ERRORS: tuple[type[BaseException], ...] = (
    McapError,
    struct.error,
    EOFError,
    ValueError,
    OverflowError,
    MemoryError,
    ZstdError,
)


class _Bounded:
    """A binary file whose reads are clamped to the bytes left, so that a corrupt length field
    gives a short read (reported as truncation) instead of a multi-gigabyte allocation."""

    def __init__(self, f: Any, size: int) -> None:
        self._f, self._size = f, size

    def read(self, n: int = -1) -> bytes:
        left = self._size - self._f.tell()
        return self._f.read(left if n is None or n < 0 else max(0, min(n, left)))


def mcap_records(f: Any, size: int) -> Iterator[Any]:
    """Records of an open MCAP file of ``size`` bytes in file order, chunks unpacked and their
    CRCs checked (a flipped byte in a chunk is an error rather than a garbled message); no record
    may be longer than the file. Iterating raises one of :data:`CORRUPTION_ERRORS` where the
    file is damaged or ends."""
    reader = StreamReader(_Bounded(f, size), emit_chunks=False, validate_crcs=True, record_size_limit=size)
    return reader.records


@dataclass(frozen=True)
class SessionMessage:
    """One decoded message: ``msg`` is the rosbags message object."""

    topic: str
    msgtype: str
    t_host: int
    t_device: int | None
    msg: Any


@dataclass
class TopicSummary:
    msgtype: str
    count: int
    first_t: int
    last_t: int


class SessionReader:
    """Sequential reader of a session ``.mcap`` file.

    Reads records in file order with the ``mcap`` stream reader, which needs neither the summary
    nor the footer, so a recording cut short (crash, power loss) is read up to its last complete
    chunk; :attr:`truncated` then says so after a full pass.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError("no such session file", path=self.path)
        with self.path.open("rb") as f:
            if f.read(8) != b"\x89MCAP0\r\n":
                raise InputError("not an MCAP file (bad magic bytes)", path=self.path)
        self.truncated = False
        self.truncation_reason = ""

    def _records(self) -> Iterator[Any]:
        self.truncated = False
        with self.path.open("rb") as f:
            saw_footer = False
            try:
                for record in mcap_records(f, self.path.stat().st_size):
                    saw_footer = saw_footer or isinstance(record, Footer)
                    yield record
            except CORRUPTION_ERRORS as exc:
                self.truncated = True
                self.truncation_reason = f"{type(exc).__name__}: {exc}".strip()
                return
            if not saw_footer:
                self.truncated = True
                self.truncation_reason = "no footer"

    def metadata(self) -> dict[str, dict[str, Any]]:
        """Metadata records by name; values decoded from JSON where they are JSON."""
        out: dict[str, dict[str, Any]] = {}
        for record in self._records():
            if isinstance(record, Metadata):
                out[record.name] = {k: _maybe_json(v) for k, v in record.metadata.items()}
        return out

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[SessionMessage]:
        """Decoded messages in file order, optionally only those of ``topics``."""
        wanted = None if topics is None else set(topics)
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        for record in self._records():
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None or (wanted is not None and channel.topic not in wanted):
                    continue
                schema = schemas.get(channel.schema_id)
                if schema is None or channel.message_encoding != "cdr":
                    continue
                try:
                    msg = rm.deserialize(record.data, schema.name)
                except Exception as exc:  # rosbags raises assorted errors on malformed CDR
                    raise InputError(
                        f"message at log time {record.log_time} ns does not decode as {schema.name} "
                        f"({type(exc).__name__}: {exc})",
                        path=self.path,
                        field=channel.topic,
                    ) from None
                device_clock = channel.metadata.get("stamp_clock", "device") == "device"
                t_device = rm.stamp_ns(msg) if device_clock and hasattr(msg, "header") else None
                yield SessionMessage(channel.topic, schema.name, int(record.log_time), t_device, msg)

    def topics(self) -> dict[str, TopicSummary]:
        """Per topic: message type, count and first/last log time (ns), from a full pass."""
        summary: dict[str, TopicSummary] = {}
        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, str]] = {}
        for record in self._records():
            if isinstance(record, Schema):
                schemas[record.id] = record.name
            elif isinstance(record, Channel):
                channels[record.id] = (record.topic, schemas.get(record.schema_id, "?"))
            elif isinstance(record, Message) and record.channel_id in channels:
                topic, msgtype = channels[record.channel_id]
                entry = summary.get(topic)
                t = int(record.log_time)
                if entry is None:
                    summary[topic] = TopicSummary(msgtype, 1, t, t)
                else:
                    entry.count += 1
                    entry.first_t = min(entry.first_t, t)
                    entry.last_t = max(entry.last_t, t)
        return summary

    def _converted(self, topic: str, convert: Any) -> Iterator[Any]:
        for m in self.messages([topic]):
            try:
                yield convert(m)
            except InputError as exc:  # the converters know the topic, not the file
                raise InputError(
                    f"{exc.reason} (message at log time {m.t_host} ns)",
                    path=self.path,
                    field=exc.field or topic,
                ) from None

    def frames(self, topic: str) -> Iterator[Frame]:
        return self._converted(
            topic, lambda m: rm.msg_to_frame(m.msg, m.msgtype, m.t_host, m.t_device, topic)
        )

    def scans(self, topic: str) -> Iterator[Scan]:
        return self._converted(topic, lambda m: rm.msg_to_scan(m.msg, m.t_host, m.t_device, topic))

    def imu(self, topic: str) -> Iterator[ImuSample]:
        return self._converted(topic, lambda m: rm.msg_to_imu(m.msg, m.t_host, m.t_device, topic))

    def camera_model(self, topic: str) -> CameraModel:
        """The camera model of the first ``CameraInfo`` on ``topic``."""
        for m in self.messages([topic]):
            return rm.msg_to_camera(m.msg)
        raise InputError(f"no CameraInfo on topic {topic}", path=self.path, field=topic)


def _maybe_json(text: str) -> Any:
    try:
        return json.loads(text)
    except ValueError:
        return text
