"""Reading sessions: every complete record of an MCAP file, even a truncated one."""

from __future__ import annotations

import json
import struct
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.records import Channel, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from zstandard import ZstdError

from rig.errors import InputError
from rig.session import ros_messages as rm
from rig.session.source import Recording, SessionMessage, TimeSpan, TopicSummary

__all__ = ["CORRUPTION_ERRORS", "SessionMessage", "SessionReader", "TopicSummary", "mcap_records"]

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


class SessionReader(Recording):
    """Sequential reader of a session ``.mcap`` file.

    Reads records in file order with the ``mcap`` stream reader, which needs neither the summary
    nor the footer, so a recording cut short (crash, power loss) is read up to its last complete
    chunk; :attr:`truncated` then says so after a full pass. Times are the MCAP log times
    (``t_host``); ``t_device`` is the header stamp of channels stamped by the device clock.
    """

    format = "session"

    def __init__(
        self, path: str | Path, *, span: TimeSpan | None = None, topic_map: dict[str, str] | None = None
    ) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError("no such session file", path=self.path)
        with self.path.open("rb") as f:
            if f.read(8) != b"\x89MCAP0\r\n":
                raise InputError("not an MCAP file (bad magic bytes)", path=self.path)
        self.span = span
        self.topic_map = dict(topic_map or {})
        self.truncated = False
        self.truncation_reason = ""
        self._window: tuple[int, int | None] | None = None
        self._summary: dict[str, TopicSummary] | None = None

    def records(self) -> Iterator[Any]:
        """Every complete record in file order (chunks unpacked); sets :attr:`truncated` at the end."""
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

    def _bounds(self, whole: bool) -> tuple[int, int | None] | None:
        """``(first, stop)`` log times of the span (None: everything), from the first message."""
        if whole or self.span is None:
            return None
        if self._window is None:
            first = next((r.log_time for r in self.records() if isinstance(r, Message)), 0)
            self._window = self.span.window(int(first))
        return self._window

    def metadata(self) -> dict[str, dict[str, Any]]:
        """Metadata records by name; values decoded from JSON where they are JSON."""
        out: dict[str, dict[str, Any]] = {}
        for record in self.records():
            if isinstance(record, Metadata):
                out[record.name] = {k: _maybe_json(v) for k, v in record.metadata.items()}
        return out

    def messages(
        self, topics: Iterable[str] | None = None, *, whole: bool = False
    ) -> Iterator[SessionMessage]:
        """Decoded messages in file order, optionally only those of ``topics``; within :attr:`span`
        unless ``whole``."""
        wanted = None if topics is None else set(topics)
        bounds = self._bounds(whole)
        schemas: dict[int, Schema] = {}
        channels: dict[int, Channel] = {}
        for record in self.records():
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
                if not _inside(bounds, record.log_time):
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
        """Per topic within :attr:`span`: message type, count and first/last log time (ns), from
        a full pass (kept for later calls)."""
        if self._summary is not None:
            return dict(self._summary)
        bounds = self._bounds(whole=False)
        summary: dict[str, TopicSummary] = {}
        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, str]] = {}
        for record in self.records():
            if isinstance(record, Schema):
                schemas[record.id] = record.name
            elif isinstance(record, Channel):
                channels[record.id] = (record.topic, schemas.get(record.schema_id, "?"))
            elif isinstance(record, Message) and record.channel_id in channels:
                t = int(record.log_time)
                if not _inside(bounds, t):
                    continue
                topic, msgtype = channels[record.channel_id]
                entry = summary.get(topic)
                if entry is None:
                    summary[topic] = TopicSummary(msgtype, 1, t, t)
                else:
                    entry.count += 1
                    entry.first_t = min(entry.first_t, t)
                    entry.last_t = max(entry.last_t, t)
        self._summary = summary
        return dict(summary)


def _inside(bounds: tuple[int, int | None] | None, t: int) -> bool:
    return bounds is None or (bounds[0] <= t and (bounds[1] is None or t < bounds[1]))


def _maybe_json(text: str) -> Any:
    try:
        return json.loads(text)
    except ValueError:
        return text
