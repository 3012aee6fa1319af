"""YAML and JSON files read with one-line errors that name the file and the line (rig.data_file)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.data_file import load_data_file
from rig.errors import InputError


def test_yaml_and_json_are_parsed(tmp_path: Path) -> None:
    (tmp_path / "a.yaml").write_text("a: [1, 2]\n")
    (tmp_path / "a.json").write_text('{"a": [1, 2]}')
    assert load_data_file(tmp_path / "a.yaml", "YAML", "thing") == {"a": [1, 2]}
    assert load_data_file(tmp_path / "a.json", "JSON", "thing") == {"a": [1, 2]}


@pytest.mark.parametrize(
    ("content", "fmt", "message"),
    [
        (b"a: 1\nb: [1, 2\n", "YAML", ":3: not valid YAML ("),
        (b'{"a": 1,\n "b": }', "JSON", ":2: not valid JSON (Expecting value)"),
        (b"\xff\xfe\x00 binary", "YAML", ": not a text file (expected YAML)"),
    ],
)
def test_bad_files_give_one_line_errors_with_the_line(
    tmp_path: Path, content: bytes, fmt: str, message: str
) -> None:
    path = tmp_path / "bad"
    path.write_bytes(content)
    with pytest.raises(InputError) as err:
        load_data_file(path, fmt, "thing")
    assert str(err.value).startswith(str(path)) and message in str(err.value), str(err.value)
    assert "\n" not in str(err.value)


def test_an_unreadable_file_says_what_it_is(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"cannot read calibration \(Is a directory\)"):
        load_data_file(tmp_path, "YAML", "calibration")
