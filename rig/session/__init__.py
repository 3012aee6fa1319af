"""Sessions: ROS 2 messages in plain MCAP files, written by ``rig record`` and the virtual rig.

Writing (:class:`SessionWriter`, synchronous; :class:`SessionRecorder`, threaded with a bounded
queue), reading (:class:`SessionReader`, tolerant of truncated files), ``rig info``
(:func:`session_info`), ``rig recover`` (:func:`recover`), ``rig replay`` (:func:`replay`), and
others' recordings through a topic map (:func:`read_foreign`), and each role's topic found by message
type (:func:`find_topics`).
"""

from rig.session.foreign import (
    UT_MM_TOPICS,
    ForeignMessage,
    list_topics,
    read_foreign,
    read_foreign_trajectory,
)
from rig.session.info import session_info
from rig.session.reader import SessionMessage, SessionReader, TopicSummary
from rig.session.recorder import DROP_POLICIES, STATUS_METADATA, SessionRecorder
from rig.session.recover import RECOVERY_METADATA, recover
from rig.session.replay import replay
from rig.session.topics import SessionTopics, find_topics
from rig.session.writer import DEFAULT_TOPICS, SESSION_METADATA, SessionWriter

__all__ = [
    "DEFAULT_TOPICS",
    "DROP_POLICIES",
    "RECOVERY_METADATA",
    "SESSION_METADATA",
    "STATUS_METADATA",
    "UT_MM_TOPICS",
    "ForeignMessage",
    "SessionMessage",
    "SessionReader",
    "SessionRecorder",
    "SessionTopics",
    "SessionWriter",
    "TopicSummary",
    "find_topics",
    "list_topics",
    "read_foreign",
    "read_foreign_trajectory",
    "recover",
    "replay",
    "session_info",
]
