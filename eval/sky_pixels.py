"""Which pixels of a test view the ground truth leaves empty (sky), and how a render treats them.

Outdoors the camera sees sky above every building; a reconstruction should leave those pixels to
its background. A camera-only triangle placed there (a facade continued past its roof, a seed on a
roofline whose silhouette is wrong from a new viewpoint) paints structure where the image shows
sky, and on the virtual street such pixels, 1 % of the static ones, carried a quarter of their
squared error. A pixel is sky when its ray from the keyframe meets no face of the ground truth
(aligned to the scene); the virtual rig's meshes end at the sky, so for them this is exact.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

from rig.camera import CameraModel
from rig.mesh_rays import cast_camera_rays, mesh_raycaster, pixel_rays


def sky_masks(
    mesh: trimesh.Trimesh, camera: CameraModel, poses_world_cam: Sequence[np.ndarray]
) -> list[np.ndarray]:
    """``(H, W)`` bool masks, one per pose ``(4, 4)`` (camera to world, the mesh's frame): the pixels
    of ``camera`` whose ray meets no face of ``mesh``."""
    raycaster = mesh_raycaster(mesh)
    rays = pixel_rays(camera)
    shape = (camera.height, camera.width)
    return [
        ~np.isfinite(cast_camera_rays(raycaster, T_world_cam, rays)["t_hit"]).reshape(shape)
        for T_world_cam in poses_world_cam
    ]
