"""How many threads work that gives the same result on any number of them may use."""

from __future__ import annotations

import os


def cpu_threads() -> int:
    """``OMP_NUM_THREADS`` where it is a positive number (as OpenMP itself reads it; a process
    started beside another is given 1), else every core."""
    value = os.environ.get("OMP_NUM_THREADS", "")
    return int(value) if value.isdigit() and int(value) > 0 else (os.cpu_count() or 1)
