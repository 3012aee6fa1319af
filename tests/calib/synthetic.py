"""Synthetic board pictures and LiDAR board scans with exact ground truth (test helpers)."""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from rig.camera import CameraModel
from rig.transforms import make_transform, transform_points

#: Texture pixels per board square.
PIXELS_PER_SQUARE = 48


def sim_camera(model: str = "pinhole", width: int = 640, height: int = 480) -> CameraModel:
    """A camera like the virtual rig's (``rig.sim``'s lens numbers) at a board-friendly size."""
    if model == "fisheye":
        f, dist = 0.45 * width, [0.02, -0.01, 0.003, -0.001]
    else:
        f, dist = 0.78 * width, [-0.10, 0.04, 0.0005, -0.0003, 0.0]
    K = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])
    return CameraModel(model, width, height, K, np.array(dist))  # type: ignore[arg-type]


@lru_cache(maxsize=4)
def _rays(camera_key: tuple) -> np.ndarray:
    model, width, height, K, dist = camera_key
    camera = CameraModel(model, width, height, np.array(K), np.array(dist))
    u, v = np.meshgrid(np.arange(width), np.arange(height))
    xy = camera.normalized_coordinates(np.stack([u.ravel(), v.ravel()], axis=1))
    return xy.reshape(height, width, 2).astype(np.float32)


def _key(camera: CameraModel) -> tuple:
    return (camera.model, camera.width, camera.height, tuple(map(tuple, camera.K)), tuple(camera.dist))


def chessboard_texture(cols: int, rows: int) -> np.ndarray:
    """Board texture: (cols + 1) × (rows + 1) squares plus one white square of margin all round."""
    s = PIXELS_PER_SQUARE
    squares = (np.indices((rows + 1, cols + 1)).sum(axis=0) % 2 == 0).astype(np.uint8)
    board = np.kron(1 - squares, np.ones((s, s), np.uint8)) * 255
    return cv2.copyMakeBorder(board, s, s, s, s, cv2.BORDER_CONSTANT, value=255)


def render_texture(
    camera: CameraModel, T_cam_board: np.ndarray, texture: np.ndarray, square_m: float, origin_px: float
) -> np.ndarray:
    """Grey image ``(H, W)`` of a planar texture (``square_m`` per PIXELS_PER_SQUARE texture pixels,
    board origin at texture pixel ``(origin_px, origin_px)``) seen from ``T_cam_board``, grey 128
    elsewhere. Pixels are mapped exactly through the lens model; 2×2 supersampled."""
    xy = _rays(_key(camera))
    R, t = T_cam_board[:3, :3], T_cam_board[:3, 3]
    out = np.zeros((camera.height, camera.width), np.float32)
    scale = square_m / PIXELS_PER_SQUARE
    for du, dv in ((-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)):
        ray = np.dstack([xy[..., 0] + du / camera.fx, xy[..., 1] + dv / camera.fy, np.ones(xy.shape[:2])])
        # Ray-plane intersection in the board frame: board z = 0.
        o_b = -R.T @ t
        d_b = ray @ R  # (H, W, 3): R.T @ ray
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = -o_b[2] / d_b[..., 2]
        p = o_b + lam[..., None] * d_b
        map_x = (p[..., 0] / scale + origin_px).astype(np.float32)
        map_y = (p[..., 1] / scale + origin_px).astype(np.float32)
        valid = np.isfinite(lam) & (lam > 0)
        map_x[~valid] = -1e4
        sample = cv2.remap(
            texture, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=128
        )
        out += sample.astype(np.float32) / 4
    return np.clip(out, 0, 255).astype(np.uint8)


def render_chessboard(
    camera: CameraModel, T_cam_board: np.ndarray, cols: int, rows: int, square_m: float
) -> np.ndarray:
    """Grey picture of a ``cols`` × ``rows`` inner-corner chessboard; board origin = first inner corner."""
    # Square k covers texture pixels [k s, (k + 1) s - 1]: its edge is at k s - 0.5 for cv2.remap.
    return render_texture(
        camera, T_cam_board, chessboard_texture(cols, rows), square_m, 2 * PIXELS_PER_SQUARE - 0.5
    )


def board_poses(
    n: int,
    distance_m: float,
    rng: np.random.Generator,
    centre_m: tuple[float, float],
    max_tilt_deg: float = 35.0,
) -> list[np.ndarray]:
    """``n`` varied ``T_cam_board`` poses: board centre (``centre_m`` in board frame) in front of the
    camera at about ``distance_m``, tilted up to ``max_tilt_deg`` and shifted across the view."""
    poses = []
    for i in range(n):
        tilt = Rotation.from_euler(
            "xyz",
            [
                rng.uniform(-max_tilt_deg, max_tilt_deg),
                rng.uniform(-max_tilt_deg, max_tilt_deg),
                rng.uniform(-15, 15),
            ],
            degrees=True,
        )
        R = tilt.as_matrix()
        shift = np.array([rng.uniform(-0.25, 0.25), rng.uniform(-0.18, 0.18), 0.0]) * distance_m
        if i == 0:
            shift[:] = 0
        centre_cam = np.array([0.0, 0.0, distance_m]) + shift
        t = centre_cam - R @ np.array([*centre_m, 0.0])
        poses.append(make_transform(R, t))
    return poses


def board_scan(
    T_lidar_board: np.ndarray,
    extent: tuple[float, float, float, float],
    rng: np.random.Generator,
    n_board: int = 600,
    noise_m: float = 0.01,
) -> np.ndarray:
    """LiDAR points ``(N, 3)``: samples on the board rectangle plus a wall 1.5 m behind it and a
    floor, each with range noise (a stand-in for the virtual rig's LiDAR with default noise)."""
    x0, x1, y0, y1 = extent
    board = np.column_stack([rng.uniform(x0, x1, n_board), rng.uniform(y0, y1, n_board), np.zeros(n_board)])
    wall = np.column_stack(
        [rng.uniform(x0 - 2, x1 + 2, 2000), rng.uniform(y0 - 2, y1 + 2, 2000), np.full(2000, 1.5)]
    )
    pts = transform_points(T_lidar_board, np.vstack([board, wall]))
    rng_dir = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    return pts + rng_dir * rng.normal(0, noise_m, (len(pts), 1))


def render_charuco(camera: CameraModel, T_cam_board: np.ndarray, board: cv2.aruco.CharucoBoard) -> np.ndarray:
    """Grey picture of a ChArUco board (board origin = its top-left outer corner)."""
    sx, sy = board.getChessboardSize()
    margin = PIXELS_PER_SQUARE // 2
    texture = board.generateImage(
        (sx * PIXELS_PER_SQUARE + 2 * margin, sy * PIXELS_PER_SQUARE + 2 * margin), None, margin, 1
    )
    return render_texture(camera, T_cam_board, texture, board.getSquareLength(), margin - 0.5)
