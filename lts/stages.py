"""One stage runner for every job of the app layer (``lts reconstruct``, ``lts demo``, the bench
scene): a stage runs unless ``stages.json`` records it finished with the same *fingerprint* and its
output is still there.

The fingerprint is a digest of the stage's key (its name and every option that shapes its output),
the toolkit's version and the size and modification time of every input file. Changing a training
option therefore retrains without redoing calibration, mapping or keyframes; a changed input or an
upgraded toolkit redoes the stages that read it. When a stage runs, the records of the stages after
it are forgotten, so a rerun never trusts outputs made from an older input.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from rig.atomic_file import write_atomic
from rig.version import package_version

MANIFEST = "stages.json"


@dataclass(frozen=True)
class StageRecord:
    """One stage's outcome: ``ran`` (with its seconds) or ``skipped`` (up to date)."""

    name: str
    status: str
    seconds: float


def _files_of(path: Path) -> list[Path]:
    if path.is_file():
        return [path]
    return sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else []


def fingerprint(key: Sequence[str], inputs: Sequence[Path]) -> str:
    """A digest of a stage's ``key``, the toolkit's version (an upgrade redoes the stages) and the
    size and mtime of every file under ``inputs``."""
    digest = hashlib.sha256(json.dumps([package_version(), *key]).encode())
    for path in inputs:
        for f in _files_of(path):
            stat = f.stat()
            digest.update(f"{f}:{stat.st_size}:{stat.st_mtime_ns}".encode())
    return digest.hexdigest()


class StageRunner:
    """Runs the stages of one job folder in ``order``, skipping those that are up to date.

    Args:
        folder: the job's folder; ``folder/stages.json`` holds the fingerprints of finished stages.
        order: every stage name of the job, first to last.
        log: where ``[stage] ...`` lines go.
    """

    def __init__(self, folder: Path, order: Sequence[str], log: Callable[[str], None]) -> None:
        self.folder = folder
        self.order = tuple(order)
        self.log = log
        self.records: list[StageRecord] = []
        path = folder / MANIFEST
        self._finished: dict[str, str] = json.loads(path.read_text()) if path.is_file() else {}

    def run(
        self,
        name: str,
        key: Sequence[str],
        inputs: Sequence[Path],
        output: Path,
        work: Callable[[], object],
    ) -> StageRecord:
        """Call ``work`` unless stage ``name`` is up to date; record it as finished when ``work``
        returns. An exception from ``work`` leaves the stage unrecorded (a rerun starts here) and
        propagates."""
        if self.up_to_date(name, key, inputs, output):
            self.log(f"[{name}] up to date, skipped")
            return self._add(StageRecord(name, "skipped", 0.0))
        digest = fingerprint(key, inputs)
        for later in self.order[self.order.index(name) :]:
            self._finished.pop(later, None)
        self._save()
        self.log(f"[{name}] {' '.join(key)}")
        started = time.perf_counter()
        try:
            work()
        except BaseException:
            self.log(
                f"[{name}] stopped: the stages before it are kept in {self.folder}, and a rerun of the "
                "same command continues from this stage"
            )
            raise
        self._finished[name] = digest
        self._save()
        return self._add(StageRecord(name, "ran", round(time.perf_counter() - started, 2)))

    def up_to_date(self, name: str, key: Sequence[str], inputs: Sequence[Path], output: Path) -> bool:
        """Whether :meth:`run` with these arguments would skip stage ``name`` now (a stage before it
        that runs still makes it run)."""
        return self._finished.get(name) == fingerprint(key, inputs) and output.exists()

    def _add(self, record: StageRecord) -> StageRecord:
        self.records.append(record)
        return record

    def _save(self) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        write_atomic(self.folder / MANIFEST, json.dumps(self._finished, indent=1))
