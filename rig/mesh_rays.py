"""Rays cast at a triangle mesh (open3d ``RaycastingScene``): one way to build the scene, a
camera's pixel rays, rays cast from a pose and the mesh points pixels see. open3d is imported on first use."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

if TYPE_CHECKING:
    from rig.camera import CameraModel


def mesh_raycaster(mesh: trimesh.Trimesh) -> Any:
    """An open3d ``RaycastingScene`` holding ``mesh``'s triangles."""
    from rig.open3d_lite import o3d

    raycaster = o3d.t.geometry.RaycastingScene()
    raycaster.add_triangles(
        o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)),
        o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32)),
    )
    return raycaster


def pixel_rays(camera: CameraModel, pixels: np.ndarray | None = None) -> np.ndarray:
    """Unit camera-frame rays ``(N, 3)`` through ``pixels`` ``(N, 2)``, by default every pixel
    centre row by row (``N = H * W``); NaN where the camera model cannot back-project the pixel."""
    if pixels is None:
        u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
        pixels = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64)
    rays = camera.unproject(pixels)
    return rays / np.linalg.norm(rays, axis=1, keepdims=True)


def mesh_points(
    raycaster: Any, camera: CameraModel, T_world_cam: np.ndarray, pixels: np.ndarray
) -> np.ndarray:
    """World points ``(N, 3)`` where the rays of ``pixels`` ``(N, 2)`` of a camera at ``T_world_cam``
    meet the mesh (NaN where they miss)."""
    rays = pixel_rays(camera, pixels)
    t_hit = cast_camera_rays(raycaster, T_world_cam, rays)["t_hit"]
    points = T_world_cam[:3, 3] + (rays @ T_world_cam[:3, :3].T) * t_hit[:, None]
    points[~np.isfinite(t_hit)] = np.nan
    return points


def cast_camera_rays(raycaster: Any, T_world_cam: np.ndarray, rays_cam: np.ndarray) -> dict[str, np.ndarray]:
    """Cast unit rays ``(N, 3)`` given in the camera frame from a camera at ``T_world_cam``.

    Returns open3d's hit arrays as numpy: ``t_hit`` ``(N,)`` (distance along the ray, inf on a
    miss) and ``primitive_normals`` ``(N, 3)`` (world frame).
    """
    origins = np.broadcast_to(T_world_cam[:3, 3], rays_cam.shape)
    return cast_world_rays(raycaster, origins, rays_cam @ T_world_cam[:3, :3].T)


def cast_world_rays(raycaster: Any, origins: np.ndarray, directions: np.ndarray) -> dict[str, np.ndarray]:
    """Cast rays from world ``origins`` ``(N, 3)`` along unit world ``directions`` ``(N, 3)``;
    returns the same arrays as :func:`cast_camera_rays`."""
    from rig.open3d_lite import o3d

    rays = np.concatenate([origins, directions], axis=1).astype(np.float32)
    hits = raycaster.cast_rays(o3d.core.Tensor(rays))
    return {
        "t_hit": hits["t_hit"].numpy().astype(np.float64),
        "primitive_normals": hits["primitive_normals"].numpy().astype(np.float64),
    }
