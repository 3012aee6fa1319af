"""The fallback mapper in a process of its own, beside the calibration.

The two stages read the same recording and neither needs the other's output, and the calibration
is mostly one thread of NumPy (its photo-consistency search): the mapper, on one thread, takes the
other core. On one recording of the demo's 20 s room, on two cores, calibrating then mapping took
47.1 / 47.5 / 52.2 s, side by side 44.4 / 42.6 / 40.8 s (alternated), with the same calibration and
the same map to the byte. A process, not a thread: both hold the GIL between their array
operations.

The child is ``python -m lts.mapper_beside``, handed the open recording and the SLAM folder
pickled on its stdin; it writes its summary (or its exception) pickled to a file named on its
command line. Not :mod:`multiprocessing`: its spawned children import the parent's main script
again, which runs a user's unguarded script a second time, and a forked child would inherit the
locks of the OpenMP and BLAS threads the parent may hold (the demo simulated in this process).
"""

from __future__ import annotations

import os
import pickle
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rig.session import Recording
    from slam_bridge.map_session import MapSummary


class MapperBeside:
    """Starts the fallback mapper on ``recording`` into the SLAM folder ``out`` in a child process;
    :meth:`join` waits for it. Leaving the ``with`` block before it has finished (an error,
    Ctrl-C) ends the child."""

    def __init__(self, recording: Recording, out: Path) -> None:
        self._folder = tempfile.TemporaryDirectory(prefix="lts-mapper-")
        self._result = Path(self._folder.name) / "result.pickle"
        command = [sys.executable, "-m", "lts.mapper_beside", str(self._result)]
        threads = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")}
        self._child = subprocess.Popen(command, stdin=subprocess.PIPE, env={**os.environ, **threads})
        assert self._child.stdin is not None
        with self._child.stdin as stdin:
            pickle.dump((recording, Path(out)), stdin)

    def join(self) -> tuple[MapSummary, float]:
        """The mapper's summary and its seconds, once it has finished; its exception (an
        :class:`~rig.errors.InputError` keeps its message) is raised here."""
        status = self._child.wait()
        if not self._result.is_file():
            raise RuntimeError(f"the fallback mapper's process ended with status {status} and no result")
        result = pickle.loads(self._result.read_bytes())
        if isinstance(result, BaseException):
            raise result
        return result

    def __enter__(self) -> MapperBeside:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        if self._child.poll() is None:
            self._child.terminate()
            self._child.wait()
        self._folder.cleanup()


def _map(recording: Recording, out: Path) -> tuple[MapSummary, float]:
    """The child's work: :func:`~slam_bridge.map_session.map_session` and its seconds."""
    from slam_bridge.map_session import map_session

    started = time.perf_counter()
    summary = map_session(recording, out)
    return summary, time.perf_counter() - started


def _child_main(result_path: Path) -> None:
    # Ctrl-C reaches the whole process group: the parent stops this child (no second traceback).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    recording, out = pickle.load(sys.stdin.buffer)
    try:
        result: object = _map(recording, out)
    except Exception as error:  # handed to the parent, which raises it
        result = error
    try:
        payload = pickle.dumps(result)
    except Exception:  # an exception that does not pickle: its message does
        payload = pickle.dumps(RuntimeError(f"{type(result).__name__}: {result}"))
    result_path.write_bytes(payload)


if __name__ == "__main__":
    _child_main(Path(sys.argv[1]))
