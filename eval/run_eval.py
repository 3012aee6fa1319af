"""Evaluation of a training run (``lts eval RUN_DIR``): the numbers of the paper's tables and the
pictures of the report.

- **Photometry** on the held-out keyframes: the final model (``RUN_DIR/model.pt``) rendered at each
  test pose, PSNR / SSIM / LPIPS against the captured image (mean over views; LPIPS needs its
  weights, :mod:`eval.lpips_weights`), and the error of the rendered depth (``depth / alpha``)
  against the LiDAR depth over pixels with a return and ``alpha > 0.5`` (pooled over views).
- **Geometry** (needs ground truth, :mod:`eval.ground_truth`: a virtual-rig ground-truth folder or a
  mesh file in the scene's frame): the exported ``RUN_DIR/mesh.ply`` against the truth in the
  scene frame, both culled to the training frusta (the contract's ``chamfer_m``, ``fscore``, ...),
  and again with the truth also culled to what the training cameras see
  (:func:`~eval.geometry.visible_mask`; the ``*_visible`` fields).
- **Geometry against the test keyframes' LiDAR** (always; :mod:`eval.lidar_agreement`): the mesh's
  precision, recall and F-score at 20 cm against the held-out returns, the pseudo ground truth of a
  real recording (the ``lidar_*`` fields).
- **Ghosts of traffic** (needs a virtual-rig ground truth with moving objects;
  :mod:`eval.mover_ghosts`): the fraction of the mesh's area inside the movers' swept volumes
  (``mover_swept_area_fraction``).
- **Leaned views** (:func:`~eval.leaned_poses` of the test poses): a hole is a pixel where the
  reference has a surface and the model's accumulated alpha is < 0.5. The reference is the ground
  truth when given, otherwise the scene's SLAM mesh (``hole_reference`` says which).
- **Physics** (needs ground truth and pybullet): probes dropped along the keyframes' footprint on
  ``RUN_DIR/collision.obj`` and on the truth (:mod:`eval.physics`).

A metric that cannot be computed is ``None`` and its reason is in ``reasons`` — never a made-up 0.
"""

from __future__ import annotations

import importlib.util
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import torch
import trimesh

from eval.geometry import DEFAULT_SAMPLES
from eval.leaned_views import ALPHA_SURFACE, hit_mask, leaned_poses
from eval.lidar_agreement import lidar_agreement
from eval.lpips_net import LpipsAlex
from eval.lpips_weights import HOW_TO_GET, load_lpips
from eval.mover_ghosts import swept_area_fraction
from eval.moving_pixels import mover_names, moving_pixel_masks
from eval.photometric import color_aligned, lpips, psnr, ssim
from eval.seams import seam_drops, seam_holes
from eval.shared_views import held_out_views
from eval.sky_pixels import sky_masks
from rig.errors import InputError
from rig.mesh_io import load_mesh
from rig.mesh_rays import mesh_raycaster
from slam_bridge.scene import Keyframe, Scene, load_scene
from splat import run_dir as layout
from splat.background_mask import above_lidar, scored_background_mask
from splat.blocks.partition import PARTITION_FILE, Partition, read_partition
from splat.camera_blur import blurred, summary_width_px
from splat.exposure import through_color_map
from splat.model import TriangleModel, load_model

#: The fields ``lts eval RUN_DIR --json`` promises (../shared/DESIGN.md), in this order.
CONTRACT_FIELDS = (
    "psnr",
    "ssim",
    "lpips",
    "chamfer_m",
    "fscore",
    "precision",
    "recall",
    "threshold_m",
    "hole_fraction_leaned",
    "n_triangles",
    "train_seconds",
)
#: Fields that need ``--gt`` (``None`` without it).
GT_FIELDS = (
    "chamfer_m",
    "fscore",
    "precision",
    "recall",
    "accuracy_m",
    "completeness_m",
    "chamfer_visible_m",
    "fscore_visible",
    "precision_visible",
    "recall_visible",
    "accuracy_visible_m",
    "completeness_visible_m",
    *(f"{name}_surface" for name in ("fscore", "precision", "recall")),
    *(f"{name}_surface_m" for name in ("chamfer", "accuracy", "completeness")),
    *(f"{name}_visible_surface" for name in ("fscore", "precision", "recall")),
    *(f"{name}_visible_surface_m" for name in ("chamfer", "accuracy", "completeness")),
    "gt_visible_fraction",
    "gt_alignment_rmse_m",
    "physics_probes",
    "fall_through_rate",
    "height_error_mean_m",
    "height_error_max_m",
    "mover_swept_area_fraction",
)
#: Fields of the mesh against the test keyframes' LiDAR (:mod:`eval.lidar_agreement`).
LIDAR_FIELDS = (
    "lidar_fscore",
    "lidar_precision",
    "lidar_recall",
    "lidar_distance_median_m",
    "lidar_threshold_m",
    "lidar_points",
)
#: Holes and fall-through along a block run's seams (:mod:`eval.seams`).
SEAM_FIELDS = (
    "seam_blocks",
    "seam_views",
    "seam_hole_fraction",
    "off_seam_hole_fraction",
    "seam_physics_probes",
    "seam_fall_through_rate",
)
EVAL_FILE = "eval.json"
MESH_FILE = "mesh.ply"
COLLISION_FILES = ("collision.obj", "collision.ply")
#: Leaned variants of each test pose, in the order of :func:`~eval.leaned_poses`.
LEAN_YAW_DEG = 10.0
LEAN_SHIFT_M = 0.2
LEAN_LABELS = (
    f"yaw +{LEAN_YAW_DEG:g}°",
    f"yaw −{LEAN_YAW_DEG:g}°",
    f"shift +{LEAN_SHIFT_M:g} m",
    f"shift −{LEAN_SHIFT_M:g} m",
)
#: Up axis of a virtual-rig ground-truth world (its scenes are z-up).
GT_UP = np.array([0.0, 0.0, 1.0])
#: The window sharpness of the hard-edged render (``psnr_hard_edges``): the window ``m^σ`` is above
#: 0.98 wherever ``m > 1e-8``, so each opaque triangle covers its pixels as a mesh rasteriser
#: draws the exported triangles (training ends at σ 0.05, whose edges still blend).
HARD_EDGE_SIGMA = 1e-3


@dataclass(frozen=True)
class ViewImages:
    """One test view: ``(H, W, 3)`` float images in [0, 1] and the view's numbers."""

    name: str
    render: np.ndarray
    target: np.ndarray
    alpha: np.ndarray
    psnr: float
    ssim: float


@dataclass(frozen=True)
class LeanedImages:
    """One leaned view: the render, the reference's surface and the holes ``(H, W)`` bool."""

    name: str
    label: str
    render: np.ndarray
    surface: np.ndarray
    holes: np.ndarray

    @property
    def hole_fraction(self) -> float:
        surface = int(self.surface.sum())
        return float(self.holes.sum() / surface) if surface else 0.0


@dataclass(frozen=True)
class PointDistances:
    """Frustum-culled surface samples in the scene frame and their distances to the other mesh;
    ``T_display_world`` takes them to a z-up frame for pictures (the ground truth's world)."""

    reconstructed: np.ndarray
    to_ground_truth: np.ndarray
    ground_truth: np.ndarray
    to_reconstruction: np.ndarray
    threshold_m: float
    T_display_world: np.ndarray


@dataclass(frozen=True)
class PhysicsDrops:
    """Probe starts ``(P, 3)``, resting heights and fall-throughs on both meshes (scene frame, heights
    along ``up``); ``T_display_world`` as in :class:`PointDistances`."""

    start: np.ndarray
    up: np.ndarray
    T_display_world: np.ndarray
    rec_height: np.ndarray
    rec_fell: np.ndarray
    gt_height: np.ndarray
    gt_fell: np.ndarray


@dataclass
class RunEvaluation:
    """Everything ``lts eval RUN_DIR`` measured: ``metrics`` (the JSON) and the report's material."""

    run_dir: Path
    metrics: dict
    views: list[ViewImages] = field(default_factory=list)
    leaned: list[LeanedImages] = field(default_factory=list)
    points: PointDistances | None = None
    physics: PhysicsDrops | None = None


def _as_rgb(image: torch.Tensor) -> np.ndarray:
    return image.detach().clamp(0, 1).cpu().numpy().astype(np.float32)


def _photometric(
    model: TriangleModel,
    scene: Scene,
    tests: list[Keyframe],
    lpips_network: LpipsAlex | None,
    metrics: dict,
    reasons: dict,
    moving: list[np.ndarray] | None = None,
    color_maps: dict[str, np.ndarray] | None = None,
    sky: list[np.ndarray] | None = None,
    blur_px: float = 0.0,
) -> list[ViewImages]:
    """PSNR, SSIM, LPIPS and depth errors of the test views into ``metrics``; also PSNR over the
    pixels above the LiDAR's reach, of the render with hard triangle edges (:data:`HARD_EDGE_SIGMA`)
    and, with ``moving`` (one ``(H, W)`` mask per test view of the pixels that show a moving
    object), over the static pixels; with ``sky`` (one ``(H, W)`` mask per test view of the pixels
    the ground truth leaves empty, :mod:`eval.sky_pixels`), over the static sky pixels and the
    share of them that triangles cover. A test view with a colour matrix ``(3, 3)`` in
    ``color_maps`` (by name: its exposure, :mod:`splat.exposure`) is scored through it, and every
    render through the camera's blur of ``blur_px`` pixels (:mod:`splat.camera_blur`); the PSNR
    without that blur is ``psnr_sharp``."""
    views, psnrs, ssims, lpips_values, depth_errors = [], [], [], [], []
    above_psnrs, static_psnrs, moving_fractions, aligned_psnrs, hard_psnrs = [], [], [], [], []
    sharp_psnrs = []
    sky_psnrs, sky_pixels, sky_covered = [], 0, 0
    hard_edged = replace(model, sigma=HARD_EDGE_SIGMA)
    for i, keyframe in enumerate(tests):
        lidar = scene.depth(keyframe)
        depth = torch.as_tensor(lidar, device=model.device)
        scene_moving = scene.moving_mask(keyframe)
        shows = scored_background_mask(
            depth,
            float(scene.camera.K[1, 1]),
            None if scene_moving is None else torch.as_tensor(scene_moving, device=model.device),
        )
        above = above_lidar(depth) if shows is not None else None
        matrix = (color_maps or {}).get(keyframe.name)
        color_map = None if matrix is None else torch.as_tensor(matrix)
        out = model.render_at(scene.camera, keyframe.T_world_cam, shows)
        render = _as_rgb(through_color_map(blurred(out.rgb, blur_px), color_map))
        target = scene.image(keyframe).astype(np.float32) / 255.0
        sharp_psnrs.append(psnr(_as_rgb(through_color_map(out.rgb, color_map)), target))
        hard = hard_edged.render_at(scene.camera, keyframe.T_world_cam, shows).rgb
        hard_psnrs.append(psnr(_as_rgb(through_color_map(blurred(hard, blur_px), color_map)), target))
        alpha = out.alpha.detach().cpu().numpy()
        aligned_psnrs.append(psnr(color_aligned(render, target), target))
        if above is not None and bool(above.any()):
            above_psnrs.append(psnr(render, target, mask=above))
        if moving is not None:
            moving_fractions.append(float(moving[i].mean()))
            static_psnrs.append(psnr(render, target, mask=~moving[i]))
        if sky is not None and (scored := sky[i] if moving is None else sky[i] & ~moving[i]).any():
            sky_psnrs.append(psnr(render, target, mask=scored))
            sky_pixels += int(scored.sum())
            sky_covered += int((scored & (alpha >= ALPHA_SURFACE)).sum())
        views.append(
            ViewImages(
                keyframe.name, render, target, alpha, psnr(render, target),
                ssim(render, target),
            )
        )  # fmt: skip
        psnrs.append(views[-1].psnr)
        ssims.append(views[-1].ssim)
        if lpips_network is not None:
            lpips_values.append(lpips(render, target, lpips_network).value)
        valid = (lidar > 0) & (alpha > ALPHA_SURFACE)
        depth = out.expected_depth().detach().cpu().numpy()[valid]
        depth_errors.append(np.abs(depth - lidar[valid]))
    metrics["psnr"] = float(np.mean(psnrs))
    metrics["psnr_sharp"] = float(np.mean(sharp_psnrs))
    metrics["camera_blur_px"] = blur_px
    metrics["ssim"] = float(np.mean(ssims))
    metrics["psnr_color_aligned"] = float(np.mean(aligned_psnrs))
    metrics["psnr_hard_edges"] = float(np.mean(hard_psnrs))
    metrics["psnr_above_lidar"] = float(np.mean(above_psnrs)) if above_psnrs else None
    if not above_psnrs:
        reasons["psnr_above_lidar"] = "no test view has pixels above its LiDAR returns"
    metrics["psnr_static"] = float(np.mean(static_psnrs)) if moving is not None else None
    metrics["moving_pixel_fraction"] = float(np.mean(moving_fractions)) if moving is not None else None
    if moving is None:
        reasons["psnr_static"] = "needs --gt with moving objects (a virtual-rig folder with movers/)"
    metrics["psnr_sky"] = float(np.mean(sky_psnrs)) if sky_psnrs else None
    metrics["sky_covered_fraction"] = sky_covered / sky_pixels if sky_pixels else None
    if not sky_psnrs:
        why = "needs --gt" if sky is None else "the ground truth has a surface behind every test pixel"
        reasons["psnr_sky"] = reasons["sky_covered_fraction"] = why
    metrics["lpips"] = float(np.mean(lpips_values)) if lpips_values else None
    if lpips_network is None:
        reasons["lpips"] = HOW_TO_GET
    errors = np.concatenate(depth_errors)
    metrics["depth_error_median_m"] = float(np.median(errors)) if errors.size else None
    metrics["depth_error_mean_m"] = float(np.mean(errors)) if errors.size else None
    metrics["depth_error_pixels"] = int(errors.size)
    if not errors.size:
        reasons["depth_error_median_m"] = "no test pixel has both a LiDAR return and alpha > 0.5"
    return views


def _rig_movers_dir(gt: Path) -> Path | None:
    """The virtual-rig ground-truth folder of ``gt`` when it has moving objects, else None."""
    from eval.ground_truth import rig_ground_truth_dir

    folder = rig_ground_truth_dir(gt)
    return folder if folder is not None and mover_names(folder) else None


def _holes(
    model: TriangleModel,
    scene: Scene,
    tests: list[Keyframe],
    views: list[ViewImages],
    reference: trimesh.Trimesh,
    metrics: dict,
) -> list[LeanedImages]:
    """Hole fractions of the unleaned test views and of their leaned variants."""
    caster = mesh_raycaster(reference)
    camera = scene.camera
    surface_total = holes_total = 0
    for keyframe, view in zip(tests, views, strict=True):
        surface = hit_mask(caster, camera, keyframe.T_world_cam)
        surface_total += int(surface.sum())
        holes_total += int((surface & (view.alpha < ALPHA_SURFACE)).sum())
    metrics["hole_fraction_test"] = holes_total / surface_total if surface_total else None
    poses = leaned_poses(np.stack([k.T_world_cam for k in tests]), LEAN_YAW_DEG, LEAN_SHIFT_M)
    leaned = []
    for index, pose in enumerate(poses):
        out = model.render_at(scene.camera, pose)
        surface = hit_mask(caster, camera, pose)
        holes = surface & (out.alpha.detach().cpu().numpy() < ALPHA_SURFACE)
        keyframe = tests[index // len(LEAN_LABELS)]
        label = LEAN_LABELS[index % len(LEAN_LABELS)]
        leaned.append(LeanedImages(keyframe.name, label, _as_rgb(out.rgb), surface, holes))
    surface = sum(int(v.surface.sum()) for v in leaned)
    metrics["hole_fraction_leaned"] = sum(int(v.holes.sum()) for v in leaned) / surface if surface else None
    return leaned


def _geometry(
    reconstructed: trimesh.Trimesh,
    scene: Scene,
    truth,
    threshold_m: float,
    samples: int,
    metrics: dict,
) -> PointDistances:
    from eval.ground_truth import compare_culled, compare_culled_surfaces, culled_samples

    points = culled_samples(reconstructed, scene, truth, samples)
    metrics.update(compare_culled(points, threshold_m))
    metrics.update(compare_culled_surfaces(points, reconstructed, truth, threshold_m))
    to_gt, to_rec = points.distances
    return PointDistances(
        points.reconstructed, to_gt, points.ground_truth, to_rec, float(threshold_m), truth.T_gt_world
    )


def _lidar(
    mesh_path: Path, scene: Scene, tests: list[Keyframe], metrics: dict, reasons: dict, log: Callable
) -> None:
    """The ``lidar_*`` fields: the mesh against the test keyframes' LiDAR returns."""
    metrics.update(dict.fromkeys(LIDAR_FIELDS))
    if not mesh_path.is_file():
        reasons["lidar_fscore"] = f"the run has no exported mesh ({mesh_path})"
        return
    log(f"comparing {mesh_path.name} with the LiDAR returns of the {len(tests)} test keyframes")
    agreement = lidar_agreement(load_mesh(mesh_path), scene, tests)
    if agreement is None:
        reasons["lidar_fscore"] = "the test keyframes have no LiDAR returns in view"
    else:
        metrics.update(agreement.metrics())


def _scene_up(truth) -> np.ndarray:
    """The ground truth's up axis expressed in the scene (SLAM map) frame."""
    up = truth.T_gt_world[:3, :3].T @ GT_UP
    return up / np.linalg.norm(up)


def _physics(run_dir: Path, scene: Scene, truth, metrics: dict, reasons: dict) -> PhysicsDrops | None:
    if importlib.util.find_spec("pybullet") is None:
        reasons["physics"] = "pybullet is not installed (pip install '.[physics]')"
        return None
    collision = _collision_file(run_dir)
    if collision is None:
        reasons["physics"] = f"the run has no collision mesh ({' or '.join(COLLISION_FILES)})"
        return None
    from eval.physics import compare_drops, drop_probes, footprint_grid

    up = _scene_up(truth)
    keyframes = sorted(scene.keyframes, key=lambda k: k.t_ns)
    starts = footprint_grid(np.stack([k.T_world_cam[:3, 3] for k in keyframes]), up)
    try:
        rec = drop_probes(load_mesh(collision), starts, up)
        gt = drop_probes(truth.mesh, starts, up)
        result = compare_drops(rec, gt)
    except InputError as exc:
        reasons["physics"] = str(exc)
        return None
    metrics.update(
        physics_probes=result.probes,
        fall_through_rate=result.fall_through_rate,
        height_error_mean_m=_finite(result.mean_height_error_m),
        height_error_max_m=_finite(result.max_height_error_m),
        physics_mesh=collision.name,
    )
    if metrics["height_error_mean_m"] is None:
        reasons["height_error_mean_m"] = "every probe fell through the reconstruction"
    return PhysicsDrops(
        starts, up, truth.T_gt_world, rec.rest_height, rec.fell_through, gt.rest_height, gt.fell_through
    )


def _read_seams(run_dir: Path, seams: str | Path | None) -> Partition | None:
    """The partition whose seams are checked: ``seams`` (an error naming it when it is not a
    partition file), else the run's own ``partition.json``, else None."""
    path = Path(seams) if seams is not None else run_dir / PARTITION_FILE
    if seams is not None and not path.is_file():
        raise InputError("no such partition file (a block run's partition.json)", path=path, field="--seams")
    return read_partition(path) if path.is_file() else None


def _seams(
    run_dir: Path,
    partition: Partition | None,
    model: TriangleModel,
    scene: Scene,
    reference: trimesh.Trimesh | None,
    truth,
    physics: bool,
    metrics: dict,
    reasons: dict,
    log: Callable,
) -> None:
    """The ``seam_*`` fields (:mod:`eval.seams`) for ``partition``'s seams; null with the reason
    when there is none."""
    metrics.update(dict.fromkeys(SEAM_FIELDS))
    if partition is None:
        reasons.update(
            dict.fromkeys(SEAM_FIELDS, "not trained in blocks (lts train --blocks; or pass --seams)")
        )
        return
    metrics["seam_blocks"] = len(partition.blocks)
    if len(partition.blocks) < 2:
        reasons.update(dict.fromkeys(SEAM_FIELDS[1:], "the run is one block: it has no seams"))
        return
    if reference is None:
        reasons["seam_hole_fraction"] = reasons["hole_fraction_leaned"]
    else:
        log(f"rendering leaned views at the seams of {len(partition.blocks)} blocks")
        metrics.update(seam_holes(model, scene, reference, partition))
    collision = _collision_file(run_dir)
    if truth is None or not physics or collision is None or importlib.util.find_spec("pybullet") is None:
        reasons["seam_fall_through_rate"] = "needs --gt, --physics, a collision mesh and pybullet"
        return
    log("dropping physics probes across the seams")
    metrics.update(seam_drops(load_mesh(collision), truth.mesh, scene, partition, _scene_up(truth)))


def _collision_file(run_dir: Path) -> Path | None:
    """The run's collision mesh (the first of :data:`COLLISION_FILES` there), or None."""
    return next((run_dir / n for n in COLLISION_FILES if (run_dir / n).is_file()), None)


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _read_summary(run_dir: Path) -> dict:
    path = layout.summary_path(run_dir)
    if not path.is_file():
        return {}
    try:
        summary = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"not JSON ({exc})", path=path) from None
    return summary if isinstance(summary, dict) else {}


def evaluate_run(
    run_dir: str | Path,
    gt: str | Path | None = None,
    threshold_m: float = 0.1,
    samples: int = DEFAULT_SAMPLES,
    device: str = "cpu",
    physics: bool = True,
    log: Callable[[str], None] = lambda _: None,
    scene: Scene | None = None,
    lpips_weights: str | Path | None = None,
    seams: str | Path | None = None,
    test_views: Scene | None = None,
) -> RunEvaluation:
    """Evaluate a finished run (see the module docstring); ``gt`` is a virtual-rig ground-truth
    folder or its parent, or a mesh file in the scene's frame (``None``: no geometric or physics
    metrics); ``scene``: the run's scene when it is already loaded (its files are then not read
    again); ``lpips_weights``: the LPIPS weights file (``None``: where
    :func:`~eval.lpips_weights.load_lpips` looks); ``seams``: a block run's ``partition.json`` whose
    seams are checked (:mod:`eval.seams`; ``None``: the run's own, when it was trained in blocks);
    ``test_views``: another scene of the same recording and map whose held-out views the test-view
    metrics score instead of the run's own (:func:`eval.shared_views.held_out_views`)."""
    run_dir = Path(run_dir)
    if threshold_m <= 0:
        raise InputError(f"threshold must be positive, got {threshold_m}", field="threshold")
    scene = scene if scene is not None else load_scene(layout.scene_of(run_dir))
    model = load_model(layout.model_path(run_dir), device)
    tests = scene.split("test") if test_views is None else held_out_views(scene, test_views)
    if not tests:
        raise InputError("the scene has no test keyframes to evaluate on", path=scene.root, field="split")
    views_from = scene if test_views is None else test_views
    summary = _read_summary(run_dir)
    blur_px = summary_width_px(summary, layout.summary_path(run_dir))
    metrics: dict = dict.fromkeys(CONTRACT_FIELDS)
    metrics["threshold_m"] = float(threshold_m)
    reasons: dict[str, str] = {}
    # bad weights, seams or ground truth fail here, before minutes of rendering
    lpips_network = load_lpips(lpips_weights)
    partition = _read_seams(run_dir, seams)
    truth = None
    if gt is not None:
        from eval.ground_truth import load_ground_truth

        truth = load_ground_truth(scene, gt)

    moving = None
    movers = None if gt is None else _rig_movers_dir(Path(gt))
    if movers is not None:
        log(f"finding the pixels of the moving objects in {len(tests)} test views")
        moving = moving_pixel_masks(movers, scene.camera, np.array([k.t_ns for k in tests]))
    log(f"rendering {len(tests)} test views")
    color_maps, metrics["test_color_maps"] = layout.read_color_maps(run_dir)
    if test_views is not None and color_maps:
        color_maps, metrics["test_color_maps"] = None, None
        reasons["test_color_maps"] = (
            "the run's colour maps are for its own test views: --test-views scores through none"
        )
    elif not color_maps:
        reasons["test_color_maps"] = "the run learnt no colour maps (lts train --exposure)"
    sky = None if truth is None else sky_masks(truth.mesh, scene.camera, [k.T_world_cam for k in tests])
    views = _photometric(
        model, views_from, tests, lpips_network, metrics, reasons, moving, color_maps, sky, blur_px
    )

    metrics.update(dict.fromkeys(GT_FIELDS))
    if truth is not None:
        metrics["gt_alignment_rmse_m"] = truth.pose_rmse_m
        if truth.pose_rmse_m is None:
            reasons["gt_alignment_rmse_m"] = "the ground truth is a mesh file, taken as in the scene's frame"
        reference, metrics["hole_reference"] = truth.mesh, "ground_truth"
    elif scene.mesh_path.is_file():
        reference, metrics["hole_reference"] = load_mesh(scene.mesh_path), "slam_mesh"
    else:
        reference, metrics["hole_reference"] = None, None
        reasons["hole_fraction_leaned"] = f"no --gt and the scene has no SLAM mesh ({scene.mesh_path})"
    leaned = []
    if reference is not None:
        log(f"rendering {4 * len(tests)} leaned views (holes against the {metrics['hole_reference']})")
        leaned = _holes(model, views_from, tests, views, reference, metrics)

    points = drops = None
    mesh_path = run_dir / MESH_FILE
    if truth is None:
        for name in GT_FIELDS:
            reasons.setdefault(
                name, "needs --gt (a ground-truth mesh in the scene's frame or a virtual-rig folder)"
            )
    elif not mesh_path.is_file():
        reasons["chamfer_m"] = f"the run has no exported mesh ({mesh_path})"
    else:
        log(f"comparing {mesh_path.name} with the ground truth ({samples} samples each)")
        reconstructed = load_mesh(mesh_path)
        points = _geometry(reconstructed, scene, truth, threshold_m, samples, metrics)
        if movers is None:
            reasons["mover_swept_area_fraction"] = "the ground truth has no moving objects (movers/)"
        else:
            metrics["mover_swept_area_fraction"] = swept_area_fraction(
                reconstructed, truth.T_gt_world, movers, samples
            )
    _lidar(mesh_path, views_from, tests, metrics, reasons, log)
    if truth is not None and physics:
        log("dropping physics probes on the collision mesh and the ground truth")
        drops = _physics(run_dir, scene, truth, metrics, reasons)
    elif truth is not None:
        reasons["physics"] = "skipped (--no-physics)"

    _seams(run_dir, partition, model, scene, reference, truth, physics, metrics, reasons, log)
    metrics["n_triangles"] = summary.get("n_triangles", model.n_triangles)
    metrics["train_seconds"] = summary.get("train_seconds")
    if metrics["train_seconds"] is None:
        reasons["train_seconds"] = f"no train_seconds in {layout.summary_path(run_dir)}"
    metrics.update(
        n_test_views=len(tests),
        n_leaned_views=len(leaned),
        method=summary.get("method"),
        run_dir=str(run_dir),
        scene_dir=str(scene.root),
        test_views_dir=str(views_from.root),
        gt_dir=str(gt) if gt is not None else None,
        reasons=reasons,
    )
    return RunEvaluation(run_dir, metrics, views, leaned, points, drops)


def write_eval_json(evaluation: RunEvaluation) -> Path:
    """Write ``RUN_DIR/eval.json`` (the metrics, NaN/Inf as null)."""
    from rig.plain import plain_data

    path = evaluation.run_dir / EVAL_FILE
    path.write_text(json.dumps(plain_data(evaluation.metrics, nonfinite_as_none=True), indent=1) + "\n")
    return path
