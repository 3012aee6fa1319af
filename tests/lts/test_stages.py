"""A reconstruction stage's fingerprint: what makes ``lts reconstruct`` redo a finished stage."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from lts import stages


@pytest.fixture()
def inputs(tmp_path: Path) -> list[Path]:
    folder = tmp_path / "session"
    folder.mkdir()
    (folder / "a.bin").write_bytes(b"1234")
    return [folder]


def test_same_stage_same_fingerprint(inputs: list[Path]) -> None:
    command = ["lts", "train"]
    assert stages.fingerprint(command, inputs) == stages.fingerprint(command, inputs)


def test_options_inputs_and_version_change_it(inputs: list[Path], monkeypatch) -> None:
    base = stages.fingerprint(["lts", "train"], inputs)
    assert stages.fingerprint(["lts", "train", "--preset", "fast"], inputs) != base
    file = inputs[0] / "a.bin"
    file.write_bytes(b"12345")
    changed = stages.fingerprint(["lts", "train"], inputs)
    assert changed != base
    os.utime(file, ns=(file.stat().st_atime_ns, file.stat().st_mtime_ns + 1))
    touched = stages.fingerprint(["lts", "train"], inputs)
    assert touched != changed
    monkeypatch.setattr(stages, "package_version", lambda: "999.0")
    assert stages.fingerprint(["lts", "train"], inputs) != touched


def _runner(folder: Path, log: list[str]) -> stages.StageRunner:
    return stages.StageRunner(folder, ("a", "b"), log.append)


def _write(path: Path, text: str) -> None:
    path.write_text(text)


def test_a_finished_stage_is_skipped_until_its_inputs_change(tmp_path: Path, inputs: list[Path]) -> None:
    out, log = tmp_path / "a.txt", []
    assert not _runner(tmp_path, log).up_to_date("a", ["make", "a"], inputs, out)
    ran = _runner(tmp_path, log).run("a", ["make", "a"], inputs, out, lambda: _write(out, "a"))
    assert ran.status == "ran"
    assert _runner(tmp_path, log).up_to_date("a", ["make", "a"], inputs, out)
    again = _runner(tmp_path, log).run("a", ["make", "a"], inputs, out, lambda: pytest.fail("redone"))
    assert again.status == "skipped" and "[a] up to date, skipped" in log
    (inputs[0] / "a.bin").write_bytes(b"changed")
    assert not _runner(tmp_path, log).up_to_date("a", ["make", "a"], inputs, out)
    redone = _runner(tmp_path, log).run("a", ["make", "a"], inputs, out, lambda: _write(out, "a2"))
    assert redone.status == "ran" and out.read_text() == "a2"


def test_a_stage_whose_output_vanished_runs_again(tmp_path: Path, inputs: list[Path]) -> None:
    out, log = tmp_path / "a.txt", []
    _runner(tmp_path, log).run("a", ["make"], inputs, out, lambda: _write(out, "a"))
    out.unlink()
    assert _runner(tmp_path, log).run("a", ["make"], inputs, out, lambda: _write(out, "a")).status == "ran"


def test_running_a_stage_forgets_the_stages_after_it(tmp_path: Path, inputs: list[Path]) -> None:
    a, b, log = tmp_path / "a.txt", tmp_path / "b.txt", []
    runner = _runner(tmp_path, log)
    runner.run("a", ["make a"], inputs, a, lambda: _write(a, "a"))
    runner.run("b", ["make b"], [a], b, lambda: _write(b, "b"))
    _runner(tmp_path, log).run("a", ["make a", "--other"], inputs, a, lambda: _write(a, "a"))
    manifest = json.loads((tmp_path / stages.MANIFEST).read_text())
    assert set(manifest) == {"a"}


def test_a_failed_stage_is_not_recorded_and_says_where_a_rerun_starts(
    tmp_path: Path, inputs: list[Path]
) -> None:
    out, log = tmp_path / "a.txt", []

    def fail() -> None:
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError, match="boom"):
        _runner(tmp_path, log).run("a", ["make"], inputs, out, fail)
    assert "a" not in json.loads((tmp_path / stages.MANIFEST).read_text())
    assert any("a rerun of the same command continues from this stage" in line for line in log)


def test_the_training_resolution_is_part_of_the_prepare_stages_fingerprint(tmp_path: Path) -> None:
    from lts.pipeline import ReconstructOptions, prepare_config, prepare_key
    from slam_bridge.prepare_config import DEFAULT_MAX_SIZE

    def key(**resolution) -> list[str]:
        config = prepare_config(ReconstructOptions(tmp_path / "s.mcap", tmp_path / "run", **resolution))
        assert (config.max_size, config.downscale) == (
            resolution.get("max_size", DEFAULT_MAX_SIZE),
            resolution.get("downscale", 1),
        )
        return prepare_key(config)

    assert len({tuple(key()), tuple(key(max_size=0)), tuple(key(downscale=2))}) == 3


def test_a_recordings_paths_topic_map_and_span_key_its_stages(tmp_path: Path) -> None:
    from lts.pipeline import ReconstructOptions
    from rig.session import TimeSpan

    parts = [tmp_path / "run_0.bag", tmp_path / "run_1.bag"]
    options = ReconstructOptions(parts, tmp_path / "out", topics="ut-mm", span=TimeSpan(5.0, 10.0))
    assert options.recording_key() == [
        *map(str, parts),
        "--topics",
        "ut-mm",
        "--start",
        "5",
        "--duration",
        "10",
    ]
    # A session with the defaults keys its stages as before (finished runs stay finished).
    assert ReconstructOptions(tmp_path / "s.mcap", tmp_path / "out").recording_key() == [
        str(tmp_path / "s.mcap")
    ]


def test_a_bad_training_option_stops_lts_reconstruct_before_any_stage(tmp_path: Path) -> None:
    from lts.pipeline import ReconstructOptions, reconstruct
    from rig.errors import InputError

    options = ReconstructOptions(tmp_path / "missing.mcap", tmp_path / "run", exposure="sometimes")
    with pytest.raises(InputError, match="exposure"):  # before the recording is even opened
        reconstruct(options, log=lambda *_: None)
    assert not (tmp_path / "run").exists()


def test_colour_maps_key_the_training_stage_only_when_not_automatic(tmp_path: Path) -> None:
    from lts.pipeline import ReconstructOptions, train_key

    session = tmp_path / "s.mcap"
    assert "--exposure" not in train_key(ReconstructOptions(session, tmp_path))  # earlier runs stay done
    assert train_key(ReconstructOptions(session, tmp_path, exposure="off"))[-2:] == ["--exposure", "off"]


def test_learnt_poses_key_the_training_stage_and_are_refused_with_blocks_before_any_stage(
    tmp_path: Path,
) -> None:
    from lts.pipeline import ReconstructOptions, reconstruct, train_config, train_key
    from rig.errors import InputError

    session = tmp_path / "s.mcap"
    assert "--learn-poses" not in train_key(ReconstructOptions(session, tmp_path))  # earlier runs stay done
    learning = ReconstructOptions(session, tmp_path, learn_poses=True)
    assert "--learn-poses" in train_key(learning) and train_config(learning).learn_poses
    options = ReconstructOptions(session, tmp_path / "run", learn_poses=True, blocks="2")
    with pytest.raises(InputError, match="not with --blocks"):  # before the recording is even opened
        reconstruct(options, log=lambda *_: None)
    assert not (tmp_path / "run").exists()
