"""The time of a bag message: the sensor's header stamp, or the bag's receive time.

A bag records when each message *arrived*; the header stamp says when the sensor *measured* it,
which is what aligning camera and LiDAR needs. So a topic is timed by its header stamps when
they are sane, and refused when they are zero or go backwards (its driver did not stamp it, or
stamped it from a clock that jumps: aligning by it would be silently wrong). A topic without a
header is timed by the receive time, and so is one whose stamps come from another clock than the
bag's (more than :data:`MAX_CLOCK_GAP_S` from its receive times, e.g. a LiDAR counting from
power-on): two sensors' own clocks would put camera and LiDAR hours apart. Which rule a topic
follows is decided at its first message and logged once.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from rig.errors import InputError
from rig.session import ros_messages as rm

logger = logging.getLogger(__name__)

#: Header stamps further than this from the bag's receive time are taken for another clock (s).
MAX_CLOCK_GAP_S = 60.0
HEADER = "header stamps"


class TopicClock:
    """The stamp rule for one topic, applied message by message in file order.

    Attributes:
        source: ``header stamps`` or ``receive time (...)``, once a message was timed.
    """

    def __init__(self, path: Path, topic: str) -> None:
        self.path, self.topic = path, topic
        self.source: str | None = None
        self.count = 0
        self._last: int | None = None

    def problem(self, msg: Any) -> str | None:
        """Why the next message cannot be timed (None when it can)."""
        if not hasattr(msg, "header") or self.source not in (None, HEADER):
            return None
        stamp = rm.stamp_ns(msg)
        if stamp <= 0:
            return f"header stamp of message {self.count + 1} is zero"
        if self._last is not None and stamp < self._last:
            return (
                f"header stamps go backwards at message {self.count + 1} "
                f"(by {(self._last - stamp) / 1e6:.3f} ms)"
            )
        return None

    def time(self, msg: Any, t_receive: int) -> int:
        """The time (ns) of the next message on the topic; raises :class:`InputError` naming the
        file and topic when its header stamp is zero or earlier than the one before."""
        problem = self.problem(msg)
        if problem is not None:
            raise InputError(
                f"{problem}; expected the sensor's time, increasing (a bag is aligned by the header "
                "stamps of the topics it is read by)",
                path=self.path,
                field=self.topic,
            )
        self.count += 1
        if self.source is None:
            self.source = self._first_source(msg, t_receive)
        if self.source != HEADER:
            return t_receive
        self._last = rm.stamp_ns(msg)
        return self._last

    @staticmethod
    def _first_source(msg: Any, t_receive: int) -> str:
        if not hasattr(msg, "header"):
            return "receive time (no header)"
        gap_s = (t_receive - rm.stamp_ns(msg)) / 1e9
        if abs(gap_s) > MAX_CLOCK_GAP_S:
            return f"receive time (its header stamps are on another clock, {abs(gap_s):.1f} s from the bag's)"
        return HEADER

    def describe(self) -> str:
        """``PATH: TOPIC: times from SOURCE``."""
        return f"{self.path}: {self.topic}: times from {self.source}"


def log_source(clock: TopicClock) -> None:
    """Say where a topic's times come from (INFO on this module's logger; the CLIs show it)."""
    logger.info("%s", clock.describe())
