"""Held-out views during training: quick metrics (PSNR, SSIM, LiDAR depth error) and renders."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import torch

from rig.camera import CameraModel
from slam_bridge.scene import Keyframe, Scene
from splat.background_mask import scored_background_mask
from splat.config import TrainConfig
from splat.losses import dssim, psnr_of_mse
from splat.model import TriangleModel
from splat.views import View, load_views


def load_held_out_views(scene: Scene, keyframes: list[Keyframe], config: TrainConfig) -> list[View]:
    """The views of held-out ``keyframes`` as they are scored: with a trained background, it shows
    only where the LiDAR reached nothing (:func:`~splat.background_mask.scored_background_mask`)."""
    views = load_views(scene, keyframes, device=config.device)
    if config.background != "none":
        mark_background(views, scene.camera)
    return views


def mark_background(views: list[View], camera: CameraModel) -> None:
    """Set each view's ``background_mask`` to where its LiDAR reached nothing
    (:func:`~splat.background_mask.scored_background_mask`)."""
    focal = float(camera.K[1, 1])
    for view in views:
        view.background_mask = scored_background_mask(view.depth, focal, view.moving_mask)


@torch.no_grad()
def evaluate_views(model: TriangleModel, views: list[View], camera) -> dict[str, float]:
    """Mean test PSNR (dB) and SSIM (:func:`splat.losses.ssim_map`) of the renders through each view's
    colour map (for early stopping and curves — the reported numbers come from :mod:`eval`) and
    median |expected depth - LiDAR| (m) over LiDAR pixels with alpha > 0.5."""
    psnrs, ssims, depth_errors = [], [], []
    for view in views:
        out = model.render(camera, view.T_cam_world, background_mask=view.background_mask)
        rgb = view.scored_rgb(out.rgb)
        mse = float(((rgb - view.image) ** 2).mean())
        psnrs.append(psnr_of_mse(mse))
        ssims.append(1 - float(dssim(rgb, view.image)))
        if view.depth is not None:
            valid = (view.depth > 0) & (out.alpha > 0.5)
            depth_errors.append((out.expected_depth()[valid] - view.depth[valid]).abs().cpu())
    result = {"test_psnr": float(np.mean(psnrs)), "test_ssim": float(np.mean(ssims))}
    if depth_errors:
        result["test_depth_l1_m"] = float(torch.cat(depth_errors).median())
    return result


@torch.no_grad()
def write_renders(model: TriangleModel, views: list[View], camera, folder: Path) -> list[Path]:
    """Write ``folder/NAME.png`` renders of ``views`` (8-bit RGB); returns the paths."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for view in views:
        out = model.render(camera, view.T_cam_world, background_mask=view.background_mask)
        rgb = view.scored_rgb(out.rgb).cpu().numpy()
        path = folder / f"{view.name}.png"
        cv2.imwrite(str(path), cv2.cvtColor((rgb * 255 + 0.5).astype(np.uint8), cv2.COLOR_RGB2BGR))
        paths.append(path)
    return paths
