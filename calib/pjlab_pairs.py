"""Image + cloud pairs in the layout of PJLab's OpenCalib (SensorsCalibration): one folder per
pair, as the calibration benchmark reads them::

    NAME/IMAGE.png|.jpg                         one camera image
    NAME/CLOUD.pcd                              the LiDAR cloud taken with it
    NAME/CAMERA-intrinsic.json                  {"CAMERA-intrinsic": {"param": {"cam_K": {"data": 3x3},
                                                                                "cam_dist": {"data": 1xN}}}}
    NAME/LIDAR-to-CAMERA-extrinsic.json         {"LIDAR-to-CAMERA-extrinsic": {"param": {"sensor_calib":
                                                                                {"data": 4x4}}}}

The extrinsic file is the pair's reference ``T_cam_lidar``. A folder holding these files is one
pair; a folder of such folders is several.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib.targetless import ExtrinsicPair
from rig.camera import CameraModel
from rig.data_file import load_data_file, matrix_field
from rig.errors import InputError
from rig.image_io import read_image
from rig.pointcloud_io import read_point_cloud

INTRINSIC_SUFFIX = "-intrinsic.json"
EXTRINSIC_SUFFIX = "-extrinsic.json"
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def _is_pair(folder: Path) -> bool:
    return any(folder.glob(f"*{INTRINSIC_SUFFIX}"))


def pjlab_pair_names(root: Path) -> list[str]:
    """The pairs under ``root``: ``"."`` when ``root`` is a pair's folder itself, else the names of
    its sub-folders that are, in order."""
    if _is_pair(root):
        return ["."]
    names = sorted(p.name for p in root.iterdir() if p.is_dir() and _is_pair(p)) if root.is_dir() else []
    if not names:
        raise InputError(
            f"no OpenCalib pairs: expected folders with an image, a .pcd, a *{INTRINSIC_SUFFIX} and a "
            f"*{EXTRINSIC_SUFFIX}",
            path=root,
        )
    return names


def _one_file(folder: Path, suffixes: tuple[str, ...], what: str) -> Path:
    found = sorted(p for p in folder.iterdir() if p.name.lower().endswith(suffixes))
    if len(found) != 1:
        names = ", ".join(p.name for p in found) or "none"
        raise InputError(f"expected one {what} ({' or '.join(suffixes)}), found {names}", path=folder)
    return found[0]


def _param(path: Path, keys: tuple[str, ...], shape: tuple[int | None, ...]) -> np.ndarray:
    """The matrix at ``keys`` under the file's own top-level key (its name without ``.json``)."""
    document = load_data_file(path, "JSON", "an OpenCalib parameter file")
    return matrix_field(document, (path.stem, *keys), shape, path)


def read_pjlab_pair(root: Path, name: str) -> tuple[ExtrinsicPair, CameraModel, np.ndarray]:
    """Pair ``name`` under ``root`` (:func:`pjlab_pair_names`): its image and cloud, the camera
    model and the reference ``T_cam_lidar`` ``(4, 4)``."""
    folder = root / name
    intrinsic = _one_file(folder, (INTRINSIC_SUFFIX,), "intrinsic file")
    extrinsic = _one_file(folder, (EXTRINSIC_SUFFIX,), "extrinsic file")
    K = _param(intrinsic, ("param", "cam_K", "data"), (3, 3))
    dist = _param(intrinsic, ("param", "cam_dist", "data"), (None, None)).ravel()
    T_ref = _param(extrinsic, ("param", "sensor_calib", "data"), (4, 4))
    image = read_image(_one_file(folder, IMAGE_SUFFIXES, "image"))
    cloud = read_point_cloud(_one_file(folder, (".pcd",), "point cloud"))
    # The image's own size: one shared pair's JSON says 1080 rows for a 1200-row image.
    camera = CameraModel("pinhole", image.shape[1], image.shape[0], K, dist)
    return ExtrinsicPair(image, cloud), camera, T_ref
