from pathlib import Path

import cv2
import numpy as np

from rig import CameraModel
from rig.kitti import kitti_camera, read_kitti_calib
from slam_bridge.depth_image import (
    lidar_depth_image,
    nearest_returns,
    remove_occluded,
    visible_returns,
    zbuffer_depth,
)


def test_kitti_depth_image_matches_an_independent_projection(real_data: Path) -> None:
    folder = real_data / "kitti_frames"
    image = cv2.imread(str(folder / "image_2" / "000000.png"))
    calib = read_kitti_calib(folder / "calib" / "000000.txt")
    scan = np.fromfile(folder / "velodyne" / "000000.bin", dtype=np.float32).reshape(-1, 4)[:, :3]
    camera, T_cam_velo = kitti_camera(calib, image.shape[1], image.shape[0])
    depth = lidar_depth_image(scan, T_cam_velo, camera, occlusion_window_px=None)

    # Independent: KITTI's own formula x = P2 · R0_rect · Tr_velo_to_cam · X in homogeneous form.
    R0 = np.eye(4)
    R0[:3, :3] = calib["R0_rect"]
    Tr = np.vstack([calib["Tr_velo_to_cam"], [0, 0, 0, 1]])
    x = calib["P2"] @ R0 @ Tr @ np.c_[scan, np.ones(len(scan))].T
    u, v = x[0] / x[2], x[1] / x[2]
    ok = (x[2] > 0.05) & (u >= -0.5) & (u < image.shape[1] - 0.5) & (v >= -0.5) & (v < image.shape[0] - 0.5)
    expected = np.full(image.shape[:2], np.inf)
    np.minimum.at(expected, (np.round(v[ok]).astype(int), np.round(u[ok]).astype(int)), x[2][ok])
    expected[np.isinf(expected)] = 0
    # The third homogeneous coordinate of P2 · X is camera 2's depth (P2 = K [I | t2]).
    assert (depth > 0).sum() == (expected > 0).sum() > 10_000
    np.testing.assert_allclose(depth, expected, atol=1e-4)
    assert 5.0 < np.median(depth[depth > 0]) < 40.0


def test_see_through_points_are_removed() -> None:
    camera = CameraModel("pinhole", 64, 48, [[50, 0, 31.5], [0, 50, 23.5], [0, 0, 1]], [])
    rng = np.random.default_rng(0)
    # A wall at 5 m seen everywhere, a post at 1 m in front of part of it, sampled sparsely.
    wall = np.c_[rng.uniform(-3, 3, 3000), rng.uniform(-2.4, 2.4, 3000), np.full(3000, 5.0)]
    post = np.c_[rng.uniform(-0.1, 0.1, 150), rng.uniform(-0.5, 0.5, 150), np.full(150, 1.0)]
    depth = zbuffer_depth(np.vstack([wall, post]), camera)
    behind_post = (
        (depth > 4)
        & (np.abs(np.arange(64) - 31.5) < 4)[None, :]
        & (np.abs(np.arange(48) - 23.5) < 20)[:, None]
    )
    assert behind_post.sum() > 0  # the sparse post lets the wall shine through
    cleaned = remove_occluded(depth)
    assert not ((cleaned > 4) & behind_post & (np.abs(np.arange(64) - 31.5) < 3)[None, :]).any()
    far_from_post = (np.abs(np.arange(64) - 31.5) > 12)[None, :] & (depth > 0)
    assert (cleaned[far_from_post] == depth[far_from_post]).all()  # the open wall is untouched


def test_the_nearest_return_of_each_pixel_wins() -> None:
    camera = CameraModel("pinhole", 64, 48, [[50, 0, 31.5], [0, 50, 23.5], [0, 0, 1]], [])
    rng = np.random.default_rng(1)
    points = np.c_[rng.uniform(-4, 4, (5000, 2)), rng.uniform(-1, 6, 5000)]
    pixels, winners = nearest_returns(points, camera)
    # Independent: np.minimum.at over the rounded projections of the points in front.
    front = points[points[:, 2] > 0.05]
    uv = front[:, :2] / front[:, 2:] * 50 + [31.5, 23.5]
    ok = (uv[:, 0] >= -0.5) & (uv[:, 0] < 63.5) & (uv[:, 1] >= -0.5) & (uv[:, 1] < 47.5)
    expected = np.full(64 * 48, np.inf)
    np.minimum.at(
        expected, np.round(uv[ok, 1]).astype(int) * 64 + np.round(uv[ok, 0]).astype(int), front[ok, 2]
    )
    np.testing.assert_array_equal(pixels, np.flatnonzero(np.isfinite(expected)))
    np.testing.assert_array_equal(points[winners, 2], expected[pixels])


def test_visible_returns_are_those_the_occlusion_test_keeps() -> None:
    camera = CameraModel("pinhole", 64, 48, [[50, 0, 31.5], [0, 50, 23.5], [0, 0, 1]], [])
    rng = np.random.default_rng(0)
    wall = np.c_[rng.uniform(-3, 3, 3000), rng.uniform(-2.4, 2.4, 3000), np.full(3000, 5.0)]
    post = np.c_[rng.uniform(-0.1, 0.1, 150), rng.uniform(-0.5, 0.5, 150), np.full(150, 1.0)]
    points = np.vstack([wall, post])
    pixels, seen = visible_returns(points, camera, 7)
    kept = remove_occluded(zbuffer_depth(points, camera), 7).ravel()
    np.testing.assert_array_equal(pixels, np.flatnonzero(kept))
    np.testing.assert_array_equal(points[seen, 2], kept[pixels])
