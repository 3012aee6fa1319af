"""Intrinsics: synthetic boards with exact ground truth (virtual-rig lenses) and the real photos."""

from __future__ import annotations

import numpy as np
import pytest

from calib.boards import (
    BoardView,
    CharucoTarget,
    ChessboardTarget,
    detect_views,
    find_chessboard_size,
    read_gray,
)
from calib.intrinsics import calibrate_intrinsics
from rig.errors import InputError

from .synthetic import board_poses, render_charuco, render_chessboard, sim_camera

COLS, ROWS, SQUARE = 9, 6, 0.04


def _chessboard_images(model: str, n: int, seed: int = 0) -> tuple[list[tuple[str, np.ndarray]], object]:
    camera = sim_camera(model)
    rng = np.random.default_rng(seed)
    distance = 0.55 if model == "pinhole" else 0.35
    images = []
    for i, T in enumerate(board_poses(n, distance, rng, ((COLS - 1) * SQUARE / 2, (ROWS - 1) * SQUARE / 2))):
        gray = render_chessboard(camera, T, COLS, ROWS, SQUARE).astype(np.float64)
        images.append((f"view{i}", np.clip(gray + rng.normal(0, 2.0, gray.shape), 0, 255).astype(np.uint8)))
    return images, camera


@pytest.mark.parametrize("model", ["pinhole", "fisheye"])
def test_virtual_rig_focal_length_within_0p2_percent(model: str) -> None:
    images, camera = _chessboard_images(model, 10)
    views, target = detect_views(images, None, SQUARE)  # board size searched
    assert isinstance(target, ChessboardTarget) and {target.cols, target.rows} == {COLS, ROWS}
    assert len(views) >= 8
    result = calibrate_intrinsics(views, camera.width, camera.height, model)  # type: ignore[arg-type]
    assert abs(result.camera.fx / camera.fx - 1) < 0.002
    assert abs(result.camera.fy / camera.fy - 1) < 0.002
    assert np.hypot(result.camera.cx - camera.cx, result.camera.cy - camera.cy) < 1.0
    assert result.rms_px < 0.2
    assert result.quality()["intrinsics"]["rms_px"] == result.rms_px


def test_charuco_board() -> None:
    camera = sim_camera("pinhole")
    target = CharucoTarget(7, 5, 0.04, 0.03, "DICT_5X5_100")
    board = target.board()
    rng = np.random.default_rng(3)
    images = [
        (f"v{i}", render_charuco(camera, T, board))
        for i, T in enumerate(board_poses(8, 0.5, rng, (7 * 0.04 / 2, 5 * 0.04 / 2)))
    ]
    views, _ = detect_views(images, target)
    assert len(views) >= 6
    result = calibrate_intrinsics(views, camera.width, camera.height)
    assert abs(result.camera.fx / camera.fx - 1) < 0.003
    assert result.rms_px < 0.3


def test_outlier_view_is_rejected() -> None:
    images, camera = _chessboard_images("pinhole", 8, seed=1)
    views, _ = detect_views(images, ChessboardTarget(COLS, ROWS, SQUARE))
    broken = views[2]
    rng = np.random.default_rng(0)
    views[2] = BoardView(
        "broken",
        broken.image_points + rng.normal(0, 4.0, broken.image_points.shape).astype(np.float32),
        broken.object_points,
    )
    result = calibrate_intrinsics(views, camera.width, camera.height)
    assert result.views_rejected == ["broken"]
    assert "broken" not in result.views_used
    assert abs(result.camera.fx / camera.fx - 1) < 0.003


def test_single_board_pose_is_poorly_constrained() -> None:
    images, camera = _chessboard_images("pinhole", 1)
    views, _ = detect_views(images, ChessboardTarget(COLS, ROWS, SQUARE))
    result = calibrate_intrinsics(views, camera.width, camera.height)
    assert result.verdict == "poorly constrained"
    assert any("1 board view" in r for r in result.reasons)


def test_no_board_is_an_error() -> None:
    blank = np.full((240, 320), 128, np.uint8)
    with pytest.raises(InputError, match="no chessboard"):
        find_chessboard_size([blank])
    with pytest.raises(InputError, match="images: no image shows the board"):
        calibrate_intrinsics([], 320, 240)


def _real_views(real_data, names):
    images = [(n, read_gray(real_data / "chessboard_pjlab" / n)) for n in names]
    return detect_views(images, None, 0.05)


def test_real_chessboard_subset(real_data) -> None:
    views, target = _real_views(real_data, ["2.png", "8.png", "14.png", "20.png"])
    assert (target.cols, target.rows) == (17, 15)
    assert len(views) == 4
    result = calibrate_intrinsics(views, 1920, 1200)
    assert result.rms_px < 0.5
    assert result.verdict == "ok"


@pytest.mark.slow
@pytest.mark.parametrize("model", ["pinhole", "fisheye"])
def test_real_chessboard_all_photos(real_data, model: str) -> None:
    names = sorted(p.name for p in (real_data / "chessboard_pjlab").glob("*.png"))
    views, _ = _real_views(real_data, names)
    assert len(views) == 11
    result = calibrate_intrinsics(views, 1920, 1200, model)
    assert result.rms_px < 0.5
    assert result.coverage > 0.8
    assert 1000 < result.camera.fx < 1120 and abs(result.camera.fx / result.camera.fy - 1) < 0.01


def test_image_read_error_names_file(tmp_path) -> None:
    path = tmp_path / "nope.png"
    path.write_bytes(b"not a png")
    with pytest.raises(InputError, match=r"nope\.png"):
        read_gray(path)
