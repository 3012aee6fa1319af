"""Guards against a check that hangs or crashes: a time limit that turns a hang into a
:class:`TimeoutError`, and a one-line description of an exception for a failure count."""

from __future__ import annotations

import signal
import threading
import traceback
from pathlib import Path
from typing import Any


def crash_description(exc: BaseException) -> str:
    """``"TypeName: message (file.py:line)"``: the exception, its message cut to 120 characters,
    and the innermost frame that raised it."""
    where = traceback.extract_tb(exc.__traceback__)[-1]
    return f"{type(exc).__name__}: {str(exc)[:120]} ({Path(where.filename).name}:{where.lineno})"


class time_limit:  # noqa: N801 (a context manager used like a function)
    """Raise :class:`TimeoutError` if the block runs longer than ``seconds`` (SIGALRM; main
    thread on POSIX only, elsewhere a no-op)."""

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        self._old: Any = None

    def __enter__(self) -> time_limit:
        if hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread():

            def expire(signum: int, frame: Any) -> None:
                raise TimeoutError(f"took longer than {self.seconds:g} s (a hang?)")

            self._old = signal.signal(signal.SIGALRM, expire)
            signal.setitimer(signal.ITIMER_REAL, self.seconds)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._old is not None:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, self._old)
