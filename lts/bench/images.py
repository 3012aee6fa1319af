"""``lts bench images``: how closely any render of a static scene can match a virtual-rig preset's
test images, whatever the training: the ceiling of image fidelity on that preset.

Two things make the images disagree with a static scene, each measured on its own at the test
views of a keyframe split like ``lts prepare``'s (one keyframe per ``interval_s``, every
``test_every``-th held out):

- **The texture's level of detail.** The simulator picks each pixel's mip level from its
  footprint on the surface, so a point seen from near and far takes different colours. A static
  colour per surface point, fitted to the training views by least squares, is the mean of the
  colours the training views that see the point give it; that mean is compared with the test
  view's own colour, at the exact geometry.
- **The undistortion.** ``lts prepare`` resamples each recorded (distorted) image bilinearly into
  the undistorted camera the rasteriser renders. The test image made so is compared with the
  simulator's own render in the undistorted camera at the same pose, blurred by the Gaussian that
  fits best (a smooth model can learn a blur, not each view's resampling).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np

from rig.errors import InputError
from rig.sim.camera_sim import CameraSimulator, pixel_footprint, to_bgr8
from rig.sim.config import SimConfig
from rig.sim.simulate import SimRun, prepare
from slam_bridge.keyframe_selection import make_keyframes
from slam_bridge.scene import Keyframe

#: Gaussian blurs (pixels) tried on the undistorted camera's render; 0: none.
BLUR_SIGMAS_PX = (0.0, 0.3, 0.5, 0.7, 0.9)
#: Pixels this close to the border are left out of the undistortion's comparison (the blur's reach).
BORDER_PX = 5


def keyframe_split(run: SimRun, interval_s: float, test_every: int) -> tuple[list[Keyframe], list[Keyframe]]:
    """Training and test keyframes of ``run`` (stamps in ns of its motion's seconds, true poses):
    one per ``interval_s`` from half an interval in, held out as ``lts prepare`` holds them out
    (:func:`~slam_bridge.keyframe_selection.make_keyframes`)."""
    times = np.arange(interval_s / 2, run.motion.duration_s - 1e-9, interval_s)
    keyframes = make_keyframes(np.round(times * 1e9).astype(np.int64), run.motion.poses(times), test_every)
    return [k for k in keyframes if k.split == "train"], [k for k in keyframes if k.split == "test"]


def _seconds(keyframe: Keyframe) -> float:
    """The keyframe's time on the run's motion (s)."""
    return keyframe.t_ns * 1e-9


def _quantised(rgb: np.ndarray) -> np.ndarray:
    """RGB in [0, 1] as an 8-bit image stores it (same shape, float)."""
    return np.round(np.clip(rgb, 0.0, 1.0) * 255.0) / 255.0


def static_colour_errors(run: SimRun, test: list[Keyframe], train: list[Keyframe]) -> tuple[float, int]:
    """Sum of squared errors and the number of values: each test pixel's colour against the mean of
    the colours the training views that see its surface point give it (pixels no training view
    sees are left out)."""
    camera_model = run.config.camera()
    camera = CameraSimulator(camera_model)
    appearance = run.world.appearance
    squared, count = 0.0, 0
    for view in test:
        hits, directions = camera.cast(run.world, view.T_world_cam, _seconds(view))
        hits, directions = hits.subset(hits.hit), directions[hits.hit]
        footprint = pixel_footprint(hits.normal, directions, hits.distance, camera.pixel_angle)
        total, seen_by = np.zeros((len(hits.points), 3)), np.zeros(len(hits.points))
        for other in train:
            T = other.T_world_cam
            in_camera = (hits.points - T[:3, 3]) @ T[:3, :3]
            ahead = np.flatnonzero(in_camera[:, 2] > 0.05)
            ahead = ahead[camera_model.in_image(camera_model.project(in_camera[ahead]))]
            offsets = hits.points[ahead] - T[:3, 3]
            distance = np.linalg.norm(offsets, axis=1)
            directions = offsets / distance[:, None]
            first = run.world.raycaster.cast(T[:3, 3], directions, _seconds(other))
            visible = first.hit & (np.abs(first.distance - distance) < 0.01 + 0.002 * distance)
            rows = ahead[visible]
            seen = hits.subset(rows)
            footprint_there = pixel_footprint(
                seen.normal, directions[visible], distance[visible], camera.pixel_angle
            )
            total[rows] += appearance.colour(seen, footprint_there)
            seen_by[rows] += 1
        kept = seen_by > 0
        mean = total[kept] / seen_by[kept, None]
        error = _quantised(mean) - _quantised(appearance.colour(hits.subset(kept), footprint[kept]))
        squared += float(np.sum(error**2))
        count += error.size
    return squared, count


def undistortion_errors(run: SimRun, test: list[Keyframe]) -> dict[float, tuple[float, int]]:
    """Per blur of :data:`BLUR_SIGMAS_PX`: sum of squared errors and the number of values of the
    recorded test images undistorted as ``lts prepare`` does against the simulator's render in the
    undistorted camera, so blurred."""
    camera_model = run.config.camera()
    target = camera_model.undistorted()
    recorded_camera, ideal_camera = CameraSimulator(camera_model), CameraSimulator(target)
    no_noise = np.random.default_rng(0)  # to_bgr8 draws nothing without noise or jitter
    sums = {sigma: (0.0, 0) for sigma in BLUR_SIGMAS_PX}
    inner = (slice(BORDER_PX, -BORDER_PX), slice(BORDER_PX, -BORDER_PX))
    for view in test:
        T, t_s = view.T_world_cam, _seconds(view)
        recorded, _ = recorded_camera.render(run.world, T, t_s)
        undistorted = camera_model.undistort_image(to_bgr8(recorded, no_noise), target)[..., ::-1] / 255.0
        ideal, _ = ideal_camera.render(run.world, T, t_s)
        for sigma in BLUR_SIGMAS_PX:
            blurred = cv2.GaussianBlur(ideal, (0, 0), sigma) if sigma > 0 else ideal
            error = (undistorted - _quantised(blurred))[inner]
            squared, count = sums[sigma]
            sums[sigma] = (squared + float(np.sum(error**2)), count + error.size)
    return sums


def psnr(squared: float, count: int) -> float:
    """PSNR (dB, peak 1) of a sum of squared errors over ``count`` values (inf when it is zero)."""
    return math.inf if squared == 0 else -10.0 * math.log10(squared / count)


def bench_images(
    config: SimConfig, interval_s: float, test_every: int, log: Callable[[str], None] = print
) -> dict[str, Any]:
    """Both ceilings on ``config``'s test views, and the two together (their squared errors added):
    the JSON table of ``lts bench images``."""
    run = prepare(config)
    train, test = keyframe_split(run, interval_s, test_every)
    if not test or not train:
        raise InputError(
            f"{run.motion.duration_s:.1f} s at one keyframe per {interval_s} s, one in {test_every} held "
            f"out, gives {len(train)} training and {len(test)} test keyframes; need both",
            field="--keyframe-interval",
        )
    log(f"{config.preset}: {len(train)} training and {len(test)} test keyframes")
    static = static_colour_errors(run, test, train)
    log(f"  a static colour per surface point: {psnr(*static):.2f} dB")
    undistortion = {sigma: psnr(*sums) for sigma, sums in undistortion_errors(run, test).items()}
    best = max(undistortion, key=lambda sigma: undistortion[sigma])
    log(f"  undistorted test images against the render: {undistortion[best]:.2f} dB (blur {best} px)")
    # Mean squared errors add for independent sources: 10^(-a/10) + 10^(-b/10).
    combined = -10.0 * math.log10(10 ** (-psnr(*static) / 10) + 10 ** (-undistortion[best] / 10))
    log(f"  both: {combined:.2f} dB")
    camera = run.config.camera()
    return {
        "preset": config.preset,
        "seed": config.seed,
        "image_size": [camera.width, camera.height],
        "train_views": len(train),
        "test_views": len(test),
        "static_colour_psnr": psnr(*static),
        "undistortion_psnr_by_blur_px": {str(sigma): value for sigma, value in undistortion.items()},
        "undistortion_psnr": undistortion[best],
        "undistortion_blur_px": best,
        "ceiling_psnr": combined,
    }
