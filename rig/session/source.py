"""What every recording offers its readers, whichever file it came from: messages in file order,
per-topic summaries and the toolkit's types (frames, scans, IMU samples, camera models), within
an optional time span and with a topic map that says which topic plays which role.

:class:`~rig.session.reader.SessionReader` (our own MCAP sessions) and
:class:`~rig.session.bag.BagRecording` (others' bags) are the two kinds; open either with
:func:`rig.session.recording.open_recording`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.camera import CameraModel
from rig.errors import InputError
from rig.messages import Frame, ImuSample, Scan
from rig.session import ros_messages as rm


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
    """Message type, count and first/last time (ns) of one topic; ``stamps`` says where a bag
    topic's times come from (None in our sessions, whose times are the host clock)."""

    msgtype: str
    count: int
    first_t: int
    last_t: int
    stamps: str | None = None


@dataclass(frozen=True)
class TimeSpan:
    """Part of a recording: ``start_s`` seconds after its first message, lasting ``duration_s``
    (None: to the end). Selected by the recording's own clock (a session's host time, a bag's
    receive time)."""

    start_s: float = 0.0
    duration_s: float | None = None

    def __post_init__(self) -> None:
        if not self.start_s >= 0:
            raise InputError(f"expected a start >= 0 s, got {self.start_s}", field="--start")
        if self.duration_s is not None and not self.duration_s > 0:
            raise InputError(f"expected a duration > 0 s, got {self.duration_s}", field="--duration")

    def window(self, t0_ns: int) -> tuple[int, int | None]:
        """``(first, stop)`` ns of the span in a recording whose first message is at ``t0_ns``
        (``stop`` excluded; None: no end)."""
        first = t0_ns + round(self.start_s * 1e9)
        return first, None if self.duration_s is None else first + round(self.duration_s * 1e9)

    def describe(self) -> str:
        """The span as the command line gives it, e.g. ``--start 5 --duration 20``."""
        return f"--start {self.start_s:g}" + (
            "" if self.duration_s is None else f" --duration {self.duration_s:g}"
        )


class Recording(ABC):
    """A recording read through one interface.

    Attributes:
        path: the file or folder named in errors (the first of several split bags).
        format: ``session`` (ours), ``ROS 1 bag``, ``rosbag2`` or ``MCAP``.
        span: the part of the recording every reader sees (None: all of it).
        topic_map: ``{role: topic}`` chosen by the user (roles of
            :data:`rig.session.topic_map.ROLES`); :func:`rig.session.find_topics` fills in the rest.
        truncated: whether the last full pass ended at a damaged or cut-off part of the file.
    """

    path: Path
    format: str
    span: TimeSpan | None
    topic_map: dict[str, str]
    truncated: bool = False
    truncation_reason: str = ""

    def input_files(self) -> list[Path]:
        """The files and folders the recording is read from (what a change to must redo its stages)."""
        return [self.path]

    @abstractmethod
    def metadata(self) -> dict[str, dict[str, Any]]:
        """Metadata records by name (empty for bags)."""

    @abstractmethod
    def messages(
        self, topics: Iterable[str] | None = None, *, whole: bool = False
    ) -> Iterator[SessionMessage]:
        """Decoded messages in file order, optionally only those of ``topics``; within :attr:`span`
        unless ``whole``."""

    @abstractmethod
    def topics(self) -> dict[str, TopicSummary]:
        """Per topic within :attr:`span`: message type, count and first/last time (ns), from a full pass."""

    def topic_types(self) -> dict[str, tuple[str, int]]:
        """``{topic: (msgtype, count)}`` within :attr:`span`, as cheaply as the file allows."""
        return {name: (s.msgtype, s.count) for name, s in self.topics().items()}

    def _converted(self, topic: str, convert: Callable[[SessionMessage], Any]) -> Iterator[Any]:
        for m in self.messages([topic]):
            try:
                yield convert(m)
            except InputError as exc:  # the converters know the topic, not the file
                raise InputError(
                    f"{exc.reason} (message at {m.t_host} ns)", path=self.path, field=exc.field or topic
                ) from None

    def frames(self, topic: str) -> Iterator[Frame]:
        return self._converted(
            topic, lambda m: rm.msg_to_frame(m.msg, m.msgtype, m.t_host, m.t_device, topic)
        )

    def scans(self, topic: str) -> Iterator[Scan]:
        return self._converted(topic, lambda m: rm.msg_to_scan(m.msg, m.t_host, m.t_device, topic))

    def imu(self, topic: str) -> Iterator[ImuSample]:
        return self._converted(topic, lambda m: rm.msg_to_imu(m.msg, m.t_host, m.t_device, topic))

    def stamps(self, topic: str) -> np.ndarray:
        """Times ``(N,)`` int64 ns of the messages on ``topic`` within :attr:`span`, in file order."""
        return np.array([m.t_host for m in self.messages([topic])], dtype=np.int64)

    def frames_at(self, topic: str, indices: np.ndarray) -> Iterator[Frame]:
        """The frames at ``indices`` ``(K,)`` (increasing positions among :meth:`stamps`),
        decoding only those."""
        wanted = set(np.asarray(indices).tolist())
        selected = (m for index, m in enumerate(self.messages([topic])) if index in wanted)
        for m in selected:
            try:
                yield rm.msg_to_frame(m.msg, m.msgtype, m.t_host, m.t_device, topic)
            except InputError as exc:
                raise InputError(
                    f"{exc.reason} (message at {m.t_host} ns)", path=self.path, field=exc.field or topic
                ) from None

    def camera_model(self, topic: str) -> CameraModel:
        """The camera model of the first ``CameraInfo`` on ``topic`` (whole recording: a camera
        info published once at the start still counts when a span starts later)."""
        for m in self.messages([topic], whole=True):
            try:
                return rm.msg_to_camera(m.msg)
            except InputError as exc:
                raise InputError(exc.reason, path=self.path, field=topic) from None
        raise InputError(f"no CameraInfo on topic {topic}", path=self.path, field=topic)
