"""A reconstruction stage's fingerprint: what makes ``lts reconstruct`` redo a finished stage."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from eval import reconstruct


@pytest.fixture()
def inputs(tmp_path: Path) -> list[Path]:
    folder = tmp_path / "session"
    folder.mkdir()
    (folder / "a.bin").write_bytes(b"1234")
    return [folder]


def test_same_stage_same_fingerprint(inputs: list[Path]) -> None:
    command = ["lts", "train"]
    assert reconstruct.fingerprint(command, inputs) == reconstruct.fingerprint(command, inputs)


def test_options_inputs_and_version_change_it(inputs: list[Path], monkeypatch) -> None:
    base = reconstruct.fingerprint(["lts", "train"], inputs)
    assert reconstruct.fingerprint(["lts", "train", "--preset", "fast"], inputs) != base
    file = inputs[0] / "a.bin"
    file.write_bytes(b"12345")
    changed = reconstruct.fingerprint(["lts", "train"], inputs)
    assert changed != base
    os.utime(file, ns=(file.stat().st_atime_ns, file.stat().st_mtime_ns + 1))
    touched = reconstruct.fingerprint(["lts", "train"], inputs)
    assert touched != changed
    monkeypatch.setattr(reconstruct, "package_version", lambda: "999.0")
    assert reconstruct.fingerprint(["lts", "train"], inputs) != touched
