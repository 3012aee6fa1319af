"""Accumulated LiDAR points of a scene, from its keyframes' LiDAR depth images."""

from __future__ import annotations

import numpy as np

from slam_bridge.scene import Keyframe, Scene


def lidar_points(scene: Scene, keyframes: list[Keyframe]) -> np.ndarray:
    """World points ``(N, 3)`` back-projected from the LiDAR depth images of ``keyframes``
    (each image holds the deskewed scans around its keyframe, so neighbours overlap)."""
    chunks = []
    for keyframe in keyframes:
        depth = scene.depth(keyframe)
        v, u = np.nonzero(depth > 0)
        if len(u) == 0:
            continue
        z = depth[v, u].astype(np.float64)
        cam = scene.camera.unproject(np.column_stack([u, v]).astype(np.float64), 1.0) * z[:, None]
        T = keyframe.T_world_cam
        chunks.append(cam @ T[:3, :3].T + T[:3, 3])
    return np.concatenate(chunks) if chunks else np.zeros((0, 3))
