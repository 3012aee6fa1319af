"""A tiny scene folder for training tests: a textured floor and back wall (a corner of a room),
rendered by the rasteriser itself from six cameras, with exact LiDAR points (on 30 % of the
pixels) and normal images and a coarse warm-start mesh of the same two planes."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import torch
import trimesh

from rig.transforms import make_transform
from slam_bridge.prepare_config import PrepareConfig
from slam_bridge.scene import LIDAR_DIR, Keyframe, write_scene_index
from splat.raster import render
from splat.raster.scenes import pinhole

CAMERA = pinhole(64, 48, fov_deg=80.0)
WALL_Y = 3.0  # the back wall is the plane y = 3 (world z up, floor z = 0)


def _grid(n: int, size: float, to_world) -> tuple[np.ndarray, np.ndarray]:
    """An n×n grid of squares (2 triangles each) mapped to the world by ``to_world(u, v)``."""
    u, v = np.meshgrid(np.linspace(0, size, n + 1), np.linspace(0, size, n + 1), indexing="ij")
    vertices = to_world(u.ravel(), v.ravel())
    faces = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = (
                i * (n + 1) + j,
                i * (n + 1) + j + 1,
                (i + 1) * (n + 1) + j,
                (i + 1) * (n + 1) + j + 1,
            )
            faces += [[a, c, b], [b, c, d]]
    return vertices, np.array(faces)


def corner_mesh(n: int = 12, size: float = 4.0) -> trimesh.Trimesh:
    """Floor ``z = 0`` over ``x in [-2, 2], y in [-1, 3]`` and back wall ``y = 3`` up to 4 m."""
    floor_v, floor_f = _grid(n, size, lambda u, v: np.column_stack([u - 2, v - 1, np.zeros_like(u)]))
    wall_v, wall_f = _grid(n, size, lambda u, v: np.column_stack([u - 2, np.full_like(u, WALL_Y), v]))
    return trimesh.Trimesh(
        np.vstack([floor_v, wall_v]), np.vstack([floor_f, wall_f + len(floor_v)]), process=False
    )


def camera_poses(count: int = 6, spread_m: float = 1.2, pitch_deg: float = 20.0) -> np.ndarray:
    """``(count, 4, 4)`` camera-to-world poses 1 m high along ``spread_m`` of x, looking along +y and
    ``pitch_deg`` down."""
    poses = []
    for i in range(count):
        yaw = np.radians(-15 + 30 * i / max(count - 1, 1))
        pitch = np.radians(pitch_deg)
        forward = np.array([np.sin(yaw) * np.cos(pitch), np.cos(yaw) * np.cos(pitch), -np.sin(pitch)])
        right = np.cross(forward, [0, 0, 1.0])
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        R = np.column_stack([right, down, forward])
        poses.append(make_transform(R, np.array([spread_m * (i / max(count - 1, 1) - 0.5), 0.0, 1.0])))
    return np.stack(poses)


def write_training_scene(
    root: Path, n_views: int = 6, seed: int = 0, spread_m: float = 1.2, pitch_deg: float = 20.0
) -> Path:
    """Write a scene folder (``lts prepare`` layout) at ``root`` seen from :func:`camera_poses`; the
    last view is the test view."""
    rng = np.random.default_rng(seed)
    truth = corner_mesh(16)
    tris = torch.as_tensor(np.asarray(truth.vertices)[np.asarray(truth.faces)], dtype=torch.float64)
    n = len(tris)
    # Smooth colours (a 1.5 m wave plus a little per-face noise): detail a coarse start can learn.
    centre = tris.mean(dim=1).numpy()
    wave = 0.5 + 0.35 * np.sin(
        2 * np.pi * (centre @ np.array([[1, 0.3, 0.5], [0.2, 1, -0.4], [0.6, -0.5, 1]])) / 1.5
    )
    face_colors = torch.as_tensor(np.clip(wave + rng.normal(0, 0.03, (n, 3)), 0, 1))
    for name in ("images", LIDAR_DIR, "normals"):
        (root / name).mkdir(parents=True, exist_ok=True)
    keyframes = []
    for i, pose in enumerate(camera_poses(n_views, spread_m, pitch_deg)):
        out = render(
            tris.reshape(-1, 3), torch.arange(3 * n).view(n, 3), face_colors.repeat_interleave(3, 0),
            torch.full((3 * n,), 1.0, dtype=torch.float64), 1e-3, CAMERA,
            torch.as_tensor(np.linalg.inv(pose)),
        )  # fmt: skip
        rgb = (out.rgb.clamp(0, 1).numpy() * 255 + 0.5).astype(np.uint8)
        name = f"{i:06d}"
        cv2.imwrite(str(root / "images" / f"{name}.png"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        alpha = out.alpha.numpy()
        depth = np.where(alpha > 0.5, out.accumulated_depth.numpy() / np.maximum(alpha, 1e-6), 0.0)
        v, u = np.nonzero((rng.random(depth.shape) < 0.3) & (depth > 0))  # returns on 30 % of the pixels
        points = CAMERA.unproject(np.column_stack([u, v]).astype(np.float64), depth[v, u])
        np.save(root / LIDAR_DIR / f"{name}.npy", points.astype(np.float32))
        normal = out.normal.numpy()
        normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-9)
        np.save(
            root / "normals" / f"{name}.npy", np.where(alpha[..., None] > 0.5, normal, 0).astype(np.float32)
        )
        split = "test" if i == n_views - 1 else "train"
        keyframes.append(Keyframe(name, 1_000_000_000 * (i + 1), pose, split))
    corner_mesh(8).export(root / "mesh.ply")
    # Exact depth has no see-through returns to remove.
    write_scene_index(root, CAMERA, keyframes, PrepareConfig(occlusion_window_px=0), {"kind": "test corner"})
    return root
