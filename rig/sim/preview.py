"""A picture of what the simulator makes: one camera frame with a LiDAR sweep projected on it."""

from __future__ import annotations

import cv2
import numpy as np

from rig.sim.camera_sim import CameraSimulator, to_bgr8
from rig.sim.lidar_sim import simulate_scan
from rig.sim.simulate import SimRun
from rig.transforms import invert, transform_points

#: The preview is enlarged by this factor so that the points are visible.
SCALE = 2


def preview_image(run: SimRun, t_s: float | None = None) -> np.ndarray:
    """BGR image ``(SCALE·H, SCALE·W, 3)``: the frame at ``t_s`` (default mid-run) with the sweep
    starting then drawn on it, each point at its true world position, coloured by depth."""
    t = run.motion.duration_s / 2 if t_s is None else t_s
    camera = run.config.camera()
    T_world_cam = run.motion.poses(np.array([t]))[0]
    rgb, _ = CameraSimulator(camera).render(run.world, T_world_cam, t)
    image = cv2.resize(
        to_bgr8(rgb, np.random.default_rng(0)), None, fx=SCALE, fy=SCALE, interpolation=cv2.INTER_CUBIC
    )
    scan = simulate_scan(
        run.world, run.motion, run.lidar, run.T_cam_lidar, t, np.random.default_rng(run.config.seed)
    )
    points_cam = transform_points(invert(T_world_cam), scan.world_points)
    pixels = camera.project(points_cam)
    inside = camera.in_image(pixels)
    depth = points_cam[inside, 2]
    levels = np.clip(255 * (depth - depth.min()) / max(np.ptp(depth), 1e-6), 0, 255).astype(np.uint8)
    colours = cv2.applyColorMap(levels.reshape(-1, 1), cv2.COLORMAP_TURBO).reshape(-1, 3)
    for (u, v), c in zip(np.round((pixels[inside] + 0.5) * SCALE - 0.5).astype(int), colours, strict=True):
        cv2.circle(image, (int(u), int(v)), 1, tuple(int(x) for x in c), -1, lineType=cv2.LINE_AA)
    return image
