"""Sessions: ROS 2 messages in plain MCAP files, written by ``rig record`` and the virtual rig."""

from rig.session.reader import SessionMessage, SessionReader, TopicSummary
from rig.session.writer import DEFAULT_TOPICS, SESSION_METADATA, SessionWriter

__all__ = [
    "DEFAULT_TOPICS",
    "SESSION_METADATA",
    "SessionMessage",
    "SessionReader",
    "SessionWriter",
    "TopicSummary",
]
