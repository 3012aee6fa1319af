"""The arrays behind the layers of ``lts view``: coloured meshes, error colours and their scale,
keyframe thumbnails, the trajectory, a keyframe's LiDAR points, and which keyframe is nearest a
viewpoint. Plain numpy/trimesh, no viser (see :mod:`eval.viewer`)."""

from __future__ import annotations

import cv2
import numpy as np
import trimesh
from matplotlib import colormaps

from rig.transforms import transform_points
from slam_bridge.scene import Keyframe, Scene
from splat.model import TriangleModel

#: Colour map of the distance to the ground truth, over ``[0, ERROR_SCALE * threshold]``.
ERROR_COLORMAP = "turbo"
ERROR_SCALE = 2.0
LIDAR_COLORMAP = "plasma"


def _linear_rgb(rgb: np.ndarray) -> np.ndarray:
    """8-bit sRGB ``(N, 3)`` as 8-bit linear RGB: glTF vertex colours are linear, and the viewer
    converts them back to sRGB on screen."""
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return np.round(linear * 255).astype(np.uint8)


def colored_mesh(
    vertices: np.ndarray, faces: np.ndarray, rgb: np.ndarray, alpha: np.ndarray | None = None
) -> trimesh.Trimesh:
    """A double-sided, non-metallic mesh with vertex colours for the viewer's glTF path.

    Args:
        vertices: ``(V, 3)`` positions; faces: ``(F, 3)`` indices.
        rgb: ``(V, 3)`` uint8 sRGB colours.
        alpha: ``(V,)`` opacity in [0, 1] (blended), or ``None`` for an opaque mesh.
    """
    # The splatted triangles face either way, so neither side may be culled.
    material = trimesh.visual.material.PBRMaterial(
        baseColorFactor=[255, 255, 255, 255],
        metallicFactor=0.0,
        roughnessFactor=1.0,
        doubleSided=True,
        alphaMode="OPAQUE" if alpha is None else "BLEND",
    )
    mesh = trimesh.Trimesh(
        vertices, faces, visual=trimesh.visual.TextureVisuals(material=material), process=False
    )
    opacity = np.ones(len(vertices)) if alpha is None else np.clip(alpha, 0.0, 1.0)
    mesh.visual.vertex_attributes["color"] = np.column_stack(
        [_linear_rgb(rgb), np.round(opacity * 255).astype(np.uint8)]
    )
    return mesh


def mesh_colors(mesh: trimesh.Trimesh) -> np.ndarray:
    """``(V, 3)`` uint8 sRGB vertex colours of ``mesh`` (a neutral grey when it has none)."""
    if mesh.visual.kind == "vertex":
        return np.asarray(mesh.visual.vertex_colors)[:, :3].astype(np.uint8)
    return np.full((len(mesh.vertices), 3), 170, dtype=np.uint8)


def triangle_soup(model: TriangleModel) -> trimesh.Trimesh:
    """The model's raw triangles as one blended mesh: ``3F`` vertices with the triangles' colours
    and each triangle's opacity."""
    n = model.n_triangles
    vertices = model.params["vertices"].detach().cpu().numpy().reshape(3 * n, 3)
    colors = model.triangle_colors().detach().cpu().numpy().reshape(3 * n, 3)
    opacity = model.triangle_opacity().detach().cpu().numpy().repeat(3)
    rgb = np.round(colors * 255).clip(0, 255).astype(np.uint8)
    return colored_mesh(vertices, np.arange(3 * n).reshape(n, 3), rgb, opacity)


def error_colors(distance: np.ndarray, threshold_m: float) -> np.ndarray:
    """``(N, 3)`` uint8 colours of distances ``(N,)`` in metres, :data:`ERROR_COLORMAP` over
    ``[0, ERROR_SCALE * threshold_m]`` (farther is the top colour)."""
    scaled = np.clip(np.asarray(distance) / (ERROR_SCALE * threshold_m), 0.0, 1.0)
    return np.round(colormaps[ERROR_COLORMAP](scaled)[:, :3] * 255).astype(np.uint8)


def colorbar(width: int = 256, height: int = 16) -> np.ndarray:
    """``(height, width, 3)`` uint8 image of :data:`ERROR_COLORMAP` from left (0) to right (1)."""
    row = colormaps[ERROR_COLORMAP](np.linspace(0.0, 1.0, width))[:, :3]
    return np.round(np.repeat(row[None], height, axis=0) * 255).astype(np.uint8)


def thumbnail(image: np.ndarray, max_width: int) -> np.ndarray:
    """``image`` ``(H, W, C)`` shrunk to at most ``max_width`` pixels wide (aspect kept)."""
    height, width = image.shape[:2]
    if width <= max_width:
        return image
    size = (max_width, max(1, round(height * max_width / width)))
    return cv2.resize(image, size, interpolation=cv2.INTER_AREA)


def trajectory_segments(scene: Scene) -> np.ndarray:
    """``(K - 1, 2, 3)`` line segments joining the keyframe camera centres in time order."""
    keyframes = sorted(scene.keyframes, key=lambda k: k.t_ns)
    centres = np.stack([k.T_world_cam[:3, 3] for k in keyframes])
    return np.stack([centres[:-1], centres[1:]], axis=1)


def lidar_points(scene: Scene, keyframe: Keyframe) -> tuple[np.ndarray, np.ndarray]:
    """The LiDAR returns ``keyframe``'s camera sees, in the world frame ``(N, 3)``, and colours
    ``(N, 3)`` uint8 by depth (:data:`LIDAR_COLORMAP`, near to far over the 2nd–98th percentile)."""
    points = scene.lidar(keyframe).points.astype(np.float64)
    if not len(points):
        return points, np.zeros((0, 3), dtype=np.uint8)
    depth = points[:, 2]
    near, far = np.percentile(depth, [2, 98])
    scaled = np.clip((depth - near) / max(far - near, 1e-6), 0.0, 1.0)
    colors = np.round(colormaps[LIDAR_COLORMAP](scaled)[:, :3] * 255).astype(np.uint8)
    return transform_points(keyframe.T_world_cam, points), colors


def nearest_keyframe(poses_world_cam: np.ndarray, T_world_cam: np.ndarray) -> int:
    """Index of the pose in ``poses_world_cam`` ``(K, 4, 4)`` whose camera centre is nearest that
    of ``T_world_cam`` ``(4, 4)``, among those looking within 90° of its view direction (all of
    them if none does)."""
    distance = np.linalg.norm(poses_world_cam[:, :3, 3] - T_world_cam[:3, 3], axis=1)
    facing = poses_world_cam[:, :3, 2] @ T_world_cam[:3, 2] > 0
    if facing.any():
        distance = np.where(facing, distance, np.inf)
    return int(np.argmin(distance))


def scene_extent(scene: Scene, mesh: trimesh.Trimesh | None) -> float:
    """Diagonal in metres of the box around the keyframe centres and ``mesh`` (at least 1 m)."""
    points = np.stack([k.T_world_cam[:3, 3] for k in scene.keyframes])
    if mesh is not None:
        points = np.vstack([points, mesh.bounds])
    return max(float(np.linalg.norm(points.max(axis=0) - points.min(axis=0))), 1.0)
