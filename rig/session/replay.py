"""``rig replay``: re-emit a session's messages to a consumer with their original timing."""

from __future__ import annotations

import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from rig.session.reader import SessionMessage, SessionReader


def replay(
    path: str | Path,
    consumer: Callable[[SessionMessage], None],
    *,
    rate: float = 1.0,
    topics: Iterable[str] | None = None,
    stop: threading.Event | None = None,
) -> dict[str, Any]:
    """Call ``consumer`` with each message, spaced as their ``t_host`` were, ``rate`` times faster.

    ``rate <= 0`` replays as fast as possible. Returns ``{"messages", "topics", "span_s", "wall_s",
    "max_lateness_s"}``: how far behind schedule the slowest message was delivered.
    """
    reader = SessionReader(path)
    counts: Counter[str] = Counter()
    t0_log: int | None = None
    last_log = 0
    start = time.monotonic()
    worst = 0.0
    for m in reader.messages(topics):
        if stop is not None and stop.is_set():
            break
        if t0_log is None:
            t0_log = m.t_host
        last_log = m.t_host
        if rate > 0:
            due = start + (m.t_host - t0_log) / 1e9 / rate
            wait = due - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            worst = max(worst, time.monotonic() - due)
        consumer(m)
        counts[m.topic] += 1
    return {
        "messages": sum(counts.values()),
        "topics": dict(counts),
        "span_s": 0.0 if t0_log is None else (last_log - t0_log) / 1e9,
        "wall_s": time.monotonic() - start,
        "max_lateness_s": worst,
        "truncated": reader.truncated,
    }
