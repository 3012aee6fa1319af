"""Others' recordings read in place: ROS 1 bags (one or several split files), rosbag2 folders
(sqlite3 or MCAP storage) and bare MCAP files, with the interface of our own sessions.

Times follow :mod:`rig.session.stamps`: a message is timed by its header stamp (``t_host``; there
is no separate device clock, ``t_device`` is None), or by the bag's receive time when it has no
header or its stamps come from another clock. The time span selects by receive time.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

from rig.session.bag_files import BagFiles, McapFile, RosbagsFiles
from rig.session.source import Recording, SessionMessage, TimeSpan, TopicSummary
from rig.session.stamps import TopicClock, log_source


class BagRecording(Recording):
    """A recording made by others, streamed from its files.

    Args:
        paths: a ROS 1 ``.bag`` (several: the split files of one recording), a rosbag2 folder or
            a bare ``.mcap`` file.
        format: ``ROS 1 bag``, ``rosbag2`` or ``MCAP`` (see :func:`rig.session.bag_files.bag_format`).
        span: the part every reader sees; topic_map: ``{role: topic}``.
    """

    def __init__(
        self,
        paths: Sequence[Path],
        format: str,
        *,
        span: TimeSpan | None = None,
        topic_map: dict[str, str] | None = None,
    ) -> None:
        self.paths = [Path(p) for p in paths]
        self.path = self.paths[0]
        self.span = span
        self.topic_map = dict(topic_map or {})
        self.files: BagFiles = McapFile(self.path) if format == "MCAP" else RosbagsFiles(self.paths, format)
        self.format = format
        self._logged: set[str] = set()
        self._summary: dict[str, TopicSummary] | None = None

    @property
    def truncated(self) -> bool:  # type: ignore[override]
        return self.files.truncated

    @property
    def truncation_reason(self) -> str:  # type: ignore[override]
        return self.files.truncation_reason

    def input_files(self) -> list[Path]:
        return list(self.paths)

    def metadata(self) -> dict[str, dict[str, Any]]:
        return {}

    def _read(self, topics: Iterable[str] | None, whole: bool) -> Iterator[tuple[str, str, int, Any]]:
        window = (None, None) if whole or self.span is None else self.span.window(self.files.start_time())
        return self.files.read(None if topics is None else set(topics), *window)

    def messages(
        self, topics: Iterable[str] | None = None, *, whole: bool = False
    ) -> Iterator[SessionMessage]:
        """Decoded messages in time order, timed by the stamp rule; a topic whose header stamps
        are zero or go backwards raises :class:`~rig.errors.InputError` where it does."""
        clocks: dict[str, TopicClock] = {}
        for topic, msgtype, t_receive, msg in self._read(topics, whole):
            clock = clocks.get(topic)
            if clock is None:
                clock = clocks[topic] = TopicClock(self.path, topic)
            t = clock.time(msg, t_receive)
            if topic not in self._logged:
                self._logged.add(topic)
                log_source(clock)
            yield SessionMessage(topic, msgtype, t, None, msg)

    def topics(self) -> dict[str, TopicSummary]:
        """Per topic within the span: type, count, first/last time by the stamp rule and where
        the times come from (``refused: ...`` for a topic whose stamps cannot be used; its times
        are then the receive times). One full pass, kept for later calls."""
        if self._summary is None:
            summary: dict[str, TopicSummary] = {}
            clocks: dict[str, TopicClock] = {}
            refused: dict[str, str] = {}
            for topic, msgtype, t_receive, msg in self._read(None, whole=False):
                clock = clocks.setdefault(topic, TopicClock(self.path, topic))
                if topic not in refused and (problem := clock.problem(msg)):
                    refused[topic] = problem
                t = t_receive if topic in refused else clock.time(msg, t_receive)
                entry = summary.setdefault(topic, TopicSummary(msgtype, 0, t, t))
                entry.count += 1
                entry.first_t, entry.last_t = min(entry.first_t, t), max(entry.last_t, t)
            for topic, entry in summary.items():
                entry.stamps = f"refused: {refused[topic]}" if topic in refused else clocks[topic].source
            self._summary = summary
        return dict(self._summary)

    def topic_types(self) -> dict[str, tuple[str, int]]:
        """From the bag's index when the whole recording is read (no pass over the messages)."""
        return self.files.index() if self.span is None else super().topic_types()
