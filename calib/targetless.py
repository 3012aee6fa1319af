"""Targetless LiDAR→camera extrinsic refinement from a rough initial guess.

Coarse to fine, over one or more (image, cloud) pairs:

1. rotation grid search (±3°, then ±0.6°) maximising the alignment of LiDAR discontinuity points
   with image edges (a wide, robust basin: silhouettes and paint line up with edges);
2. rotation grid search (±0.3°) then a bounded 6-DoF Powell search maximising the mutual
   information between LiDAR intensity and image grey level (sharp near the optimum);
3. uncertainty: step 2's local search re-run on random halves of the points; the spread of the
   results is the reported standard deviation, and the verdict is ``poorly constrained`` when it
   (or the data) is too weak, with the reason. When the translation spreads too much (far
   structure only, typical of one outdoor frame), the guess's translation is kept with the joint
   fit's rotation: a fine stage must not drift away from a good start on noise.

The increment ``x`` is ``(rotation vector in degrees (3), translation in decimetres (3))``
(:func:`apply_increment`). The two units make the search space isotropic enough for the
derivative-free optimiser.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from scipy.ndimage import map_coordinates
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from calib.boards import to_gray
from calib.features import edge_field, lidar_edges
from calib.intervals import NORMAL_95
from rig.camera import CameraModel
from rig.errors import InputError
from rig.image_io import read_image
from rig.pointcloud_io import PointCloud, read_point_cloud
from rig.transforms import distance_and_angle, make_transform, transform_points

#: Images wider than this are downscaled to it; blur and edge widths below are in pixels at
#: this width and scale with the working image.
WORK_WIDTH = 960
#: (edge field sigma in working pixels, grid half-width in degrees, grid step in degrees).
EDGE_STAGES = ((8.0, 3.0, 0.5), (4.0, 0.6, 0.2))
MI_STAGE = (2.0, 0.3, 0.1)
MI_FINE_SIGMA = 1.0
MI_BINS = 32
#: Weights of the depth-edge and intensity-edge terms of the edge score.
EDGE_WEIGHTS = (0.3, 1.0)
#: Bounds of the local search around the grid result: degrees, and decimetres around the guess.
LOCAL_ROT_DEG = 0.5
LOCAL_TRANS_DM = 1.5
BOOTSTRAP_RUNS = 4
#: Verdict thresholds on the spread between data halves: half the accuracy we aim for, because
#: halves share the data's biases (on real data the spread underestimates the error).
MIN_POINTS = 1000
MIN_EDGE_POINTS = 50
MAX_ROT_STD_DEG = 0.1
MAX_TRANS_STD_M = 0.015


@dataclass(eq=False)
class ExtrinsicPair:
    """One camera image ``(H, W[, 3])`` uint8 and the LiDAR cloud taken at the same time."""

    image: np.ndarray
    cloud: PointCloud


@dataclass(eq=False)
class ExtrinsicResult:
    """A refined ``T_cam_lidar`` ``(4, 4)`` with its residuals, uncertainty and verdict."""

    T_cam_lidar: np.ndarray
    T_init: np.ndarray
    verdict: str
    reasons: list[str]
    rotation_std_deg: float
    translation_std_m: float
    mutual_information: dict[str, float]
    edge_score: dict[str, float]
    n_points: int
    n_edge_points: int
    method: str = "targetless (edges + mutual information)"
    extra: dict[str, Any] = field(default_factory=dict)
    #: Half-width of the 95 % interval in reported standard deviations: a normal quantile, or
    #: Student's t where the spread comes from a handful of groups (a jackknife).
    interval_95: float = NORMAL_95

    def change_from_init(self) -> tuple[float, float]:
        """Rotation (degrees) and translation (metres) between the result and the initial guess."""
        distance, angle = distance_and_angle(self.T_cam_lidar, self.T_init)
        return float(np.degrees(angle)), float(distance)

    def to_json(self) -> dict[str, Any]:
        """The fields ``lts calibrate extrinsic --json`` prints (and the ``quality:`` block holds)."""
        rot, trans = self.change_from_init()
        return {
            "T_cam_lidar": self.T_cam_lidar.tolist(),
            "verdict": self.verdict,
            "reasons": self.reasons,
            "method": self.method,
            "rotation_std_deg": self.rotation_std_deg,
            "translation_std_m": self.translation_std_m,
            "rotation_interval_95_deg": self.interval_95 * self.rotation_std_deg,
            "translation_interval_95_m": self.interval_95 * self.translation_std_m,
            "change_from_init_deg": rot,
            "change_from_init_m": trans,
            "mutual_information": self.mutual_information,
            "edge_score": self.edge_score,
            "n_points": self.n_points,
            "n_edge_points": self.n_edge_points,
            **self.extra,
        }


def read_pair(image_path: Path, cloud_path: Path) -> ExtrinsicPair:
    """An image file (colour, any format OpenCV reads) and a point-cloud file
    (:func:`rig.pointcloud_io.read_point_cloud`) as one pair."""
    return ExtrinsicPair(read_image(image_path), read_point_cloud(cloud_path))


def apply_increment(x: np.ndarray, T_init: np.ndarray) -> np.ndarray:
    """``T_init`` with its rotation turned by ``x[:3]`` (rotation vector, degrees, camera frame)
    and its translation moved by ``x[3:]`` (decimetres): the rotation pivots about the LiDAR
    origin, so rotation and translation stay decoupled."""
    R = Rotation.from_rotvec(np.radians(x[:3])).as_matrix() @ T_init[:3, :3]
    return make_transform(R, T_init[:3, 3] + np.asarray(x[3:]) / 10.0)


@dataclass(eq=False)
class _View:
    """Per-pair data prepared for the objectives: ``gray`` is the image undistorted and downscaled,
    ``K`` ``(3, 3)`` its pinhole camera matrix."""

    gray: np.ndarray
    K: np.ndarray
    points: np.ndarray
    intensity: np.ndarray
    depth_edges: np.ndarray
    intensity_edges: np.ndarray


def _sample(
    image: np.ndarray, K: np.ndarray, T: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear samples of an undistorted working ``image`` (camera matrix ``K``) at the pinhole
    projections of ``points`` ``(N, 3)``, and the mask ``(N,)`` of points that land in it."""
    p = transform_points(T, points)
    z = np.where(p[:, 2] > 1e-6, p[:, 2], np.nan)
    u = K[0, 0] * p[:, 0] / z + K[0, 2]
    v = K[1, 1] * p[:, 1] / z + K[1, 2]
    height, width = image.shape
    with np.errstate(invalid="ignore"):
        inside = (u >= -0.5) & (u < width - 0.5) & (v >= -0.5) & (v < height - 0.5)
    return map_coordinates(image, [v[inside], u[inside]], order=1, mode="nearest"), inside


def _edge_cost(x: np.ndarray, T_init: np.ndarray, views: list[_View], fields: list[np.ndarray]) -> float:
    T = apply_increment(x, T_init)
    total = 0.0
    for view, fld in zip(views, fields, strict=True):
        for weight, pts in zip(EDGE_WEIGHTS, (view.depth_edges, view.intensity_edges), strict=True):
            if len(pts):
                values, _ = _sample(fld, view.K, T, pts)
                total -= weight * values.sum() / len(pts)
    return total


def mutual_information(a: np.ndarray, b: np.ndarray, bins: int = MI_BINS) -> float:
    """Mutual information (nats) of two samples ``(N,)`` with values in [0, 256), from a
    Gaussian-smoothed joint histogram."""
    ia = np.clip((np.asarray(a) * (bins / 256.0)).astype(np.int64), 0, bins - 1)
    ib = np.clip((np.asarray(b) * (bins / 256.0)).astype(np.int64), 0, bins - 1)
    joint = np.bincount(ia * bins + ib, minlength=bins * bins).reshape(bins, bins)
    joint = cv2.GaussianBlur(joint.astype(np.float32), (0, 0), 1.0).astype(np.float64)
    if joint.sum() <= 0:
        return 0.0
    p = joint / joint.sum()
    outer = p.sum(axis=1, keepdims=True) @ p.sum(axis=0, keepdims=True)
    nz = p > 0
    return float(np.sum(p[nz] * np.log(p[nz] / outer[nz])))


def _mi_cost(
    x: np.ndarray,
    T_init: np.ndarray,
    views: list[_View],
    images: list[np.ndarray],
    subsets: list[np.ndarray] | None = None,
) -> float:
    T = apply_increment(x, T_init)
    lidar_values, image_values = [], []
    for i, (view, image) in enumerate(zip(views, images, strict=True)):
        pts, inten = view.points, view.intensity
        if subsets is not None:
            pts, inten = pts[subsets[i]], inten[subsets[i]]
        values, inside = _sample(image, view.K, T, pts)
        lidar_values.append(inten[inside])
        image_values.append(values)
    return -mutual_information(np.concatenate(lidar_values), np.concatenate(image_values))


def _grid_search(cost: Any, x: np.ndarray, half_deg: float, step_deg: float) -> np.ndarray:
    """Best rotation offset on a cubic grid around ``x`` (translation held)."""
    steps = np.arange(-half_deg, half_deg + 1e-9, step_deg)
    best_value, best_x = np.inf, x
    for offset in itertools.product(steps, repeat=3):
        candidate = x.copy()
        candidate[:3] += offset
        value = cost(candidate)
        if value < best_value:
            best_value, best_x = value, candidate
    return best_x


def _intensity_to_255(intensity: np.ndarray) -> np.ndarray:
    """Rescale intensities ``(N,)`` to [0, 255] by their 99th percentile (sensors differ in units)."""
    top = np.percentile(intensity, 99) if len(intensity) else 1.0
    return np.clip(intensity / max(float(top), 1e-9) * 255.0, 0, 255)


def working_pixels(width_at_work_width: float, image_width: int) -> float:
    """A blur or edge width given at :data:`WORK_WIDTH`, in pixels of a working image
    ``image_width`` wide (at least 0.5)."""
    return max(0.5, width_at_work_width * image_width / WORK_WIDTH)


def working_image(image: np.ndarray, camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """An image ``(H, W[, 3])`` uint8 in grey, undistorted and downscaled to at most
    :data:`WORK_WIDTH` wide, and the pinhole camera matrix ``(3, 3)`` of the result."""
    gray = to_gray(image)
    if gray.shape != (camera.height, camera.width):
        raise InputError(
            f"image is {gray.shape[1]}x{gray.shape[0]}, the camera model says {camera.width}x{camera.height}",
            field="image",
        )
    # Undistorted once, the image can be sampled with a plain pinhole projection (fast).
    undistorted = camera.undistort_image(gray)
    scale = min(1.0, WORK_WIDTH / camera.width)
    small = (
        cv2.resize(undistorted, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        if scale < 1
        else undistorted
    )
    K = camera.K.copy()
    K[:2] *= scale
    K[:2, 2] += 0.5 * scale - 0.5  # pixel centres at integers in both images
    return small, K


def _prepare(pair: ExtrinsicPair, camera: CameraModel, T_init: np.ndarray) -> _View:
    small, K = working_image(pair.image, camera)
    cloud = pair.cloud
    # Points that could land in the image near the initial guess (margin for the search range).
    margin = -0.1 * camera.width
    near = camera.in_image(camera.project(transform_points(T_init, cloud.points)), margin)
    edges = lidar_edges(cloud.points, cloud.intensity)

    def near_view(pts: np.ndarray) -> np.ndarray:
        return pts[camera.in_image(camera.project(transform_points(T_init, pts)), margin)]

    return _View(
        gray=small,
        K=K,
        points=cloud.points[near],
        intensity=_intensity_to_255(cloud.intensity[near]),
        depth_edges=near_view(edges.depth),
        intensity_edges=near_view(edges.intensity),
    )


def refine_extrinsic(
    pairs: Sequence[ExtrinsicPair], camera: CameraModel, T_init: np.ndarray, seed: int = 0
) -> ExtrinsicResult:
    """Refine ``T_cam_lidar`` from a rough guess ``T_init`` (within a few degrees and decimetres).

    Never raises on weak data: an empty scan or a view without structure gives the initial guess
    back with a ``poorly constrained`` verdict and the reason.
    """
    views = [_prepare(pair, camera, T_init) for pair in pairs]
    n_points = sum(len(v.points) for v in views)
    n_edges = sum(len(v.depth_edges) + len(v.intensity_edges) for v in views)
    reasons: list[str] = []
    if n_points < MIN_POINTS or n_edges < MIN_EDGE_POINTS:
        reasons.append(
            f"only {n_points} LiDAR points ({n_edges} edge points) project into the image near the "
            f"initial guess; need {MIN_POINTS} ({MIN_EDGE_POINTS})"
        )
        return ExtrinsicResult(
            T_init.copy(),
            T_init.copy(),
            "poorly constrained",
            reasons,
            np.inf,
            np.inf,
            {},
            {},
            n_points,
            n_edges,
        )

    x = np.zeros(6)
    edge_init = edge_final = 0.0
    for sigma, half, step in EDGE_STAGES:
        fields = [edge_field(v.gray, working_pixels(sigma, v.gray.shape[1])) for v in views]

        def edge_cost(y: np.ndarray, fields: list[np.ndarray] = fields) -> float:
            return _edge_cost(y, T_init, views, fields)

        if sigma == EDGE_STAGES[0][0]:
            edge_init = -float(edge_cost(np.zeros(6)))
        x = _grid_search(edge_cost, x, half, step)
        edge_final = -float(edge_cost(x))

    sigma, half, step = MI_STAGE
    blurred = [
        cv2.GaussianBlur(v.gray, (0, 0), working_pixels(sigma, v.gray.shape[1])).astype(np.float32)
        for v in views
    ]
    x = _grid_search(lambda y: _mi_cost(y, T_init, views, blurred), x, half, step)
    fine = [
        cv2.GaussianBlur(v.gray, (0, 0), working_pixels(MI_FINE_SIGMA, v.gray.shape[1])).astype(np.float32)
        for v in views
    ]
    bounds = [(xi - LOCAL_ROT_DEG, xi + LOCAL_ROT_DEG) for xi in x[:3]] + [
        (-LOCAL_TRANS_DM, LOCAL_TRANS_DM)
    ] * 3

    def local(subsets: list[np.ndarray] | None) -> np.ndarray:
        args = (T_init, views, fine, subsets)
        options = {"xtol": 1e-3, "ftol": 1e-7}
        return minimize(_mi_cost, x, args=args, method="Powell", bounds=bounds, options=options).x

    def spread(x_ref: np.ndarray) -> tuple[float, float]:
        """Rotation (degrees) and translation (metres) spread of the local search on data halves."""
        rng = np.random.default_rng(seed)
        runs = []
        for _ in range(BOOTSTRAP_RUNS):
            subsets = [rng.random(len(v.points)) < 0.5 for v in views]
            runs.append(local(subsets) - x_ref)
        rms = np.sqrt(np.mean(np.asarray(runs) ** 2, axis=0))
        return float(np.linalg.norm(rms[:3])), float(np.linalg.norm(rms[3:])) / 10.0

    x_best = local(None)
    rot_std, trans_std = spread(x_best)
    if trans_std > MAX_TRANS_STD_M:
        # The data cannot place the LiDAR: keep the guess's translation rather than drift with
        # the noise. The rotation stays the joint fit's: refitting it with the translation held
        # at the guess would turn it to make up for the guess's error on near structure (on the
        # PJLab pairs 0.29-0.53° off instead of 0.07-0.49°).
        reasons.append(
            f"translation not observable from these views (±{trans_std * 100:.1f} cm between halves "
            f"of the data, limit {MAX_TRANS_STD_M * 100:.1f} cm): kept the initial translation; add "
            "views with near structure"
        )
        x_best = np.r_[x_best[:3], 0.0, 0.0, 0.0]
    mi_init = -_mi_cost(np.zeros(6), T_init, views, fine)
    mi_final = -_mi_cost(x_best, T_init, views, fine)
    if mi_final <= mi_init:
        # A result the objective rates below the guess is no refinement: return the guess.
        reasons.append("mutual information did not improve on the initial guess: kept the guess")
        x_best, mi_final = np.zeros(6), mi_init
    if rot_std > MAX_ROT_STD_DEG:
        reasons.append(
            f"rotation varies by ±{rot_std:.2f}° between halves of the data (limit {MAX_ROT_STD_DEG}°)"
        )
    at_bound = np.isclose(np.abs(x_best[3:]), LOCAL_TRANS_DM, atol=1e-3).any()
    if at_bound:
        reasons.append(f"translation reached the search bound (±{LOCAL_TRANS_DM * 10:.0f} cm from the guess)")
    return ExtrinsicResult(
        T_cam_lidar=apply_increment(x_best, T_init),
        T_init=T_init.copy(),
        verdict="poorly constrained" if reasons else "ok",
        reasons=reasons,
        rotation_std_deg=rot_std,
        translation_std_m=trans_std,
        mutual_information={"init": mi_init, "final": mi_final},
        edge_score={"init": edge_init, "final": edge_final},
        n_points=n_points,
        n_edge_points=n_edges,
    )
