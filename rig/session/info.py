"""``rig info``: what a recording holds, what went wrong while recording, and whether it was cut short."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from rig.errors import InputError
from rig.session.recorder import STATUS_METADATA
from rig.session.recording import open_recording
from rig.session.source import TimeSpan
from rig.session.topics import find_topics
from rig.session.writer import SESSION_METADATA


def session_info(
    paths: str | Path | Sequence[str | Path],
    span: TimeSpan | None = None,
    topic_map: dict[str, str] | None = None,
    camera: int | None = None,
) -> dict[str, Any]:
    """The ``rig info --json`` object of a session or a bag (several paths: split bags).

    ``{"topics": {NAME: {"type", "count", "first_t", "last_t"}}, "duration_s", "errors": {...},
    "truncated", "truncation_reason", "messages", "session", "clock", "format", "roles"}``; times
    are t_host ns (a bag's follow :mod:`rig.session.stamps`; each topic says which in ``stamps``).
    ``errors`` holds the recorder's drops and write error and each device's health counters, from
    the last status record (the final one, or the last written before a crash); ``finished`` is
    None for bags. ``roles`` is the topic of each role as the offline commands would pick it with
    ``topic_map`` (None, and ``roles_problem`` says why, when the map leaves a role ambiguous; a
    map naming a missing topic raises :class:`~rig.errors.InputError`).
    """
    reader = open_recording(paths, span=span, topic_map=topic_map, camera=camera)
    topics = reader.topics()
    try:
        roles, problem = asdict(find_topics(reader, require_points=False)), None
    except InputError as exc:
        if topic_map:
            raise
        roles, problem = None, exc.reason
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
            name: {
                "type": t.msgtype,
                "count": t.count,
                "first_t": t.first_t,
                "last_t": t.last_t,
                **({} if t.stamps is None else {"stamps": t.stamps}),
            }
            for name, t in topics.items()
        },
        "duration_s": (max(lasts) - min(firsts)) / 1e9 if topics else 0.0,
        "errors": errors,
        "truncated": reader.truncated,
        "truncation_reason": reader.truncation_reason,
        "finished": bool(status.get("finished", False)) if reader.format == "session" else None,
        "messages": sum(t.count for t in topics.values()),
        "session": meta.get(SESSION_METADATA, {}),
        "clock": {name: h.get("clock") for name, h in devices.items() if h.get("clock")},
        "format": reader.format,
        "roles": roles,
        **({} if problem is None else {"roles_problem": problem}),
    }
