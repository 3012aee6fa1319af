"""Keep native libraries' console output off stdout, which ``--json`` reserves for one object."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO


@contextmanager
def native_output_to_stderr() -> Iterator[TextIO]:
    """Point file descriptor 1 at stderr while the block runs, and yield a stream on the real stdout.

    Native libraries (depthai, pybullet, OpenBLAS under pycolmap, open3d) write straight to
    descriptor 1, below Python's ``sys.stdout``; with ``--json`` that would corrupt the one JSON
    object scripts parse. When ``sys.stdout`` is not descriptor 1 (a test's capture, Click's
    runner) it is what the block gets: the redirection does not touch it.
    """
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        if _writes_to_descriptor_1(sys.stdout):
            with os.fdopen(os.dup(saved), "w") as real_stdout:
                yield real_stdout
        else:
            yield sys.stdout
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def _writes_to_descriptor_1(stream: TextIO) -> bool:
    try:
        return stream.fileno() == 1
    except (AttributeError, OSError, ValueError):  # io.UnsupportedOperation is both of the last two
        return False
