"""The fallback mapper in a process of its own (``lts reconstruct`` runs it beside the calibration)."""

from __future__ import annotations

from pathlib import Path

import pytest

from lts.mapper_beside import MapperBeside
from rig.errors import InputError
from rig.session import open_recording
from slam_bridge.map_session import map_session


@pytest.fixture(scope="module")
def quick_session(quick_room: Path) -> Path:
    return quick_room / "session.mcap"


def test_the_mapper_beside_writes_what_the_mapper_writes_here(quick_session: Path, tmp_path: Path) -> None:
    recording = open_recording(quick_session)
    here = map_session(recording, tmp_path / "here")
    with MapperBeside(recording, tmp_path / "beside") as mapper:
        summary, seconds = mapper.join()
    assert seconds > 0
    assert summary.describe()[1:] == here.describe()[1:]  # the first line names the folder
    for name in ("mesh.ply", "trajectory.tum"):
        assert (tmp_path / "beside" / name).read_bytes() == (tmp_path / "here" / name).read_bytes(), name


def test_the_mappers_input_error_reaches_the_caller(quick_session: Path, tmp_path: Path) -> None:
    recording = open_recording(quick_session, topic_map={"points": "/nope"})
    with MapperBeside(recording, tmp_path / "slam") as mapper, pytest.raises(InputError, match="'/nope'"):
        mapper.join()


def test_leaving_before_the_mapper_ends_stops_its_process(quick_session: Path, tmp_path: Path) -> None:
    with pytest.raises(KeyboardInterrupt), MapperBeside(open_recording(quick_session), tmp_path) as mapper:
        raise KeyboardInterrupt
    assert mapper._child.returncode is not None
    assert not (tmp_path / "mesh.ply").exists()
