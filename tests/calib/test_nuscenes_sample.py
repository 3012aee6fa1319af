"""The nuScenes sample reader: each camera with the sweep and its reference; bad samples refused."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from calib.nuscenes_sample import nuscenes_camera_names, read_nuscenes_camera
from rig.errors import InputError
from rig.transforms import transform_points


def _sample(folder, **camera_fields):
    """A sample with one 64x48 camera (K, reference 1 m ahead of the sweep) and a 3-point sweep."""
    folder.mkdir(exist_ok=True)
    cv2.imwrite(str(folder / "front.jpg"), np.full((48, 64, 3), 128, np.uint8))
    np.array([[1, 0, 5, 10, 0], [0, 1, 6, 20, 1], [2, 2, 7, 30, 2]], "<f4").tofile(folder / "sweep.pcd.bin")
    reference = np.eye(4)
    reference[2, 3] = -1.0
    camera = {
        "file": "front.jpg",
        "width": 64,
        "height": 48,
        "K": [[50, 0, 32], [0, 50, 24], [0, 0, 1]],
        "dist": [],
        "T_cam_lidar_with_ego_motion": reference.tolist(),
        **camera_fields,
    }
    (folder / "calib.json").write_text(
        json.dumps({"lidar": {"file": "sweep.pcd.bin"}, "cameras": {"FRONT": camera}})
    )
    return folder


def test_a_camera_comes_with_the_sweep_and_the_reference_with_the_motion(tmp_path):
    folder = _sample(tmp_path / "s")
    assert nuscenes_camera_names(folder) == ["FRONT"]
    pair, camera, reference = read_nuscenes_camera(folder, "FRONT")
    assert pair.image.shape == (48, 64, 3)
    np.testing.assert_allclose(pair.cloud.intensity, [10, 20, 30])
    assert (camera.width, camera.height, camera.K[0, 0]) == (64, 48, 50.0)
    assert reference[2, 3] == -1.0


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"K": [[1, 0], [0, 1]]}, r"calib\.json: cameras\.FRONT\.K: expected a 3x3 matrix"),
        (
            {"T_cam_lidar_with_ego_motion": None},
            r"cameras\.FRONT\.T_cam_lidar_with_ego_motion: expected a 4x4",
        ),
        ({"width": 640}, r"cameras\.FRONT\.width: the image is 64x48, the calibration says 640x48"),
        ({"file": "missing.jpg"}, r"missing\.jpg: cannot read the image"),
    ],
)
def test_bad_cameras_name_the_field(tmp_path, fields, message):
    with pytest.raises(InputError, match=message):
        read_nuscenes_camera(_sample(tmp_path / "s", **fields), "FRONT")


def test_folders_that_are_no_sample_are_refused(tmp_path):
    with pytest.raises(InputError, match=r"no calib\.json"):
        nuscenes_camera_names(tmp_path)
    (tmp_path / "calib.json").write_text('{"lidar": {"file": "x.pcd.bin"}, "cameras": []}')
    with pytest.raises(InputError, match=r"calib\.json: cameras: expected a mapping"):
        nuscenes_camera_names(tmp_path)
    (tmp_path / "calib.json").write_text('{"cameras": {"A": {}}}')
    with pytest.raises(InputError, match=r"lidar\.file"):
        nuscenes_camera_names(tmp_path)
    with pytest.raises(InputError, match=r"cameras\.B\.file"):
        read_nuscenes_camera(_sample(tmp_path / "s"), "B")


def test_the_shared_sample_projects_onto_each_camera(real_data):
    folder = real_data / "nuscenes_sample"
    names = nuscenes_camera_names(folder)
    assert len(names) == 6
    for name in names:
        pair, camera, reference = read_nuscenes_camera(folder, name)
        seen = camera.in_image(camera.project(transform_points(reference, pair.cloud.points)))
        # A 32-beam sweep around the car: each camera's ~70° field holds roughly a sixth of it.
        assert 0.08 < seen.mean() < 0.3, name
