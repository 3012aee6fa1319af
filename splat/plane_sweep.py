"""Dense camera-only geometry above the LiDAR's reach: plane-sweep stereo between keyframes.

The upward extension (:mod:`splat.upward_extension`) continues upright surfaces the LiDAR touched;
what it never touched (an overpass's face, tree crowns, the upper floors of a building set back
behind a lower one) had only the sparse points' seeds and was otherwise left to the background,
which then painted structure from every viewpoint alike. Here each reference keyframe's pixels
above its topmost LiDAR returns get a depth by sweeping fronto-parallel planes (uniform in inverse
depth) and scoring each against the nearest keyframes before and after it (far enough apart to see
parallax) by zero-mean normalised cross-correlation over a window: insensitive to the images'
gains. A depth is kept only where the window has texture, the correlation is high, its peak is
clearly unique along the sweep and inside it (sky, far structure beyond the sweep and pixels near
the epipole of a forward drive have no such peak), it does not lie where a window may have taken a
nearer surface's depth (beside a depth edge, under the sky) and another reference keyframe finds
the same surface. Each kept pixel of a coarse grid becomes a square cell facing its keyframe, as
wide as the grid step there; cells the LiDAR explains or sees through are dropped, as are cells on
pixels of moving objects.

Written by hand: OpenCV's stereo matchers need rectified pairs, which a forward-moving camera
(epipole inside the image) cannot give, and the multi-view stereo of COLMAP needs CUDA.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import torch
from scipy.ndimage import binary_dilation
from scipy.spatial import cKDTree

from rig.camera import CameraModel
from splat.background_mask import above_lidar
from splat.camera_only import one_per_grid_square, quad_triangles, seen_through, unexplained_points
from splat.upright_planes import UprightPlanes, snap_to_planes

#: Depth hypotheses of the sweep, uniform in inverse depth between these (m).
SWEEP_PLANES = 96
SWEEP_NEAR_M = 3.0
SWEEP_FAR_M = 80.0
#: The correlation window (pixels, odd) and the grey-level spread below which it has no texture.
WINDOW_PX = 7
MIN_TEXTURE = 0.005
#: A depth is kept where the mean correlation over the source keyframes reaches MIN_NCC and every
#: hypothesis more than UNIQUE_PLANES planes from the best scores at most best - UNIQUE_MARGIN.
MIN_NCC = 0.8
UNIQUE_PLANES = 3
UNIQUE_MARGIN = 0.1
#: Source keyframes lie at least this far from the reference (m): enough parallax at tens of metres.
MIN_BASELINE_M = 1.5
#: One cell per this many pixels (square) of the reference keyframe.
CELL_PX = 8
#: A depth another reference keyframe agrees with lies within this fraction of it.
AGREE_FRACTION = 0.05
#: A correlation window that straddles a depth edge takes the nearer, textured side's depth
#: (foreground fattening): depths within this many pixels of a jump between neighbours, or this
#: many rows below a blank pixel without a depth (the sky over a roofline), are left out.
FATTENING_PX = WINDOW_PX // 2


@dataclass(frozen=True)
class SweptCells:
    """Two triangles per cell ``(2C, 3, 3)`` and their colours ``(2C, 3, 3)`` in [0, 1] where plane-sweep
    stereo found a surface above the LiDAR's reach; ``n_matched`` depths before the checks between
    keyframes, ``n_references`` keyframes swept, ``n_snapped`` cells moved onto an upright surface
    the LiDAR touched (:mod:`splat.upright_planes`)."""

    triangles: np.ndarray
    colors: np.ndarray
    n_matched: int
    n_references: int
    n_snapped: int = 0

    @property
    def reason(self) -> str:
        if self.n_references == 0:
            return (
                "no camera-only cells from plane-sweep stereo: no keyframe sees above the LiDAR's reach "
                f"with others at least {MIN_BASELINE_M} m from it"
            )
        return (
            f"{len(self.triangles) // 2} camera-only cells from plane-sweep stereo above the LiDAR's reach "
            f"({self.n_matched} confident depths, one per {CELL_PX} x {CELL_PX} pixels, in "
            f"{self.n_references} keyframes; "
            "kept where another keyframe agrees and no LiDAR return explains or sees through them; "
            f"{self.n_snapped} moved onto the plane of an upright surface the LiDAR touched below them)"
        )


def _grey(image: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY).astype(np.float32) / 255.0


def _box(image: np.ndarray) -> np.ndarray:
    return cv2.blur(image, (WINDOW_PX, WINDOW_PX), borderType=cv2.BORDER_REFLECT)


def _window_stats(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mean and variance ``(H, W)`` of ``image`` over each pixel's :data:`WINDOW_PX` window."""
    mean = _box(image)
    return mean, np.maximum(_box(image * image) - mean * mean, 0.0)


def _ncc(band: np.ndarray, mean: np.ndarray, variance: np.ndarray, warped: np.ndarray) -> np.ndarray:
    """Zero-mean normalised cross-correlation ``(R, W)`` over :data:`WINDOW_PX` windows of ``band``
    (with its window ``mean`` and ``variance``) and a source image ``warped`` onto it (NaN outside
    the source); -1 where a window reaches outside the source."""
    inside = np.isfinite(warped)
    warped = np.where(inside, warped, 0.0).astype(np.float32)
    mean_w = _box(warped)
    covariance = _box(band * warped) - mean * mean_w
    variance_w = np.maximum(_box(warped * warped) - mean_w * mean_w, 1e-8)
    ncc = covariance / np.sqrt(np.maximum(variance, 1e-8) * variance_w)
    return np.where(_box(inside.astype(np.float32)) > 0.999, ncc, -1.0)


def _sources(centres: np.ndarray, reference: int) -> list[int]:
    """The nearest keyframes before and after ``reference`` (by index) at least
    :data:`MIN_BASELINE_M` from it, of camera ``centres`` ``(K, 3)``."""
    distance = np.linalg.norm(centres - centres[reference], axis=1)
    far = distance >= MIN_BASELINE_M
    before = [i for i in range(reference - 1, -1, -1) if far[i]][:1]
    after = [i for i in range(reference + 1, len(centres)) if far[i]][:1]
    return before + after


def sweep_depth(
    camera: CameraModel,
    reference: tuple[np.ndarray, np.ndarray],
    sources: list[tuple[np.ndarray, np.ndarray]],
    rows: int,
) -> np.ndarray:
    """Depth ``(rows, W)`` (m, NaN where not confident) of the top ``rows`` image rows of the
    ``reference`` keyframe (grey image ``(H, W)`` float32 in [0, 1], ``T_world_cam`` ``(4, 4)``)
    by plane-sweep stereo against ``sources`` (the same pairs)."""
    grey, T_world_ref = reference
    width = camera.width
    band = grey[:rows]
    mean, variance = _window_stats(band)
    textured = variance >= MIN_TEXTURE**2
    K = camera.K
    inverse = np.linspace(1.0 / SWEEP_FAR_M, 1.0 / SWEEP_NEAR_M, SWEEP_PLANES)
    score = np.full((SWEEP_PLANES, rows, width), -1.0, dtype=np.float32)
    for source_grey, T_world_src in sources:
        T = np.linalg.inv(T_world_src) @ T_world_ref
        for plane, w in enumerate(inverse):
            # The plane z = 1 / w of the reference maps into the source by K (R + t n^T w) K^-1.
            H = K @ (T[:3, :3] + np.outer(T[:3, 3], [0.0, 0.0, w])) @ np.linalg.inv(K)
            warped = cv2.warpPerspective(
                source_grey, H, (width, rows), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan,
            )  # fmt: skip
            ncc = _ncc(band, mean, variance, warped)
            # The mean over sources; a source that does not see the pixel counts as no match.
            score[plane] += (ncc + 1.0) / len(sources)
    best = np.argmax(score, axis=0)
    best_score = np.take_along_axis(score, best[None], axis=0)[0]
    planes = np.arange(SWEEP_PLANES)[:, None, None]
    away = np.abs(planes - best[None]) > UNIQUE_PLANES
    rival = np.where(away, score, -np.inf).max(axis=0)
    confident = (
        textured
        & (best_score >= MIN_NCC)
        & (rival <= best_score - UNIQUE_MARGIN)
        & (best > 0)
        & (best < SWEEP_PLANES - 1)
    )
    w = inverse[best] + _peak_shift(score, best) * (inverse[1] - inverse[0])
    return np.where(confident, 1.0 / w, np.nan).astype(np.float32)


def _peak_shift(score: np.ndarray, best: np.ndarray) -> np.ndarray:
    """Where between samples the peak of ``score`` ``(S, R, W)`` lies ``(R, W)``, in samples from
    ``best`` ``(R, W)``: the vertex of the parabola through it and its neighbours, within +-1/2."""
    inner = np.clip(best, 1, len(score) - 2)
    centre, before, after = (np.take_along_axis(score, (inner + d)[None], axis=0)[0] for d in (0, -1, 1))
    curvature = before - 2 * centre + after
    shift = np.where(curvature < 0, 0.5 * (before - after) / np.minimum(curvature, -1e-6), 0.0)
    return np.where(best == inner, np.clip(shift, -0.5, 0.5), 0.0)


def _cell_quads(
    camera: CameraModel, T_world_cam: np.ndarray, pixels: np.ndarray, depth: np.ndarray
) -> np.ndarray:
    """World squares ``(N, 4, 3)`` facing the camera at ``T_world_cam`` ``(4, 4)``: each covers the
    :data:`CELL_PX` × :data:`CELL_PX` pixels around ``pixels`` ``(N, 2)`` (u, v) at ``depth`` ``(N,)``.
    (Tilted into the plane of their neighbours, the cells on the street's facades lie no closer to the
    truth: their depth's error dominates.)"""
    half = CELL_PX / 2
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    uv = (pixels[:, None, :] + corners[None]).reshape(-1, 2)
    points = camera.unproject(uv, np.repeat(depth, len(corners))).reshape(len(pixels), len(corners), 3)
    return points @ T_world_cam[:3, :3].T + T_world_cam[:3, 3]


def keyframe_sweeps(
    camera: CameraModel,
    images: list[np.ndarray],
    poses_world_cam: np.ndarray,
    depths: list[np.ndarray],
    moving: list[np.ndarray | None],
) -> list[np.ndarray | None]:
    """Each keyframe's :func:`sweep_depth` ``(H, W)`` (m; NaN where not confident, below the LiDAR's
    reach, on moving pixels and where :func:`without_fattening` doubts it), or None where there is
    nothing above the LiDAR's reach or no other keyframe :data:`MIN_BASELINE_M` away: keyframes
    with RGB ``images`` ``(H, W, 3)`` uint8 at ``poses_world_cam`` ``(K, 4, 4)``, LiDAR depth
    images ``depths`` ``(H, W)`` (0 = no return) and masks of moving pixels ``moving``. ``camera``
    must be an undistorted pinhole (a scene's camera is); for any other, every entry is None."""
    if camera.model != "pinhole" or np.any(camera.dist):
        return [None] * len(images)
    greys = [_grey(image) for image in images]
    centres = poses_world_cam[:, :3, 3]
    sweeps: list[np.ndarray | None] = []
    for reference, (T_world_cam, depth) in enumerate(zip(poses_world_cam, depths, strict=True)):
        above = above_lidar(torch.as_tensor(depth)).numpy()
        if moving[reference] is not None:
            above &= ~moving[reference]
        sources = _sources(centres, reference)
        if not above.any() or not sources:
            sweeps.append(None)
            continue
        rows = int(np.flatnonzero(above.any(axis=1)).max()) + 1
        others = [(greys[i], poses_world_cam[i]) for i in sources]
        swept = np.full(depth.shape, np.nan, dtype=np.float32)
        swept[:rows] = sweep_depth(camera, (greys[reference], T_world_cam), others, rows)
        sweeps.append(without_fattening(np.where(above, swept, np.nan), greys[reference]))
    return sweeps


def without_fattening(depth: np.ndarray, grey: np.ndarray) -> np.ndarray:
    """``depth`` ``(H, W)`` (m, NaN where none) of the grey image ``grey`` ``(H, W)`` in [0, 1] without
    the depths a window may have taken from a nearer surface beside them: within
    :data:`FATTENING_PX` pixels of a jump of more than :data:`AGREE_FRACTION` (in log depth) between
    two neighbours that both have one, or up to :data:`FATTENING_PX` rows under a pixel without a
    depth whose window has no texture (the sky: the band above a roofline whose windows reach the
    roof takes its depth). On the 20 s street a quarter of the swept depths within 4 px of a depth
    edge or the sky lay over 15 % too near, and 3 % of all of them on the sky."""
    known = np.isfinite(depth)
    log_depth = np.log(np.where(known, depth, 1.0))
    # Pairs of neighbours that both have a depth and differ by more than AGREE_FRACTION: both ends.
    across = known[:, 1:] & known[:, :-1] & (np.abs(np.diff(log_depth, axis=1)) > AGREE_FRACTION)
    down = known[1:] & known[:-1] & (np.abs(np.diff(log_depth, axis=0)) > AGREE_FRACTION)
    jump = np.zeros_like(known)
    jump[:, 1:] |= across
    jump[:, :-1] |= across
    jump[1:] |= down
    jump[:-1] |= down
    doubtful = binary_dilation(jump, iterations=FATTENING_PX)
    blank = ~known & (_window_stats(grey)[1] < MIN_TEXTURE**2)
    for rows in range(1, FATTENING_PX + 1):
        doubtful[rows:] |= blank[:-rows]
    return np.where(doubtful, np.nan, depth)


def swept_cells(
    camera: CameraModel,
    images: list[np.ndarray],
    poses_world_cam: np.ndarray,
    depths: list[np.ndarray],
    sweeps: list[np.ndarray | None],
    known: np.ndarray,
    planes: UprightPlanes | None = None,
) -> SweptCells:
    """Camera-only cells where the keyframes' :func:`keyframe_sweeps` ``sweeps`` (RGB ``images``
    ``(H, W, 3)`` uint8 at ``poses_world_cam`` ``(K, 4, 4)``, LiDAR depth images ``depths``
    ``(H, W)``, 0 = no return) found a surface that another keyframe agrees with, that none of the
    ``known`` points ``(M, 3)`` (LiDAR returns, cells already made) explains
    (:func:`splat.camera_only.unexplained_points`) and that the LiDAR does not see through; each
    moved onto the nearest of the upright ``planes`` within :data:`AGREE_FRACTION` of its depth
    (:func:`splat.upright_planes.snap_to_planes`), when given."""
    empty = SweptCells(np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), 0, 0)
    centres = poses_world_cam[:, :3, 3]
    points, quads, colors, owner = [], [], [], []
    n_references = 0
    for reference, (T_world_cam, swept) in enumerate(zip(poses_world_cam, sweeps, strict=True)):
        if swept is None:
            continue
        n_references += 1
        v, u = np.mgrid[CELL_PX // 2 : camera.height : CELL_PX, CELL_PX // 2 : camera.width : CELL_PX]
        z = swept[v, u]
        keep = np.isfinite(z)
        if not keep.any():
            continue
        pixels = np.stack([u[keep], v[keep]], axis=1).astype(np.float64)
        cell = _cell_quads(camera, T_world_cam, pixels, z[keep].astype(np.float64))
        quads.append(cell)
        points.append(cell.mean(axis=1))
        mean_rgb = cv2.blur(images[reference], (CELL_PX, CELL_PX))[v[keep], u[keep]] / 255.0
        colors.append(mean_rgb)
        owner.append(np.full(int(keep.sum()), reference))
    if not points:
        return empty
    points, quads, colors, owner = map(np.concatenate, (points, quads, colors, owner))
    n_matched = len(points)
    depth = np.linalg.norm(points - centres[owner], axis=1)
    neighbours = cKDTree(points).query_ball_point(points, AGREE_FRACTION * depth)
    agreed = np.array([np.any(owner[list(near)] != own) for near, own in zip(neighbours, owner, strict=True)])
    keep = agreed & unexplained_points(points, known, centres)
    keep[keep] = ~seen_through(points[keep], camera, poses_world_cam, depths)
    points, quads, colors, owner = points[keep], quads[keep], colors[keep], owner[keep]
    snapped = np.zeros(len(points), dtype=bool)
    if planes is not None:
        quads, snapped = snap_to_planes(quads, centres[owner], planes, AGREE_FRACTION)
        points = quads.mean(axis=1)
    if len(points):
        side = np.linalg.norm(quads[:, 1] - quads[:, 0], axis=1)
        first = one_per_grid_square(points, float(np.median(side)))
        quads, colors, snapped = quads[first], colors[first], snapped[first]
    rgb = np.repeat(np.concatenate([colors, colors])[:, None, :], 3, axis=1)
    return SweptCells(quad_triangles(quads), rgb, n_matched, n_references, int(snapped.sum()))
