"""The pixels a ground truth leaves empty: a ground plane below a level camera leaves the top half."""

from __future__ import annotations

import numpy as np
import trimesh

from eval.sky_pixels import sky_masks
from rig.camera import CameraModel

CAMERA = CameraModel("pinhole", 64, 48, [[40, 0, 31.5], [0, 40, 23.5], [0, 0, 1]], [])


def _ground(height_m: float) -> trimesh.Trimesh:
    """A 400 m square plane ``height_m`` below a camera at the origin looking along +z (y down)."""
    return trimesh.creation.box(
        extents=(400, 0.01, 400), transform=trimesh.transformations.translation_matrix((0, height_m, 0))
    )


def test_the_rows_above_the_horizon_are_sky_the_rest_ground() -> None:
    (sky,) = sky_masks(_ground(1.5), CAMERA, [np.eye(4)])
    assert sky.shape == (48, 64)
    # the horizon of a 400 m plane 1.5 m below lies 0.3 px under the principal row (23.5)
    assert sky[:24].all() and not sky[24:].any()


def test_one_mask_per_pose_each_from_its_own_viewpoint() -> None:
    tilted_down = np.eye(4)
    tilted_down[:3, :3] = trimesh.transformations.rotation_matrix(np.radians(-60), (1, 0, 0))[:3, :3]
    level, looking_down = sky_masks(_ground(1.5), CAMERA, [np.eye(4), tilted_down])
    assert level[:24].all()
    assert not looking_down.any()  # 60° down: the ground fills the 62° tall view
