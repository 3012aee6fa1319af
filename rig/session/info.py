"""``rig info``: what a session holds, what went wrong while recording, and whether it was cut short."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rig.session.reader import SessionReader
from rig.session.recorder import STATUS_METADATA
from rig.session.writer import SESSION_METADATA


def session_info(path: str | Path) -> dict[str, Any]:
    """The ``rig info --json`` object.

    ``{"topics": {NAME: {"type", "count", "first_t", "last_t"}}, "duration_s", "errors": {...},
    "truncated", "truncation_reason", "messages", "session", "clock"}``; times are t_host ns.
    ``errors`` holds the recorder's drops and write error and each device's health counters, from
    the last status record (the final one, or the last written before a crash).
    """
    reader = SessionReader(path)
    topics = reader.topics()
    meta = reader.metadata()
    status = meta.get(STATUS_METADATA, {})
    recorder = status.get("recorder", {}) if isinstance(status.get("recorder"), dict) else {}
    devices = status.get("devices", {}) if isinstance(status.get("devices"), dict) else {}
    errors: dict[str, Any] = {
        "dropped": recorder.get("dropped", {}),
        "write_error": recorder.get("error"),
        "devices": {name: {k: v for k, v in h.items() if k != "clock"} for name, h in devices.items()},
    }
    firsts = [t.first_t for t in topics.values()]
    lasts = [t.last_t for t in topics.values()]
    return {
        "topics": {
            name: {"type": t.msgtype, "count": t.count, "first_t": t.first_t, "last_t": t.last_t}
            for name, t in topics.items()
        },
        "duration_s": (max(lasts) - min(firsts)) / 1e9 if topics else 0.0,
        "errors": errors,
        "truncated": reader.truncated,
        "truncation_reason": reader.truncation_reason,
        "finished": bool(status.get("finished", False)),
        "messages": sum(t.count for t in topics.values()),
        "session": meta.get(SESSION_METADATA, {}),
        "clock": {name: h.get("clock") for name, h in devices.items() if h.get("clock")},
    }
