"""Snapping warm-start mesh vertices onto the LiDAR returns the keyframes recorded.

A SLAM mesh is often coarser and noisier than the LiDAR returns it came from (voxel maps, TSDF
smoothing, drift between map updates). Training moves vertices only slowly (their learning rate is
small, and zero at first, so that the photometric loss cannot tear the warm start apart), so a
vertex that starts 10 cm off mostly stays off. Here each vertex is moved onto the planes through
the LiDAR returns at its pixels in the keyframes that see it, along the scene's normal prior there
(from the SLAM mesh or the user's normal maps), and the results are averaged over the views.

Which views agree with a vertex is decided by a radius that adapts to the mesh: three robust
standard deviations (1.4826 × median) of all vertex-to-LiDAR depth residuals. A clean mesh gets a
small radius, so a vertex of a surface hidden behind another one in a view (its residual is the
gap between the two) is not pulled forward; a noisy mesh gets a large one. Vertices at pixels with
no LiDAR return (the floor a level LiDAR never sees) stay where they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from rig.transforms import invert, transform_points
from slam_bridge.scene import Keyframe, Scene


@dataclass(frozen=True)
class Snap:
    """Snapped vertices ``(V, 3)``, how many moved, and the agreement radius used (metres)."""

    vertices: np.ndarray
    n_snapped: int
    radius_m: float

    @property
    def reason(self) -> str:
        return (
            f"{self.n_snapped} of {len(self.vertices)} warm-start vertices snapped onto the LiDAR depth "
            f"(views within {100 * self.radius_m:.1f} cm of them)"
        )


@dataclass(frozen=True)
class _Observation:
    """One keyframe's LiDAR view of the vertices: ``vertex`` ``(M,)`` indices, where each one
    belongs by the LiDAR return at (or next to) its pixel ``(M, 3)``, and the depth residual
    (LiDAR − vertex) ``(M,)``."""

    vertex: np.ndarray
    point: np.ndarray
    residual: np.ndarray


def _observe(vertices: np.ndarray, scene: Scene, keyframe: Keyframe, max_pixels: float) -> _Observation:
    """The LiDAR return at each vertex's pixel (or the nearest one within ``max_pixels``)."""
    lidar = scene.lidar(keyframe)
    depth = lidar.depth()
    T = keyframe.T_world_cam
    cam = transform_points(invert(T), vertices)
    front = np.flatnonzero(cam[:, 2] > 0.1)
    pixels = scene.camera.project(cam[front])
    inside = scene.camera.in_image(pixels)
    front, pixels = front[inside], pixels[inside]
    u, v = np.round(pixels).astype(np.int64).T
    u, v = np.clip(u, 0, depth.shape[1] - 1), np.clip(v, 0, depth.shape[0] - 1)
    gap, (iy, ix) = ndimage.distance_transform_edt(depth <= 0, return_indices=True)
    ly, lx = iy[v, u], ix[v, u]
    index = lidar.point_index()[ly, lx]
    ok = (gap[v, u] <= max_pixels) & (index >= 0)
    front, ly, lx = front[ok], ly[ok], lx[ok]
    returns = lidar.points[index[ok]].astype(np.float64)
    normal = scene.normals(keyframe)[ly, lx].astype(np.float64)
    has_normal = np.linalg.norm(normal, axis=1) > 0.5
    # Along the normal prior onto the plane through the return: the vertex keeps its place along
    # the surface (the return may be a pixel or two away, far along a floor seen at a grazing
    # angle). Without a prior, onto the return itself.
    along = np.einsum("ij,ij->i", cam[front] - returns, normal)
    target = np.where(has_normal[:, None], cam[front] - along[:, None] * normal, returns)
    return _Observation(front, transform_points(T, target), returns[:, 2] - cam[front, 2])


def snap_to_lidar(
    vertices: np.ndarray,
    scene: Scene,
    keyframes: list[Keyframe],
    max_pixels: float = 2.0,
    radius_range_m: tuple[float, float] = (0.03, 0.5),
) -> Snap:
    """Move each vertex ``(V, 3)`` onto the planes through the LiDAR returns at its pixels in the
    ``keyframes`` whose depth agrees with it (averaged) (within the adaptive radius, clipped to
    ``radius_range_m``; the LiDAR pixel may be up to ``max_pixels`` from the vertex's)."""
    vertices = np.asarray(vertices, dtype=np.float64)
    seen = [_observe(vertices, scene, keyframe, max_pixels) for keyframe in keyframes]
    residual = np.concatenate([o.residual for o in seen]) if seen else np.zeros(0)
    plausible = np.abs(residual) < radius_range_m[1]
    if not plausible.any():
        return Snap(vertices, 0, 0.0)
    radius = float(np.clip(3.0 * 1.4826 * np.median(np.abs(residual[plausible])), *radius_range_m))
    total = np.zeros_like(vertices)
    count = np.zeros(len(vertices))
    for o in seen:
        agree = np.abs(o.residual) < radius
        np.add.at(total, o.vertex[agree], o.point[agree])
        np.add.at(count, o.vertex[agree], 1.0)
    snap = count > 0
    snapped = vertices.copy()
    snapped[snap] = total[snap] / count[snap, None]
    return Snap(snapped, int(snap.sum()), radius)
