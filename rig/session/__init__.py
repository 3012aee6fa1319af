"""Sessions: ROS 2 messages in plain MCAP files, written by ``rig record`` and the virtual rig.

Writing (:class:`SessionWriter`, synchronous; :class:`SessionRecorder`, threaded with a bounded
queue), reading (:class:`SessionReader`, tolerant of truncated files), ``rig info``
(:func:`session_info`), ``rig recover`` (:func:`recover`), ``rig replay`` (:func:`replay`), and
any recording the offline commands take, our sessions or others' bags read in place
(:func:`open_recording`, with a topic map :func:`parse_topic_map` and a :class:`TimeSpan`), and each
role's topic found by choice or message type (:func:`find_topics`).
"""

from rig.session.bag import BagRecording
from rig.session.foreign import (
    UT_MM_TOPICS,
    ForeignMessage,
    list_topics,
    read_foreign,
    read_foreign_trajectory,
)
from rig.session.info import session_info
from rig.session.reader import SessionReader
from rig.session.recorder import DROP_POLICIES, STATUS_METADATA, SessionRecorder
from rig.session.recording import as_recording, open_recording
from rig.session.recover import RECOVERY_METADATA, recover
from rig.session.replay import replay
from rig.session.source import Recording, SessionMessage, TimeSpan, TopicSummary
from rig.session.topic_map import PRESETS as TOPIC_MAP_PRESETS
from rig.session.topic_map import parse_topic_map
from rig.session.topics import SessionTopics, find_topics
from rig.session.writer import DEFAULT_TOPICS, SESSION_METADATA, SessionWriter

__all__ = [
    "DEFAULT_TOPICS",
    "DROP_POLICIES",
    "RECOVERY_METADATA",
    "SESSION_METADATA",
    "STATUS_METADATA",
    "TOPIC_MAP_PRESETS",
    "UT_MM_TOPICS",
    "BagRecording",
    "ForeignMessage",
    "Recording",
    "SessionMessage",
    "SessionReader",
    "SessionRecorder",
    "SessionTopics",
    "SessionWriter",
    "TimeSpan",
    "TopicSummary",
    "as_recording",
    "find_topics",
    "list_topics",
    "open_recording",
    "parse_topic_map",
    "read_foreign",
    "read_foreign_trajectory",
    "recover",
    "replay",
    "session_info",
]
