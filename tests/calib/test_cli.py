"""``lts calibrate``: the contract's JSON fields, calib.yaml output, one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rig.calibration import Calibration, load_calibration, save_calibration

from .test_targetless import load_pjlab, perturb

LTS = Path(sys.executable).parent / "lts"


def _lts(*args: str, timeout: int = 300) -> subprocess.CompletedProcess:
    return subprocess.run([LTS, *map(str, args)], capture_output=True, text=True, timeout=timeout)


def test_intrinsics_json_and_calib_yaml(real_data, tmp_path) -> None:
    images = [real_data / "chessboard_pjlab" / n for n in ("2.png", "10.png", "16.png")]
    out = tmp_path / "cam.yaml"
    result = _lts("calibrate", "intrinsics", *images, "--out", out, "--square", "0.05", "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert {"rms_px", "K", "dist", "views_used"} <= set(summary)
    assert summary["rms_px"] < 0.5 and len(summary["views_used"]) == 3
    calibration = load_calibration(out)
    np.testing.assert_allclose(calibration.camera.K, summary["K"])
    assert calibration.quality["intrinsics"]["rms_px"] == pytest.approx(summary["rms_px"])
    assert not calibration.has_extrinsic  # the camera alone: no identity to mistake for a guess
    (tmp_path / "scan.bin").write_bytes(np.zeros((10, 4), np.float32).tobytes())
    result = _lts(
        "calibrate", "extrinsic", "--image", images[0], "--points", tmp_path / "scan.bin",
        "--init", out, "--out", tmp_path / "extrinsic.yaml",
    )  # fmt: skip
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert f"{out}: T_cam_lidar: missing" in result.stderr


def test_bad_input_is_one_line_error(tmp_path) -> None:
    result = _lts("calibrate", "intrinsics", tmp_path / "missing.png", "--out", tmp_path / "c.yaml")
    assert result.returncode == 2
    assert "missing.png" in result.stderr and "Traceback" not in result.stderr
    init = tmp_path / "init.yaml"
    save_calibration(Calibration(_camera()), init)
    (tmp_path / "scan.bin").write_bytes(b"\x00" * 10)
    (tmp_path / "img.png").write_bytes(b"")
    result = _lts(
        "calibrate",
        "extrinsic",
        "--image",
        tmp_path / "img.png",
        "--points",
        tmp_path / "scan.bin",
        "--init",
        init,
        "--out",
        tmp_path / "out.yaml",
    )
    assert result.returncode == 2 and "img.png" in result.stderr and "Traceback" not in result.stderr


def test_a_forgotten_recording_is_named(tmp_path) -> None:
    """``lts calibrate --out calib.yaml``: the error names the missing recording, not the option."""
    result = _lts("calibrate", "--out", tmp_path / "c.yaml")
    assert result.returncode == 2 and "RECORDING" in result.stderr and "No such option" not in result.stderr
    assert "Commands" in _lts("calibrate", "--help").stdout


def test_a_mistyped_subcommand_is_named(tmp_path) -> None:
    """``lts calibrate tme REC``: a word close to a subcommand that names no file is a typo, not
    a recording; a file of that name is still a recording."""
    result = _lts("calibrate", "tme", tmp_path / "rec.mcap", "--out", tmp_path / "c.yaml")
    assert result.returncode == 2 and "Did you mean 'time'?" in result.stderr
    assert "Traceback" not in result.stderr
    (tmp_path / "tme").write_bytes(b"not a recording")
    command = [LTS, "calibrate", "tme", "--out", "c.yaml"]
    result = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert result.returncode == 2 and "not a recording" in result.stderr
    result = _lts("calibrate", tmp_path / "session.mcap", "--out", tmp_path / "c.yaml")  # a path: no typo
    assert result.returncode == 2 and "no such session file" in result.stderr


def _camera():
    from rig.camera import CameraModel

    return CameraModel("pinhole", 64, 48, np.array([[50.0, 0, 32], [0, 50, 24], [0, 0, 1]]), np.zeros(0))


@pytest.mark.slow
def test_extrinsic_on_real_pair_keeps_the_guess_unless_ok(real_data, tmp_path) -> None:
    _, camera, T_ref = load_pjlab(real_data, "manual")
    init = tmp_path / "init.yaml"
    save_calibration(Calibration(camera, perturb(T_ref, np.random.default_rng(5)), 0.0), init)
    folder = real_data / "lidar_camera_pjlab" / "manual"
    out, overlay = tmp_path / "calib.yaml", tmp_path / "overlay.png"
    args = (
        "calibrate",
        "extrinsic",
        "--image",
        folder / "0.png",
        "--points",
        folder / "0.pcd",
        "--init",
        init,
        "--out",
        out,
        "--overlay",
        overlay,
        "--json",
    )
    result = _lts(*args)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    # One frame of far structure: the translation is not observable (test_targetless).
    assert summary["verdict"] == "poorly constrained" and summary["applied"] is False
    written = load_calibration(out)
    np.testing.assert_allclose(written.T_cam_lidar, load_calibration(init).T_cam_lidar)
    assert written.quality["extrinsic"]["applied"] is False
    assert overlay.stat().st_size > 10_000

    forced = _lts(*args, "--force")
    assert forced.returncode == 0, forced.stderr
    assert json.loads(forced.stdout)["applied"] is True
    np.testing.assert_allclose(load_calibration(out).T_cam_lidar, summary["T_cam_lidar"])
