"""KITTI object/odometry calibration files (``P0..P3``, ``R0_rect``, ``Tr_velo_to_cam``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.camera import CameraModel
from rig.errors import InputError
from rig.transforms import make_transform

_SHAPES = {"R0_rect": (3, 3)}


def read_kitti_calib(path: str | Path) -> dict[str, np.ndarray]:
    """Matrices of a KITTI calibration file by name: ``P*`` ``(3, 4)``, ``R0_rect`` ``(3, 3)``,
    ``Tr_*`` ``(3, 4)``."""
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as exc:
        raise InputError(f"cannot read KITTI calibration ({exc.strerror})", path=path) from None
    out: dict[str, np.ndarray] = {}
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        name, _, values = line.partition(":")
        shape = _SHAPES.get(name.strip(), (3, 4))
        try:
            matrix = np.array(values.split(), dtype=np.float64)
        except ValueError:
            raise InputError("expected numbers", path=path, line=number, field=name.strip()) from None
        if matrix.size != shape[0] * shape[1]:
            raise InputError(
                f"expected {shape[0] * shape[1]} numbers, got {matrix.size}",
                path=path,
                line=number,
                field=name.strip(),
            )
        out[name.strip()] = matrix.reshape(shape)
    return out


def kitti_camera(
    calib: dict[str, np.ndarray], width: int, height: int, camera: int = 2
) -> tuple[CameraModel, np.ndarray]:
    """The rectified camera ``camera`` as a pinhole model and its ``T_cam_velo`` ``(4, 4)``.

    KITTI projects ``x = P_i · R0_rect · Tr_velo_to_cam · X``; ``P_i = K [I | t_i]`` holds the
    offset of camera ``i`` from the rectified camera 0, which goes into the extrinsic here.
    """
    for key in (f"P{camera}", "R0_rect", "Tr_velo_to_cam"):
        if key not in calib:
            raise InputError("missing from KITTI calibration", field=key)
    P = calib[f"P{camera}"]
    K = P[:, :3]
    offset = np.linalg.solve(K, P[:, 3])
    T_cam_rect0 = make_transform(np.eye(3), offset)
    T_rect0_cam0 = make_transform(calib["R0_rect"], np.zeros(3))
    T_cam0_velo = np.vstack([calib["Tr_velo_to_cam"], [0.0, 0.0, 0.0, 1.0]])
    return CameraModel("pinhole", width, height, K, []), T_cam_rect0 @ T_rect0_cam0 @ T_cam0_velo
