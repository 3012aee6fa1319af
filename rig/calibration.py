"""The calibration file ``calib.yaml``: camera intrinsics, ``T_cam_lidar``, time offset, quality.

``time_offset_s`` is the number of seconds to add to LiDAR timestamps to express them on the
camera clock. ``quality`` holds the residuals that produced the calibration (free-form mapping).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from rig.atomic_file import write_atomic
from rig.camera import CameraModel
from rig.data_file import load_data_file
from rig.errors import InputError
from rig.plain import plain_data
from rig.transforms import check_rigid


@dataclass(eq=False)
class Calibration:
    """Camera model, LiDAR→camera extrinsic ``(4, 4)``, time offset and quality block."""

    camera: CameraModel
    T_cam_lidar: np.ndarray = field(default_factory=lambda: np.eye(4))
    time_offset_s: float = 0.0
    quality: dict[str, Any] = field(default_factory=dict)
    #: False for the camera alone (a file without ``T_cam_lidar``, as ``lts calibrate intrinsics``
    #: writes one): ``T_cam_lidar`` is then a placeholder, and no guess of the extrinsic.
    has_extrinsic: bool = True

    def __post_init__(self) -> None:
        self.T_cam_lidar = check_rigid(self.T_cam_lidar, field="T_cam_lidar")

    def to_dict(self) -> dict[str, Any]:
        extrinsic = {"T_cam_lidar": self.T_cam_lidar.tolist()} if self.has_extrinsic else {}
        return {
            "camera": self.camera.to_dict(),
            **extrinsic,
            "time_offset_s": float(self.time_offset_s),
            "quality": plain_data(self.quality),
        }


def load_calibration(path: str | Path, needs_extrinsic: bool = False) -> Calibration:
    """Read and validate ``calib.yaml``; errors name the file and the field. Without
    ``T_cam_lidar`` it is the camera alone (:attr:`Calibration.has_extrinsic` False), unless
    ``needs_extrinsic``: then that is an error."""
    path = Path(path)
    data = load_data_file(path, "YAML", "calibration")
    if not isinstance(data, dict):
        raise InputError("expected a mapping with camera, T_cam_lidar, time_offset_s", path=path)
    if "camera" not in data:
        raise InputError("missing", path=path, field="camera")
    if needs_extrinsic and "T_cam_lidar" not in data:
        raise InputError(
            "missing: this file holds the camera alone, and a LiDAR-to-camera extrinsic is needed here "
            "(give it as --init to lts calibrate SESSION or lts reconstruct, which find one)",
            path=path,
            field="T_cam_lidar",
        )
    camera = CameraModel.from_dict(data["camera"], path=str(path))
    T = check_rigid(data.get("T_cam_lidar", np.eye(4).tolist()), field="T_cam_lidar", path=str(path))
    try:
        offset = float(data.get("time_offset_s", 0.0))
    except (TypeError, ValueError):
        raise InputError(
            f"expected seconds, got {data.get('time_offset_s')!r}", path=path, field="time_offset_s"
        ) from None
    if not np.isfinite(offset):
        raise InputError("must be finite", path=path, field="time_offset_s")
    quality = data.get("quality") or {}
    if not isinstance(quality, dict):
        raise InputError("expected a mapping", path=path, field="quality")
    return Calibration(camera, T, offset, quality, has_extrinsic="T_cam_lidar" in data)


def save_calibration(calibration: Calibration, path: str | Path) -> None:
    """Write ``calib.yaml`` (atomically: a crash never leaves a half-written file)."""
    write_atomic(path, yaml.safe_dump(calibration.to_dict(), sort_keys=False, default_flow_style=None))
