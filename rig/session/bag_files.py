"""The files of others' recordings, message by message: which topics they hold, and their
decoded messages in time order with the bag's receive times.

ROS 1 bags (one file, or several split files of one recording, merged in time order) and rosbag2
folders (sqlite3 or MCAP storage) are read with rosbags' ``AnyReader``, which seeks through the
bag's index; a bare MCAP file (no ``metadata.yaml``) is read record by record, its types taken
from its schemas. Both stream: one message at a time is in memory.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import Any, Protocol

from rig.errors import InputError
from rig.session import ros_messages as rm

ROS1_MAGIC = b"#ROSBAG V2.0\n"
MCAP_MAGIC = b"\x89MCAP0\r\n"

#: ``(topic, msgtype, receive time ns, message)``.
RawMessage = tuple[str, str, int, Any]


def bag_format(path: Path) -> str | None:
    """``ROS 1 bag``, ``rosbag2`` or ``MCAP`` by content (a rosbag2 folder by its
    ``metadata.yaml``); None when ``path`` is none of them."""
    if path.is_dir():
        return "rosbag2" if (path / "metadata.yaml").is_file() else None
    try:
        with path.open("rb") as f:
            head = f.read(len(ROS1_MAGIC))
    except OSError:
        return None
    if head == ROS1_MAGIC:
        return "ROS 1 bag"
    return "MCAP" if head.startswith(MCAP_MAGIC) else None


class BagFiles(Protocol):
    """What :class:`~rig.session.bag.BagRecording` needs of a bag's files."""

    format: str
    #: Whether the last full pass stopped at a damaged or cut-off part (and why).
    truncated: bool
    truncation_reason: str

    def start_time(self) -> int:
        """Receive time (ns) of the first message."""

    def index(self) -> dict[str, tuple[str, int]]:
        """``{topic: (msgtype, count)}`` of the whole bag."""

    def read(self, topics: set[str] | None, start: int | None, stop: int | None) -> Iterator[RawMessage]:
        """Decoded messages of ``topics`` (None: all) received in ``[start, stop)``, in time order."""


class RosbagsFiles:
    """ROS 1 bags (one or several split files) or a rosbag2 folder, through rosbags' ``AnyReader``
    (which refuses a damaged bag rather than reading part of it)."""

    truncated = False
    truncation_reason = ""

    def __init__(self, paths: Sequence[Path], format: str) -> None:
        self.paths, self.format = list(paths), format
        with self._reader() as reader:
            self._start = int(reader.start_time) if reader.connections else 0
            self._index: dict[str, tuple[str, int]] = {}
            for c in reader.connections:
                msgtype, count = self._index.get(c.topic, (c.msgtype, 0))
                self._index[c.topic] = (msgtype, count + c.msgcount)

    @contextmanager
    def _reader(self) -> Iterator[Any]:
        from rosbags.highlevel import AnyReader
        from rosbags.highlevel.anyreader import AnyReaderError

        reader = AnyReader(self.paths, default_typestore=rm.typestore())
        try:
            reader.open()
        except AnyReaderError as exc:
            hint = " (a bag cut short or still being recorded: `rosbag reindex` repairs it)"
            raise InputError(
                f"cannot read the {self.format}: {exc}{hint if self.format == 'ROS 1 bag' else ''}",
                path=self.paths[0],
            ) from None
        try:
            yield reader
        finally:
            reader.close()

    def start_time(self) -> int:
        return self._start

    def index(self) -> dict[str, tuple[str, int]]:
        return dict(self._index)

    def read(self, topics: set[str] | None, start: int | None, stop: int | None) -> Iterator[RawMessage]:
        with self._reader() as reader:
            connections = [c for c in reader.connections if topics is None or c.topic in topics]
            if not connections:
                return
            try:
                for c, t, raw in reader.messages(connections=connections, start=start, stop=stop):
                    yield (
                        c.topic,
                        c.msgtype,
                        int(t),
                        _decoded(reader.deserialize, raw, c.msgtype, t, self.paths[0], c.topic),
                    )
            except InputError:
                raise
            except Exception as exc:  # rosbags' reader errors on a damaged chunk
                raise InputError(
                    f"cannot read the {self.format}: {type(exc).__name__}: {exc}", path=self.paths[0]
                ) from None


class McapFile:
    """A bare MCAP file recorded by others: ROS 2 (CDR) or ROS 1 messages, types from its schemas."""

    format = "MCAP"

    def __init__(self, path: Path) -> None:
        from rosbags.typesys import Stores, get_typestore

        from rig.session.reader import SessionReader

        self.path = path
        self._container = SessionReader(path)
        self._types = get_typestore(Stores.EMPTY)
        self._start: int | None = None
        self._index: dict[str, tuple[str, int]] | None = None

    @property
    def truncated(self) -> bool:
        return self._container.truncated

    @property
    def truncation_reason(self) -> str:
        return self._container.truncation_reason

    def _records(self) -> Iterator[tuple[str, str, int, bytes, str]]:
        """``(topic, msgtype, log time, data, encoding)`` of every message, registering types."""
        from mcap.records import Channel, Message, Schema

        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, str, str]] = {}
        for record in self._container.records():
            if isinstance(record, Schema):
                schemas[record.id] = record.name
                self._register(record)
            elif isinstance(record, Channel):
                channels[record.id] = (
                    record.topic,
                    schemas.get(record.schema_id, ""),
                    record.message_encoding,
                )
            elif isinstance(record, Message) and record.channel_id in channels:
                topic, msgtype, encoding = channels[record.channel_id]
                yield topic, msgtype, int(record.log_time), record.data, encoding

    def _register(self, schema: Any) -> None:
        from rosbags.typesys import get_types_from_idl, get_types_from_msg
        from rosbags.typesys.base import TypesysError

        text = schema.data.decode(errors="replace")
        if schema.name in self._types.FIELDDEFS or not text.strip():
            return
        try:
            parsed = (
                get_types_from_idl(text)
                if schema.encoding == "ros2idl"
                else get_types_from_msg(text, schema.name)
            )
            self._types.register(parsed)
        except TypesysError as exc:
            raise InputError(f"cannot parse the schema of {schema.name} ({exc})", path=self.path) from None

    def start_time(self) -> int:
        if self._start is None:
            self._start = next((t for _, _, t, _, _ in self._records()), 0)
        return self._start

    def index(self) -> dict[str, tuple[str, int]]:
        if self._index is None:
            index: dict[str, tuple[str, int]] = {}
            for topic, msgtype, _, _, _ in self._records():
                index[topic] = (msgtype, index.get(topic, (msgtype, 0))[1] + 1)
            self._index = index
        return dict(self._index)

    def read(self, topics: set[str] | None, start: int | None, stop: int | None) -> Iterator[RawMessage]:
        for topic, msgtype, t, data, encoding in self._records():
            if topics is not None and topic not in topics:
                continue
            if (start is not None and t < start) or (stop is not None and t >= stop):
                continue
            decode = partial(self._deserialize, encoding=encoding)
            yield topic, msgtype, t, _decoded(decode, data, msgtype, t, self.path, topic)

    def _deserialize(self, data: bytes, msgtype: str, encoding: str) -> Any:
        store = self._types if msgtype in self._types.FIELDDEFS else rm.typestore()
        if encoding == "cdr":
            return store.deserialize_cdr(data, msgtype)
        if encoding == "ros1":
            return store.deserialize_ros1(data, msgtype)
        raise InputError(
            f"message encoding {encoding!r} is not supported (expected cdr or ros1)", path=self.path
        )


def _decoded(
    deserialize: Callable[[bytes, str], Any], data: bytes, msgtype: str, t: int, path: Path, topic: str
) -> Any:
    try:
        return deserialize(data, msgtype)
    except InputError:
        raise
    except Exception as exc:  # rosbags raises assorted errors on malformed or unknown messages
        raise InputError(
            f"message received at {t} ns does not decode as {msgtype} ({type(exc).__name__}: {exc})",
            path=path,
            field=topic,
        ) from None
