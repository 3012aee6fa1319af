"""Accumulated LiDAR points of a scene: the returns its keyframes' cameras see, in the world."""

from __future__ import annotations

import numpy as np

from rig.transforms import transform_points
from slam_bridge.scene import Keyframe, Scene


def keyframe_lidar_points(scene: Scene, keyframes: list[Keyframe]) -> list[np.ndarray]:
    """World points ``(N_k, 3)`` of the LiDAR returns each of ``keyframes`` sees (one per pixel; each
    keyframe holds the deskewed scans around it, so neighbours overlap)."""
    return [transform_points(k.T_world_cam, scene.lidar(k).points) for k in keyframes]


def lidar_points(scene: Scene, keyframes: list[Keyframe]) -> np.ndarray:
    """:func:`keyframe_lidar_points` of ``keyframes`` together ``(N, 3)``."""
    chunks = keyframe_lidar_points(scene, keyframes)
    return np.concatenate(chunks) if chunks else np.zeros((0, 3))
