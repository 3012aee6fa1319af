"""Board-plane extrinsic: virtual-rig ground truth, degenerate pose sets."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib.boards import BoardView, ChessboardTarget, detect_chessboard
from calib.intervals import NORMAL_95, jackknife_interval_95
from calib.target_based import JACKKNIFE_GROUPS, BoardObservation, board_pose, calibrate_with_board
from rig.errors import InputError
from rig.pointcloud_io import PointCloud
from rig.transforms import distance_and_angle, invert, make_transform

from .synthetic import board_poses, board_scan, render_chessboard, sim_camera

COLS, ROWS, SQUARE = 9, 6, 0.1
#: Half the board's outline (one square of margin around the corners), about the corners' centre.
HALF = ((COLS + 1) * SQUARE / 2, (ROWS + 1) * SQUARE / 2)
#: The virtual rig's room-preset style extrinsic (LiDAR x forward, camera z forward).
T_CAM_LIDAR = make_transform(
    Rotation.from_euler("xyz", [-91, 1, -88], degrees=True).as_matrix(), [0.02, -0.09, -0.03]
)


def _observations(n: int, seed: int) -> list[BoardObservation]:
    camera = sim_camera("pinhole")
    rng = np.random.default_rng(seed)
    corners_centre = ((COLS - 1) * SQUARE / 2, (ROWS - 1) * SQUARE / 2)
    outline = (-SQUARE, COLS * SQUARE, -SQUARE, ROWS * SQUARE)  # board frame with the first corner at 0
    target = ChessboardTarget(COLS, ROWS, SQUARE)
    observations = []
    for i, T_cam_board in enumerate(board_poses(n, 2.0, rng, corners_centre, max_tilt_deg=55)):
        corners = detect_chessboard(render_chessboard(camera, T_cam_board, COLS, ROWS, SQUARE), COLS, ROWS)
        if corners is None:
            continue
        estimated = board_pose(BoardView(str(i), corners, target.object_points()), camera)
        points = board_scan(invert(T_CAM_LIDAR) @ T_cam_board, outline, rng, n_board=2000, noise_m=0.01)
        observations.append(
            BoardObservation(estimated, PointCloud(points, np.zeros(len(points), np.float32)), str(i))
        )
    return observations


def _guess() -> np.ndarray:
    delta = make_transform(
        Rotation.from_rotvec(np.radians(2.0) * np.array([0.6, 0.8, 0.0])).as_matrix(), [0.08, -0.06, 0.0]
    )
    return delta @ T_CAM_LIDAR


def test_virtual_rig_board_extrinsic_within_0p1_deg_and_1_cm() -> None:
    observations = _observations(10, seed=0)
    assert len(observations) >= 8
    result = calibrate_with_board(observations, HALF, _guess())
    trans, angle = distance_and_angle(result.T_cam_lidar, T_CAM_LIDAR)
    rot = np.degrees(angle)
    assert rot < 0.1 and trans < 0.01, (rot, trans)
    assert result.verdict == "ok", result.reasons
    assert result.extra["plane_rms_m"] < 0.015
    assert 0 < result.rotation_std_deg < 0.1 and 0 < result.translation_std_m < 0.01
    # The jackknife over 8 groups of poses: Student's t with 7 degrees of freedom, not 1.96.
    assert result.interval_95 == pytest.approx(jackknife_interval_95(JACKKNIFE_GROUPS))
    interval = result.to_json()["rotation_interval_95_deg"]
    assert interval == pytest.approx(2.365 * result.rotation_std_deg, rel=1e-3)


def test_range_noise_along_the_rays_does_not_tilt_the_boards() -> None:
    """Boards seen obliquely, exact camera poses, 4 cm range noise along the LiDAR's rays: fitted
    as point-to-plane distances, the noise tilted the boards the same way in every draw (0.24–0.27°
    over 4 draws); as range errors along the rays, 0.02–0.04°."""
    rng = np.random.default_rng(0)
    outline = (-HALF[0], HALF[0], -HALF[1], HALF[1])
    observations = []
    for i, tilt in enumerate(([50, 0, 0], [0, 50, 0], [-50, 0, 0], [0, -50, 0], [35, 35, 0])):
        R = Rotation.from_euler("xyz", tilt, degrees=True).as_matrix()
        T_cam_board = make_transform(R, [0.3 * (i - 2), 0.1 * (i % 2), 2.0])  # centre at 0
        points = board_scan(invert(T_CAM_LIDAR) @ T_cam_board, outline, rng, n_board=20000, noise_m=0.04)
        observations.append(
            BoardObservation(T_cam_board, PointCloud(points, np.zeros(len(points), np.float32)), str(i))
        )
    result = calibrate_with_board(observations, HALF, _guess())
    trans, angle = distance_and_angle(result.T_cam_lidar, T_CAM_LIDAR)
    rot = np.degrees(angle)
    assert rot < 0.08 and trans < 0.005, (rot, trans)
    assert result.verdict == "ok", result.reasons


def test_single_board_pose_is_poorly_constrained() -> None:
    observations = _observations(1, seed=0)
    result = calibrate_with_board(observations, HALF, _guess())
    assert result.verdict == "poorly constrained"
    assert result.interval_95 == NORMAL_95  # no jackknife ran: the Jacobian's spread alone
    assert "1 pose" in result.reasons[0]
    with pytest.raises(InputError, match="no initial guess"):
        calibrate_with_board(observations, HALF, None)


def test_parallel_boards_are_poorly_constrained() -> None:
    observations = _observations(4, seed=2)
    same_tilt = [BoardObservation(observations[0].T_cam_board, o.cloud, o.name) for o in observations[:1]] * 4
    result = calibrate_with_board(same_tilt, HALF, _guess())
    assert result.verdict == "poorly constrained"
    assert "normals hardly differ" in result.reasons[0]


def test_cli_board_mode(tmp_path) -> None:
    import json
    import subprocess
    import sys
    from pathlib import Path

    import cv2

    from rig.calibration import Calibration, load_calibration, save_calibration

    camera = sim_camera("pinhole")
    rng = np.random.default_rng(4)
    corners_centre = ((COLS - 1) * SQUARE / 2, (ROWS - 1) * SQUARE / 2)
    outline = (-SQUARE, COLS * SQUARE, -SQUARE, ROWS * SQUARE)
    args = []
    for i, T_cam_board in enumerate(board_poses(8, 2.0, rng, corners_centre, max_tilt_deg=50)):
        cv2.imwrite(str(tmp_path / f"{i}.png"), render_chessboard(camera, T_cam_board, COLS, ROWS, SQUARE))
        points = board_scan(invert(T_CAM_LIDAR) @ T_cam_board, outline, rng, n_board=2000)
        np.column_stack([points, np.zeros(len(points))]).astype("<f4").tofile(tmp_path / f"{i}.bin")
        args += ["--image", tmp_path / f"{i}.png", "--points", tmp_path / f"{i}.bin"]
    init, out = tmp_path / "init.yaml", tmp_path / "calib.yaml"
    save_calibration(Calibration(camera, _guess()), init)
    lts = Path(sys.executable).parent / "lts"
    result = subprocess.run(
        [
            str(lts),
            "calibrate",
            "extrinsic",
            *map(str, args),
            "--init",
            str(init),
            "--out",
            str(out),
            "--board",
            f"{COLS}x{ROWS}",
            "--square",
            str(SQUARE),
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["method"] == "target-based (board planes)"
    trans, angle = distance_and_angle(load_calibration(out).T_cam_lidar, T_CAM_LIDAR)
    rot = np.degrees(angle)
    assert rot < 0.15 and trans < 0.01, (rot, trans)


def test_outline_places_the_board_along_its_planes() -> None:
    """Boards turned only about the camera's y axis: their planes say nothing about the LiDAR's
    height (camera y), which the boards' top and bottom edges then fix."""
    rng = np.random.default_rng(5)
    observations = []
    for i, yaw in enumerate((-35.0, -10.0, 15.0, 40.0)):
        R = Rotation.from_euler("y", yaw, degrees=True).as_matrix()
        T_cam_board = make_transform(R, [0.3 * np.sin(np.radians(yaw)), 0.1 * (i - 1.5), 2.5])  # centre at 0
        outline = (-HALF[0], HALF[0], -HALF[1], HALF[1])
        points = board_scan(invert(T_CAM_LIDAR) @ T_cam_board, outline, rng, n_board=2000, noise_m=0.01)
        observations.append(
            BoardObservation(T_cam_board, PointCloud(points, np.zeros(len(points), np.float32)))
        )
    guess = T_CAM_LIDAR.copy()
    guess[1, 3] += 0.05
    result = calibrate_with_board(observations, HALF, guess)
    assert result.verdict == "poorly constrained"  # the normals span a plane only
    assert abs(result.T_cam_lidar[1, 3] - T_CAM_LIDAR[1, 3]) < 0.005, (
        result.T_cam_lidar[1, 3] - T_CAM_LIDAR[1, 3]
    )
    assert result.n_edge_points > 0
