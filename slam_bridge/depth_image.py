"""Sparse LiDAR depth images: project points into a camera, z-buffer them, and remove points
that the camera cannot see although the LiDAR could (the baseline between the sensors lets
background points "shine through" gaps beside foreground objects)."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.ndimage import minimum_filter

from rig.camera import CameraModel
from rig.transforms import transform_points


def nearest_returns(
    points_cam: np.ndarray, camera: CameraModel, near_m: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """The z-buffer of camera-frame points ``(N, 3)``: each point lands on the pixel nearest its
    projection and the nearest point (smallest z beyond ``near_m``) wins. Returns the flat pixel
    indices ``(M,)`` (``row * W + col``, increasing) that got a point and the winning points'
    indices ``(M,)`` into ``points_cam``."""
    points = np.asarray(points_cam, dtype=np.float64)
    candidates = np.flatnonzero(points[:, 2] > near_m)
    pixels = camera.project(points[candidates])
    inside = camera.in_image(pixels)
    candidates = candidates[inside]
    cols = np.round(pixels[inside, 0]).astype(np.int64)
    rows = np.round(pixels[inside, 1]).astype(np.int64)
    flat = rows * camera.width + cols
    order = np.lexsort((points[candidates, 2], flat))  # by pixel, nearest first
    first = np.ones(len(order), dtype=bool)
    first[1:] = flat[order[1:]] != flat[order[:-1]]
    return flat[order[first]], candidates[order[first]]


#: A moving point masks the pixels within this fraction of the image width around it, which joins
#: the beams' hits on a vehicle into one region.
MOVING_MASK_RADIUS_FRACTION = 0.01
#: A moving object cut by the top of the LiDAR's field is masked up to this far above its returns
#: there (along the camera's up, -y): a lorry stands at most about 4.2 m tall, and a car's roof
#: LiDAR (1.73 m up on KITTI's) meets it with its rising top beam no lower than its own height. On a
#: creeping drive beside a lorry 4 m masked the sky above vehicles farther off and kept 0.8 dB less
#: of the static pixels (docs/outdoor.md, "A lorry above the LiDAR's field").
MOVING_MASK_ABOVE_M = 2.5


def moving_pixel_mask(
    points_cam: np.ndarray, camera: CameraModel, at_field_top: np.ndarray | None = None
) -> np.ndarray:
    """``(H, W)`` bool: the pixels within :data:`MOVING_MASK_RADIUS_FRACTION` of the image width
    of the projection of any camera-frame point ``(N, 3)`` (the points of moving objects), or of
    the pixel column from any point of ``at_field_top`` ``(M, 3)`` (those of them at the top of the
    LiDAR's field) up to the projection of a point :data:`MOVING_MASK_ABOVE_M` above it."""
    pixels, _ = nearest_returns(points_cam, camera)
    mask = np.zeros((camera.height, camera.width), dtype=np.uint8)
    mask.flat[pixels] = 1
    if at_field_top is not None and len(at_field_top):
        rows, cols = _columns_above(np.asarray(at_field_top, dtype=np.float64), camera)
        mask[rows, cols] = 1
    radius = max(1, round(MOVING_MASK_RADIUS_FRACTION * camera.width))
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    return cv2.dilate(mask, disk).astype(bool)


def _columns_above(points_cam: np.ndarray, camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns ``(P,)`` of the pixels from each point's pixel (in the image, in front of
    the camera) up its column to the row of the point :data:`MOVING_MASK_ABOVE_M` higher."""
    points = points_cam[points_cam[:, 2] > 0]
    pixels = camera.project(points)
    inside = camera.in_image(pixels)
    raised = points[inside] - np.array([0.0, MOVING_MASK_ABOVE_M, 0.0])
    cols = np.round(pixels[inside, 0]).astype(np.int64)
    bottom = np.round(pixels[inside, 1]).astype(np.int64)
    top = np.clip(np.round(camera.project(raised)[:, 1]).astype(np.int64), 0, bottom)
    lengths = bottom - top + 1
    starts = np.repeat(np.cumsum(lengths) - lengths, lengths)
    rows = np.repeat(top, lengths) + np.arange(int(lengths.sum())) - starts
    return rows, np.repeat(cols, lengths)


def zbuffer_depth(points_cam: np.ndarray, camera: CameraModel, near_m: float = 0.05) -> np.ndarray:
    """Depth image ``(H, W)`` float32 (z in metres, 0 = no return) of camera-frame points ``(N, 3)``
    (see :func:`nearest_returns`)."""
    pixels, winners = nearest_returns(points_cam, camera, near_m)
    depth = np.zeros(camera.height * camera.width, dtype=np.float32)
    depth[pixels] = np.asarray(points_cam, dtype=np.float64)[winners, 2]
    return depth.reshape(camera.height, camera.width)


def remove_occluded(
    depth: np.ndarray, window_px: int = 7, relative: float = 0.1, absolute_m: float = 0.1
) -> np.ndarray:
    """Drop returns ``(H, W)`` that lie clearly behind a nearer return within a ``window_px`` window.

    A return at depth ``d`` is kept when ``d <= d_min + max(absolute_m, relative * d_min)``, with
    ``d_min`` the nearest return in its window: sparse LiDAR leaves gaps through which farther
    surfaces appear beside a foreground object, and this local min-depth test removes them.
    """
    valid = depth > 0
    nearest = minimum_filter(np.where(valid, depth, np.inf), size=window_px, mode="nearest")
    keep = valid & (depth <= nearest + np.maximum(absolute_m, relative * nearest))
    return np.where(keep, depth, 0.0).astype(np.float32)


def visible_returns(
    points_cam: np.ndarray, camera: CameraModel, occlusion_window_px: int = 7
) -> tuple[np.ndarray, np.ndarray]:
    """The returns among camera-frame points ``(N, 3)`` that the camera sees: the z-buffer's
    winners (:func:`nearest_returns`) less those :func:`remove_occluded` drops (window 0: none).
    Returns flat pixel indices ``(M,)`` and the indices ``(M,)`` of their points."""
    pixels, winners = nearest_returns(points_cam, camera)
    if occlusion_window_px:
        depth = np.zeros(camera.height * camera.width, dtype=np.float32)
        depth[pixels] = np.asarray(points_cam, dtype=np.float64)[winners, 2]
        kept = remove_occluded(depth.reshape(camera.height, camera.width), occlusion_window_px).ravel()
        seen = kept[pixels] > 0
        pixels, winners = pixels[seen], winners[seen]
    return pixels, winners


def lidar_depth_image(
    points_lidar: np.ndarray,
    T_cam_lidar: np.ndarray,
    camera: CameraModel,
    occlusion_window_px: int | None = 7,
) -> np.ndarray:
    """Depth image ``(H, W)`` float32 of LiDAR points ``(N, 3)`` seen by ``camera`` at ``T_cam_lidar``
    ``(4, 4)``; ``occlusion_window_px=None`` skips the see-through removal."""
    depth = zbuffer_depth(transform_points(T_cam_lidar, points_lidar), camera)
    if occlusion_window_px:
        depth = remove_occluded(depth, occlusion_window_px)
    return depth
