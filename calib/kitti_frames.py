"""Single frames in KITTI's object-detection layout (``calib/NAME.txt``, ``image_2/NAME.png``,
``velodyne/NAME.bin``): an image + cloud pair with the dataset's target-based reference extrinsic,
as the calibration benchmark reads them."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib.targetless import ExtrinsicPair, read_pair
from rig.camera import CameraModel
from rig.errors import InputError
from rig.kitti import kitti_camera, read_kitti_calib


def kitti_frame_names(folder: Path) -> list[str]:
    """Names of the frames with a Velodyne scan under ``folder/velodyne``, in order."""
    names = sorted(p.stem for p in (folder / "velodyne").glob("*.bin"))
    if not names:
        raise InputError(
            "no KITTI frames: expected velodyne/NAME.bin with image_2/NAME.png and calib/NAME.txt",
            path=folder,
        )
    return names


def read_kitti_frame(folder: Path, name: str) -> tuple[ExtrinsicPair, CameraModel, np.ndarray]:
    """Frame ``name``: the left colour image with its Velodyne cloud, the rectified camera and
    the reference ``T_cam_velo`` ``(4, 4)``."""
    pair = read_pair(folder / "image_2" / f"{name}.png", folder / "velodyne" / f"{name}.bin")
    height, width = pair.image.shape[:2]
    camera, T_ref = kitti_camera(read_kitti_calib(folder / "calib" / f"{name}.txt"), width, height)
    return pair, camera, T_ref
