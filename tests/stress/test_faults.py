"""Faults while recording: SIGKILL (the file is read up to its last complete record and
`rig recover` makes it valid) and a full disk (a 2 MB tmpfs: recording stops with a valid file)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from rig.messages import Frame
from rig.session import SessionReader, SessionRecorder, recover, session_info

BIN = Path(sys.executable).parent
IMAGE_TOPIC = "/camera/image/compressed"


def rig(*args: object, timeout: float = 60) -> subprocess.CompletedProcess:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "COLUMNS": "400"}
    return subprocess.run(
        [BIN / "rig", *map(str, args)], capture_output=True, text=True, timeout=timeout, env=env
    )


@pytest.fixture(scope="module")
def sim_scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3 s synthetic scene for `rig record --sim` (as in tests/session)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from tests.session.conftest import write_scene

    return write_scene(tmp_path_factory.mktemp("scene"), seconds=3.0)


def _record_and_kill(scene: Path, out: Path, min_bytes: int) -> None:
    proc = subprocess.Popen(
        [BIN / "rig", "record", "--sim", scene, "--out", out, "--duration", "60"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and (not out.exists() or out.stat().st_size < min_bytes):
            time.sleep(0.02)
        assert out.exists(), "the recorder never created its file"
    finally:
        proc.kill()
        proc.wait(10)


@pytest.mark.parametrize("min_bytes", [1, 400_000], ids=["at-once", "after-chunks"])
def test_sigkill_during_record_then_info_and_recover_from_the_cli(
    sim_scene: Path, tmp_path: Path, min_bytes: int
) -> None:
    killed = tmp_path / "killed.mcap"
    _record_and_kill(sim_scene, killed, min_bytes)
    result = rig("info", killed, "--json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    assert info["truncated"] and not info["finished"]
    if min_bytes > 1:
        assert info["topics"][IMAGE_TOPIC]["count"] > 5
    assert sum(1 for _ in SessionReader(killed).messages()) == info["messages"]

    fixed = tmp_path / "fixed.mcap"
    result = rig("recover", killed, "--out", fixed, "--json")
    assert result.returncode == 0, result.stderr
    salvage = json.loads(result.stdout)
    assert salvage["truncated"] and salvage["messages"] == info["messages"]
    repaired = session_info(fixed)
    assert not repaired["truncated"] and repaired["messages"] == info["messages"]
    frames = list(SessionReader(fixed).frames(IMAGE_TOPIC)) if info["topics"].get(IMAGE_TOPIC) else []
    assert len(frames) == info["topics"].get(IMAGE_TOPIC, {"count": 0})["count"]


@pytest.fixture
def tiny_disk(tmp_path: Path) -> Iterator[Path]:
    """A 2 MB tmpfs (needs root / CAP_SYS_ADMIN; skipped otherwise)."""
    mount = tmp_path / "tiny"
    mount.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mount)], capture_output=True, text=True
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a 2 MB tmpfs here ({done.stderr.strip() or done.returncode}): not root?")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)


def test_nearly_full_disk_stops_rig_record_with_a_valid_file(sim_scene: Path, tiny_disk: Path) -> None:
    out = tiny_disk / "s.mcap"
    result = rig("record", "--sim", sim_scene, "--out", out, "--duration", "5", "--json")
    assert result.returncode == 1, result.stderr
    assert "disk almost full" in result.stderr and "Traceback" not in result.stderr
    info = session_info(out)
    assert not info["truncated"] and info["finished"]
    assert "disk almost full" in info["errors"]["write_error"]


def test_disk_full_mid_recording_leaves_a_file_read_to_its_last_record(
    tiny_disk: Path, tmp_path: Path
) -> None:
    """No free-space reserve: the writes themselves fail (ENOSPC)."""
    out = tiny_disk / "s.mcap"
    recorder = SessionRecorder(out, image_format="png", chunk_size=64 << 10, min_free_bytes=0)
    rng = np.random.default_rng(0)
    t = 10**9
    deadline = time.monotonic() + 30
    while recorder.recording and time.monotonic() < deadline:
        t += 10**7
        frame = Frame(rng.integers(0, 255, (64, 64, 3), dtype=np.uint8), t, t, "cam")
        if not recorder.put(frame, IMAGE_TOPIC, "camera"):
            time.sleep(0.005)
    recorder.close()
    assert not recorder.recording and "No space left" in (recorder.error or ""), recorder.error
    info = session_info(out)
    assert info["messages"] > 20
    fixed = tmp_path / "fixed.mcap"
    salvage = recover(out, fixed)
    assert salvage["messages"] == info["messages"]
    assert not session_info(fixed)["truncated"]
    assert len(list(SessionReader(fixed).frames(IMAGE_TOPIC))) == info["messages"]
