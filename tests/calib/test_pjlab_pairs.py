"""PJLab's OpenCalib pairs: an image, a cloud, the camera and the reference; bad folders refused."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from calib.pjlab_pairs import pjlab_pair_names, read_pjlab_pair
from rig.errors import InputError
from rig.transforms import transform_points

INTRINSIC = "cam-intrinsic.json"
EXTRINSIC = "lidar-to-cam-extrinsic.json"


def _pair(folder, K=((50, 0, 32), (0, 50, 24), (0, 0, 1)), T=None):
    """A 64x48 image, a 3-point ASCII PCD and OpenCalib's two parameter files."""
    folder.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(folder / "0.png"), np.full((48, 64, 3), 128, np.uint8))
    (folder / "0.pcd").write_text(
        "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 3\n"
        "HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 0 5 10\n0 1 6 20\n2 2 7 30\n"
    )
    param = {"cam_K": {"data": [list(r) for r in K]}, "cam_dist": {"data": [[0.1, 0, 0, 0]]}}
    (folder / INTRINSIC).write_text(json.dumps({INTRINSIC[:-5]: {"param": param}}))
    T = np.eye(4).tolist() if T is None else T
    (folder / EXTRINSIC).write_text(json.dumps({EXTRINSIC[:-5]: {"param": {"sensor_calib": {"data": T}}}}))
    return folder


def test_a_pair_comes_with_its_camera_and_reference(tmp_path):
    _pair(tmp_path / "b")
    _pair(tmp_path / "a")
    (tmp_path / "notes").mkdir()
    assert pjlab_pair_names(tmp_path) == ["a", "b"]
    assert pjlab_pair_names(tmp_path / "a") == ["."]
    pair, camera, reference = read_pjlab_pair(tmp_path, "a")
    assert pair.image.shape == (48, 64, 3)
    np.testing.assert_allclose(pair.cloud.intensity, [10, 20, 30])
    assert (camera.width, camera.height, camera.K[0, 0]) == (64, 48, 50.0)
    np.testing.assert_allclose(camera.dist, [0.1, 0, 0, 0])
    np.testing.assert_array_equal(reference, np.eye(4))


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (
            lambda f: _pair(f, K=((1, 0), (0, 1))),
            r"cam-intrinsic\.json: cam-intrinsic\.param\.cam_K\.data: expected a 3x3",
        ),
        (lambda f: _pair(f, T=[[1, 2, 3]]), r"sensor_calib\.data: expected a 4x4 matrix"),
        (lambda f: (_pair(f), (f / "0.pcd").unlink()), r"expected one point cloud \(\.pcd\), found none"),
        (
            lambda f: (_pair(f), (f / "1.jpg").write_bytes(b"x")),
            r"expected one image .* found 0\.png, 1\.jpg",
        ),
        (lambda f: (_pair(f), (f / EXTRINSIC).write_text("{")), r"extrinsic\.json:1: not valid JSON"),
    ],
)
def test_bad_pairs_name_the_file_and_field(tmp_path, make, message):
    make(tmp_path / "p")
    with pytest.raises(InputError, match=message):
        read_pjlab_pair(tmp_path, "p")


def test_a_folder_without_pairs_is_refused(tmp_path):
    with pytest.raises(InputError, match="no OpenCalib pairs"):
        pjlab_pair_names(tmp_path)
    with pytest.raises(InputError, match="no OpenCalib pairs"):
        pjlab_pair_names(tmp_path / "missing")


def test_the_shared_pairs_project_into_their_images(real_data):
    folder = real_data / "lidar_camera_pjlab"
    assert pjlab_pair_names(folder) == ["auto", "manual"]
    for name in ("auto", "manual"):
        pair, camera, reference = read_pjlab_pair(folder, name)
        assert (camera.width, camera.height) == (1920, 1200)  # the image's size, not the JSON's
        seen = camera.in_image(camera.project(transform_points(reference, pair.cloud.points)))
        assert seen.mean() > 0.05, name
