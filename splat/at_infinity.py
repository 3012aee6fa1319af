"""Camera-only cells the background explains: the images agree as well when the cell is at infinity.

The upward strips and the plane-sweep cells put camera-only triangles above the LiDAR's reach.
Where they stand in front of the sky (a strip continued past a roof, a cell on a roofline's edge),
the images say nothing about their depth: the sky is as uniform at 40 m as at infinity. Trained,
such a triangle turns opaque and paints the sky in the keyframes it was made from and the wrong
colour wherever the roof moves against it (the 8 s street: 2.6 % of the test pixels, 29 % of the
static pixels' squared error). So a cell is left to the background when the keyframes' colours
along its direction, as if it lay at infinity, agree with one another at least twice as well as
their colours at the cell itself: a facade shifts against the sky between keyframes (parallax),
the sky and far structure do not.
"""

from __future__ import annotations

import warnings

import cv2
import numpy as np

from rig.camera import CameraModel

#: A cell is left to the background when its colours at infinity spread at most this share of its
#: colours at its own depth.
SPREAD_RATIO = 0.5
#: Both hypotheses need this many keyframes that see the cell.
MIN_VIEWS = 3
#: Colours are read from the images blurred by a box this wide (pixels): a sample's noise, not a
#: cell's texture.
BLUR_PX = 3


def explained_at_infinity(
    centres: np.ndarray, camera: CameraModel, images: list[np.ndarray], poses_world_cam: np.ndarray
) -> np.ndarray:
    """``(N,)`` bool: cells (world ``centres`` ``(N, 3)``) whose keyframes' colours along their
    direction from the nearest keyframe that sees them (the cell at infinity) spread at most
    :data:`SPREAD_RATIO` of their colours at the centres themselves, over at least
    :data:`MIN_VIEWS` keyframes that see both (``camera`` at ``poses_world_cam`` ``(K, 4, 4)``,
    ``images`` ``(H, W, 3)`` uint8). The spread is the median over keyframes of each colour's mean
    absolute deviation from the median colour."""
    if not len(centres):
        return np.zeros(0, dtype=bool)
    blurred = [cv2.blur(image.astype(np.float32) / 255.0, (BLUR_PX, BLUR_PX)) for image in images]
    at_centre = np.stack([_colours(camera, (centres - T[:3, 3]) @ T[:3, :3], image)
                          for T, image in zip(poses_world_cam, blurred, strict=True)])  # fmt: skip
    seen = np.isfinite(at_centre[..., 0])  # (K, N)
    distance = np.linalg.norm(centres[None] - poses_world_cam[:, None, :3, 3], axis=2)
    nearest = np.where(seen, distance, np.inf).argmin(axis=0)
    directions = centres - poses_world_cam[nearest, :3, 3]
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    at_infinity = np.stack([_colours(camera, directions @ T[:3, :3], image)
                            for T, image in zip(poses_world_cam, blurred, strict=True)])  # fmt: skip
    both = seen & np.isfinite(at_infinity[..., 0])
    spread_centre, spread_infinity = _spread(at_centre, both), _spread(at_infinity, both)
    return (both.sum(axis=0) >= MIN_VIEWS) & (spread_infinity <= SPREAD_RATIO * spread_centre)


def _colours(camera: CameraModel, points_cam: np.ndarray, image: np.ndarray) -> np.ndarray:
    """``(N, 3)`` colours of ``image`` at camera-frame ``points_cam`` ``(N, 3)`` (NaN where behind the
    camera or outside the image)."""
    colours = np.full((len(points_cam), 3), np.nan, dtype=np.float32)
    front = points_cam[:, 2] > 1e-3
    uv = np.rint(camera.project(points_cam[front])).astype(np.int64)
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < camera.width) & (uv[:, 1] >= 0) & (uv[:, 1] < camera.height)
    index = np.flatnonzero(front)[inside]
    colours[index] = image[uv[inside, 1], uv[inside, 0]]
    return colours


def _spread(colours: np.ndarray, used: np.ndarray) -> np.ndarray:
    """``(N,)``: the median over keyframes of the mean absolute deviation of ``colours``
    ``(K, N, 3)`` from their median colour, over the keyframes ``used`` ``(K, N)`` (NaN: none)."""
    kept = np.where(used[..., None], colours, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # cells no keyframe sees in both ways
        median = np.nanmedian(kept, axis=0)
        return np.nanmedian(np.abs(kept - median[None]).mean(axis=-1), axis=0)
