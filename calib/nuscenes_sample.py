"""A nuScenes sample as the calibration benchmark reads it: one LiDAR sweep (``.pcd.bin``) and the
images of the cameras around it, listed in a ``calib.json``::

    {"lidar": {"file": "...LIDAR_TOP....pcd.bin"},
     "cameras": {"CAM_FRONT": {"file": "....jpg", "width": 1600, "height": 900,
                               "K": 3x3, "dist": [], "T_cam_lidar_with_ego_motion": 4x4}, ...}}

The reference of each camera is nuScenes' calibration composed with the car's motion between the
sweep's stamp and the image's (``T_cam_lidar_with_ego_motion``: at 9 m/s the front camera's image is
33 cm from where the sweep was taken), so a pair's points land where the image saw them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from calib.targetless import ExtrinsicPair, read_pair
from rig.camera import CameraModel
from rig.data_file import load_data_file, matrix_field
from rig.errors import InputError

CALIB_FILE = "calib.json"
REFERENCE_FIELD = "T_cam_lidar_with_ego_motion"


def _calib(folder: Path) -> dict[str, Any]:
    path = folder / CALIB_FILE
    if not path.is_file():
        raise InputError(
            f"no {CALIB_FILE}: expected a nuScenes sample (a LiDAR sweep, camera images and their "
            "calibration)",
            path=folder,
        )
    calib = load_data_file(path, "JSON", "the nuScenes sample's calibration")
    cameras = calib.get("cameras") if isinstance(calib, dict) else None
    if not isinstance(cameras, dict) or not cameras:
        raise InputError(
            "expected a mapping of camera names to their calibration", path=path, field="cameras"
        )
    if not isinstance(calib.get("lidar"), dict) or not isinstance(calib["lidar"].get("file"), str):
        raise InputError("expected the sweep's file name", path=path, field="lidar.file")
    return calib


def nuscenes_camera_names(folder: Path) -> list[str]:
    """The cameras of the sample in ``folder`` (as its ``calib.json`` lists them)."""
    return list(_calib(folder)["cameras"])


def read_nuscenes_camera(folder: Path, name: str) -> tuple[ExtrinsicPair, CameraModel, np.ndarray]:
    """Camera ``name`` of the sample: its image with the sweep, its camera model and the reference
    ``T_cam_lidar`` ``(4, 4)`` with the car's motion between the two stamps."""
    calib = _calib(folder)
    path = folder / CALIB_FILE
    where = f"cameras.{name}"
    entry = calib["cameras"].get(name)
    if not isinstance(entry, dict) or not isinstance(entry.get("file"), str):
        raise InputError("expected the camera's image file name", path=path, field=f"{where}.file")
    K = matrix_field(calib, ("cameras", name, "K"), (3, 3), path)
    T_ref = matrix_field(calib, ("cameras", name, REFERENCE_FIELD), (4, 4), path)
    pair = read_pair(folder / entry["file"], folder / calib["lidar"]["file"])
    height, width = pair.image.shape[:2]
    if (entry.get("width"), entry.get("height")) != (width, height):
        raise InputError(
            f"the image is {width}x{height}, the calibration says {entry.get('width')}x{entry.get('height')}",
            path=path,
            field=f"{where}.width",
        )
    return pair, CameraModel("pinhole", width, height, K, entry.get("dist") or []), T_ref
