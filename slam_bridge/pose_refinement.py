"""Keyframe pose refinement anchored on the LiDAR mesh (``lts prepare --refine-poses``).

A plain bundle adjustment lets points and poses drift together: short, outward-looking robot
baselines leave depth and a common rotation barely observed, and on the virtual-rig room it moved
poses by up to 47 cm. Here the scene points come from the LiDAR and stay fixed; only camera poses
move, and only where held-out matches confirm it:

1. **Anchors**: a verified SIFT match between keyframes *i* and *j* gives *j* a 2D–3D
   correspondence whose 3D point is where *i*'s ray through its keypoint meets the SLAM mesh
   (metric, from the LiDAR).
2. **Resection**: each keyframe's pose is refined against its anchors with pycolmap's
   ``refine_absolute_pose`` (intrinsics fixed, Cauchy loss of 1 px), keyframes in time order; the
   anchors a keyframe casts are re-cast as soon as its pose changes (Gauss–Seidel), for a few rounds.
3. **Slow errors from the LiDAR**: anchors move with the keyframe that casts them, so an error
   that neighbouring keyframes share (all shifted along the wall they look at) is barely seen by
   the images and drifts over the rounds. The slowly varying part of ``LiDAR − refined`` is
   therefore given back: a Gaussian over time (σ = :attr:`RefineConfig.smoothing_s`) smooths the
   difference, which is added to the refined poses (a complementary filter: images correct what
   changes from keyframe to keyframe, the LiDAR trajectory the rest).
4. **Guard**: every :attr:`RefineConfig.holdout_every`-th match is left out of 1–3 and judges the
   result. A keyframe keeps its LiDAR pose unless its median held-out reprojection error drops by
   at least :attr:`RefineConfig.min_gain` and it moved less than the trust bounds; if the held-out
   error over all keyframes does not drop by that much, the refinement is refused altogether.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from rig.camera import CameraModel
from rig.mesh_rays import mesh_points
from rig.transforms import distance_and_angle, invert, make_transform, transform_points
from slam_bridge.colmap_matches import COLMAP_PIXEL_OFFSET, Correspondences, colmap_camera_params

#: A keyframe is resected only with at least this many anchored correspondences.
MIN_CORRESPONDENCES = 12


@dataclass(frozen=True)
class RefineConfig:
    """Settings of :func:`refine_keyframe_poses`.

    Attributes:
        rounds: Gauss–Seidel rounds of resection.
        smoothing_s: σ (s) of the Gaussian that hands slow errors back to the LiDAR trajectory.
        inlier_px: correspondences farther than this from the current projection are ignored.
        holdout_every: every n-th match is held out to judge the result.
        min_gain: the held-out error must drop by at least this fraction.
        min_checks: a keyframe needs this many held-out observations to be judged.
        max_move_m, max_turn_deg: trust bounds on how far a pose may move from the LiDAR one.
    """

    rounds: int = 3
    smoothing_s: float = 2.0
    inlier_px: float = 10.0
    holdout_every: int = 5
    min_gain: float = 0.05
    min_checks: int = 10
    max_move_m: float = 0.10
    max_turn_deg: float = 2.0


@dataclass(frozen=True)
class RefinementReport:
    """What the refinement did: how many keyframes took a refined pose, why the others kept their
    LiDAR pose (by keyframe name), the median held-out reprojection error (px) with the LiDAR and
    the final poses, how far the final poses are from the LiDAR ones, and why the whole refinement
    was refused (None if it was not)."""

    refined: int
    kept: dict[str, str]
    heldout_px_before: float
    heldout_px_after: float
    max_move_m: float
    median_move_m: float
    max_turn_deg: float
    median_turn_deg: float
    refused: str | None = None


def reprojection_errors(
    camera: CameraModel, T_world_cam: np.ndarray, uv: np.ndarray, points: np.ndarray
) -> np.ndarray:
    """Pixel distance ``(N,)`` between ``uv`` and the projection of world ``points``; NaN behind
    the camera or for NaN points."""
    projected = camera.project(transform_points(invert(T_world_cam), points))
    return np.linalg.norm(projected - uv, axis=1)


def resect(
    colmap_camera: Any,
    camera: CameraModel,
    T_world_cam: np.ndarray,
    uv: np.ndarray,
    points: np.ndarray,
    inlier_px: float,
) -> np.ndarray:
    """``T_world_cam`` refined against 2D–3D correspondences (pycolmap, Cauchy loss); unchanged
    when fewer than :data:`MIN_CORRESPONDENCES` lie within ``inlier_px`` of their projection."""
    import pycolmap

    errors = reprojection_errors(camera, T_world_cam, uv, points)
    inliers = errors < inlier_px  # False for NaN
    if inliers.sum() < MIN_CORRESPONDENCES:
        return T_world_cam
    T_cam_world = invert(T_world_cam)
    options = pycolmap.AbsolutePoseRefinementOptions()
    options.loss_function_scale = 1.0
    result = pycolmap.refine_absolute_pose(
        pycolmap.Rigid3d(pycolmap.Rotation3d(T_cam_world[:3, :3]), T_cam_world[:3, 3]),
        uv[inliers] + COLMAP_PIXEL_OFFSET,
        points[inliers],
        np.ones(int(inliers.sum()), dtype=bool),
        colmap_camera,
        options,
    )
    if result is None:
        return T_world_cam
    refined = result["cam_from_world"]
    return invert(make_transform(refined.rotation.matrix(), refined.translation))


def restore_slow_errors(
    refined: np.ndarray, lidar: np.ndarray, t_ns: np.ndarray, sigma_s: float
) -> np.ndarray:
    """``refined`` poses ``(N, 4, 4)`` plus the Gaussian-smoothed (σ = ``sigma_s`` over time
    ``t_ns``) difference ``lidar − refined`` (positions, and rotations as world-frame rotation
    vectors)."""
    t = np.asarray(t_ns, dtype=np.float64) * 1e-9
    weights = np.exp(-0.5 * ((t[:, None] - t[None, :]) / sigma_s) ** 2)
    weights /= weights.sum(axis=1, keepdims=True)
    shift = weights @ (lidar[:, :3, 3] - refined[:, :3, 3])
    turn = (
        weights @ Rotation.from_matrix(lidar[:, :3, :3] @ refined[:, :3, :3].transpose(0, 2, 1)).as_rotvec()
    )
    rotations = Rotation.from_rotvec(turn).as_matrix() @ refined[:, :3, :3]
    return make_transform(rotations, refined[:, :3, 3] + shift)


class _Anchored:
    """Correspondences with their anchors, re-cast when a source keyframe's pose changes."""

    def __init__(
        self, corr: Correspondences, select: np.ndarray, raycaster: Any, camera: CameraModel
    ) -> None:
        self.observer, self.source = corr.observer[select], corr.source[select]
        self.uv_observer, self.uv_source = corr.uv_observer[select], corr.uv_source[select]
        self.raycaster, self.camera = raycaster, camera
        self.points = np.full((len(self.observer), 3), np.nan)

    def recast(self, keyframe: int, T_world_cam: np.ndarray) -> None:
        rows = self.source == keyframe
        if rows.any():
            self.points[rows] = mesh_points(self.raycaster, self.camera, T_world_cam, self.uv_source[rows])

    def recast_all(self, poses: np.ndarray) -> None:
        for k, T in enumerate(poses):
            self.recast(k, T)

    def errors_by_observer(self, poses: np.ndarray) -> list[np.ndarray]:
        """Reprojection errors of each keyframe's observations (NaN where an anchor missed)."""
        errors = []
        for k, T_world_cam in enumerate(poses):
            rows = self.observer == k
            errors.append(
                reprojection_errors(self.camera, T_world_cam, self.uv_observer[rows], self.points[rows])
            )
        return errors


def _moves(poses: np.ndarray, lidar: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m) and angle (deg) of each pose from the LiDAR one."""
    distance, angle = distance_and_angle(poses, lidar)
    return distance, np.degrees(angle)


def _median(errors: list[np.ndarray]) -> float:
    values = np.concatenate(errors)
    values = values[np.isfinite(values)]
    return float(np.median(values)) if values.size else float("nan")


def _judge(
    names: list[str],
    before: list[np.ndarray],
    after: list[np.ndarray],
    moves: tuple[np.ndarray, np.ndarray],
    config: RefineConfig,
) -> dict[str, str]:
    """The keyframes that keep their LiDAR pose, with the reason: too few held-out observations
    to judge, a held-out error that did not drop by ``min_gain``, or a move beyond the bounds."""
    kept = {}
    for k, name in enumerate(names):
        valid = np.isfinite(before[k]) & np.isfinite(after[k])
        if valid.sum() < config.min_checks:
            kept[name] = f"{int(valid.sum())} held-out matches, {config.min_checks} needed to judge"
            continue
        was, now = float(np.median(before[k][valid])), float(np.median(after[k][valid]))
        move_m, turn_deg = moves[0][k], moves[1][k]
        if now > (1 - config.min_gain) * was:
            kept[name] = f"held-out error {was:.2f} -> {now:.2f} px"
        elif move_m > config.max_move_m or turn_deg > config.max_turn_deg:
            kept[name] = f"moved {move_m:.3f} m / {turn_deg:.2f} deg, beyond the trust bounds"
    return kept


def refine_keyframe_poses(
    names: list[str],
    t_ns: np.ndarray,
    lidar_poses: np.ndarray,
    camera: CameraModel,
    correspondences: Correspondences,
    raycaster: Any,
    config: RefineConfig = RefineConfig(),
) -> tuple[np.ndarray, RefinementReport]:
    """Refine keyframe poses ``T_world_cam`` ``(N, 4, 4)`` (at stamps ``t_ns``) against the mesh in
    ``raycaster`` (see the module docstring); returns the final poses and a report.

    Args:
        names: keyframe names, in the order of the poses and of the correspondences' indices.
        camera: the distortion-free pinhole camera of the keyframe images (kept fixed).
        correspondences: verified matches between the keyframe images.
    """
    import pycolmap

    colmap_camera = pycolmap.Camera.create_from_model_name(
        1, "PINHOLE", camera.fx, camera.width, camera.height
    )
    colmap_camera.params = colmap_camera_params(camera)
    held = correspondences.match % config.holdout_every == 0
    fit = _Anchored(correspondences, ~held, raycaster, camera)
    check = _Anchored(correspondences, held, raycaster, camera)

    poses = lidar_poses.copy()
    fit.recast_all(poses)
    for _ in range(config.rounds):
        for k in range(len(poses)):
            rows = fit.observer == k
            poses[k] = resect(
                colmap_camera, camera, poses[k], fit.uv_observer[rows], fit.points[rows], config.inlier_px
            )
            fit.recast(k, poses[k])
    candidate = restore_slow_errors(poses, lidar_poses, t_ns, config.smoothing_s)

    check.recast_all(lidar_poses)
    before = check.errors_by_observer(lidar_poses)
    check.recast_all(candidate)
    after = check.errors_by_observer(candidate)
    kept = _judge(names, before, after, _moves(candidate, lidar_poses), config)
    final = np.where(np.isin(names, list(kept))[:, None, None], lidar_poses, candidate)

    check.recast_all(final)
    before_px, after_px = _median(before), _median(check.errors_by_observer(final))
    refused = None
    if len(kept) == len(names):
        refused = "no keyframe's held-out error dropped within the trust bounds"
    elif not after_px <= (1 - config.min_gain) * before_px:
        refused = f"the held-out error over all keyframes went {before_px:.2f} -> {after_px:.2f} px"
    if refused:
        final, after_px = lidar_poses.copy(), before_px
    move_m, turn_deg = _moves(final, lidar_poses)
    report = RefinementReport(
        refined=0 if refused else len(names) - len(kept),
        kept=kept,
        heldout_px_before=before_px,
        heldout_px_after=after_px,
        max_move_m=float(move_m.max()),
        median_move_m=float(np.median(move_m)),
        max_turn_deg=float(turn_deg.max()),
        median_turn_deg=float(np.median(turn_deg)),
        refused=refused,
    )
    return final, report
