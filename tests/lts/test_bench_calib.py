"""The calibration benchmark: guesses, their sizes, one small run end to end, and its usage errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lts.bench.calibration import Guess, bench_calib, parse_guess, perturbed
from rig.errors import InputError
from rig.transforms import distance_and_angle

LTS = Path(sys.executable).parent / "lts"


def test_guesses_are_parsed():
    assert parse_guess("10/30") == Guess(10.0, 30.0)
    assert parse_guess(" 2.5 / 0 ") == Guess(2.5, 0.0)
    assert parse_guess("None") == Guess(None)
    assert parse_guess("10/30").label == "10°/30 cm"
    for bad in ("10", "10/", "x/30", "10/30/5", ""):
        with pytest.raises(InputError, match="DEG/CM"):
            parse_guess(bad)


def test_a_guess_is_exactly_its_size_from_the_truth():
    truth = np.eye(4)
    truth[:3, 3] = [0.02, -0.09, -0.03]
    rng = np.random.default_rng(3)
    for _ in range(5):
        distance, angle = distance_and_angle(perturbed(truth, Guess(10.0, 30.0), rng), truth)
        assert np.degrees(angle) == pytest.approx(10.0)
        assert distance == pytest.approx(0.30)


@pytest.mark.slow
def test_bench_scores_each_guess_against_the_truth(tmp_path):
    log: list[str] = []
    result = bench_calib(["room"], [0], [Guess(0.0, 0.0), Guess(None)], 4.0, tmp_path, log.append)
    rows = result["rows"]
    assert [r["guess"] for r in rows] == ["0°/0 cm", "none"]
    exact = rows[0]
    assert exact["init_rotation_error_deg"] == pytest.approx(0.0, abs=1e-6)
    assert exact["init_translation_error_m"] == pytest.approx(0.0, abs=1e-9)
    for row in rows:
        if row["verdict"] == "not run":
            assert not row["success"]
            continue
        assert row["success"] == (row["rotation_error_deg"] <= 0.5 and row["translation_error_m"] <= 0.05)
        assert row["false_ok"] == (row["verdict"] == "ok" and not row["success"])
        if row["covered"] is not None:  # the method's own 95 % interval, in its standard deviations
            reach = row["interval_95"]
            assert row["covered"] == (
                row["rotation_error_deg"] <= reach * row["rotation_std_deg"]
                and row["translation_error_m"] <= reach * row["translation_std_m"]
            )
    summary = result["summary"]["room"]
    assert summary["0°/0 cm"]["trials"] == 1
    assert json.loads((tmp_path / "bench_calib.json").read_text())["rows"] == json.loads(json.dumps(rows))
    assert (tmp_path / "bench_calib.png").stat().st_size > 1000
    assert any("room seed 0 guess none" in line for line in log)
    assert all(r["source"] == "room" for r in rows)
    # The session is simulated once: a second run reuses it.
    log.clear()
    bench_calib(["room"], [0], [Guess(0.0, 0.0)], 4.0, tmp_path, log.append)
    assert any("up to date" in line for line in log)


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (["--guess", "3x"], "--guess"),
        (["--sim", "rooom"], "preset"),
        (["--seeds", "0"], "--seeds"),
        (["--first-seed", "-1"], "--first-seed"),
        (["--kitti-frames", "nowhere"], "nowhere"),
        (["--nuscenes-sample", "nowhere"], "nowhere"),
    ],
)
def test_usage_errors_are_one_line(tmp_path, args, field):
    result = subprocess.run(
        [LTS, "bench", "calib", "--out", str(tmp_path), *args], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert field in result.stderr
    assert not any(tmp_path.iterdir())


def test_kitti_frames_folder_without_frames_is_refused(tmp_path):
    from calib.kitti_frames import kitti_frame_names

    with pytest.raises(InputError, match="no KITTI frames"):
        kitti_frame_names(tmp_path)


@pytest.mark.slow
def test_bench_runs_each_kitti_frame_alone(real_data, tmp_path):
    folder = real_data / "kitti_frames"
    result = bench_calib([], [], [Guess(2.0, 10.0), Guess(None)], 10.0, tmp_path, lambda _: None, folder)
    rows = result["rows"]
    assert [(r["frame"], r["guess"]) for r in rows] == [
        (f"{i:06d}", g) for i in range(3) for g in ("2°/10 cm", "none")
    ]
    for row in rows:
        if row["guess"] == "none":
            assert row["verdict"] == "not run"  # one frame: no motion to start from
        else:
            assert row["init_rotation_error_deg"] == pytest.approx(2.0)
            assert row["init_translation_error_m"] == pytest.approx(0.10)
            assert row["false_ok"] is False
    assert result["sources"] == ["kitti"]


@pytest.mark.slow
def test_bench_runs_each_nuscenes_camera_alone(real_data, tmp_path):
    folder = real_data / "nuscenes_sample"
    result = bench_calib([], [], [Guess(0.0, 0.0)], 10.0, tmp_path, lambda _: None, nuscenes_sample=folder)
    rows = result["rows"]
    assert [r["frame"] for r in rows] == [
        "CAM_FRONT",
        "CAM_FRONT_RIGHT",
        "CAM_FRONT_LEFT",
        "CAM_BACK",
        "CAM_BACK_LEFT",
        "CAM_BACK_RIGHT",
    ]
    assert result["sources"] == ["nuscenes"]
    assert all(r["false_ok"] is False and r["init_rotation_error_deg"] < 1e-6 for r in rows)


@pytest.mark.slow
def test_bench_runs_each_pjlab_pair_alone(real_data, tmp_path):
    folder = real_data / "lidar_camera_pjlab"
    result = bench_calib([], [], [Guess(2.0, 10.0)], 10.0, tmp_path, lambda _: None, pjlab_pairs=folder)
    assert [r["frame"] for r in result["rows"]] == ["auto", "manual"]
    assert result["sources"] == ["pjlab"]
    for row in result["rows"]:
        assert row["init_rotation_error_deg"] == pytest.approx(2.0)
        # Measured 0.14 and 0.43°; the translation stays at the guess, poorly constrained.
        assert row["rotation_error_deg"] < 0.6
        assert row["false_ok"] is False
