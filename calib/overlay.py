"""Quality pictures: LiDAR points coloured by depth, projected into the image."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from rig.camera import CameraModel
from rig.errors import InputError
from rig.transforms import transform_points

#: Longest side of the written picture (each panel).
PANEL_MAX_SIDE = 1280


def draw_overlay(
    image: np.ndarray, camera: CameraModel, points: np.ndarray, T_cam_lidar: np.ndarray, label: str
) -> np.ndarray:
    """The image ``(H, W[, 3])`` with LiDAR points ``(N, 3)`` drawn as dots coloured by depth
    (near red → far blue, JET scale up to the 95th percentile), downscaled to PANEL_MAX_SIDE."""
    canvas = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image.copy()
    cam_points = transform_points(T_cam_lidar, points)
    pixels = camera.project(cam_points)
    inside = camera.in_image(pixels)
    scale = min(1.0, PANEL_MAX_SIDE / max(canvas.shape[:2]))
    canvas = cv2.resize(canvas, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    if inside.any():
        depth = cam_points[inside, 2]
        far = max(float(np.percentile(depth, 95)), 1e-6)
        levels = np.clip(255 - depth / far * 255, 0, 255).astype(np.uint8).reshape(-1, 1)
        colours = cv2.applyColorMap(levels, cv2.COLORMAP_JET).reshape(-1, 3)
        radius = max(1, round(2 * scale * max(canvas.shape[:2]) / 960))
        for (u, v), colour in zip(
            ((pixels[inside] + 0.5) * scale - 0.5).round().astype(int), colours, strict=True
        ):
            cv2.circle(canvas, (int(u), int(v)), radius, tuple(int(c) for c in colour), -1, cv2.LINE_AA)
    size = max(0.5, canvas.shape[1] / 1000)
    cv2.putText(
        canvas, label, (10, int(30 * size)), cv2.FONT_HERSHEY_SIMPLEX, size, (0, 0, 0), 4, cv2.LINE_AA
    )
    cv2.putText(
        canvas, label, (10, int(30 * size)), cv2.FONT_HERSHEY_SIMPLEX, size, (255, 255, 255), 1, cv2.LINE_AA
    )
    return canvas


def write_comparison(
    path: str | Path,
    image: np.ndarray,
    camera: CameraModel,
    points: np.ndarray,
    T_init: np.ndarray,
    T_result: np.ndarray,
) -> None:
    """Write a PNG with the initial guess (left) beside the result (right)."""
    left = draw_overlay(image, camera, points, T_init, "initial guess")
    right = draw_overlay(image, camera, points, T_result, "result")
    if not cv2.imwrite(str(path), np.hstack([left, right])):
        raise InputError("cannot write the overlay picture", path=path)
