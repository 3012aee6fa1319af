"""Stress checks for numerical stability and bad input, runnable without pytest.

Each *area* (rasteriser, photometric metrics, geometric metrics, trajectory alignment, time
offset, file readers) has a case builder driven by a small parameter record and a check that
returns the problems it found (an empty list: the case passed). The pytest suite in
``tests/stress`` draws the parameters with hypothesis; :func:`run_stability_suite` draws them
with a seeded random generator and counts, per area, the cases tried, the failures found and
the non-finite events caught (a NaN/Inf fed in on purpose and rejected with
:class:`~rig.errors.InputError`, or a degenerate input answered with an explicit refusal).

:func:`bench_stability_command` is ``lts bench stability [--profile ci|long] [--seed N] [--json]``.
Hypothesis is a test dependency only; nothing here needs it.
"""

from __future__ import annotations

import math
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import typer

from rig.errors import InputError

#: Triangle kinds the rasteriser cases mix (see :func:`raster_scene`).
TRIANGLE_KINDS = (
    "regular",
    "zero_area",
    "collinear",
    "needle",
    "near_graze",
    "near_cross",
    "edge_on",
    "huge",
    "behind",
)
#: Scene scales (metres) the rasteriser cases span.
SCALES = (1e-4, 1e-2, 1.0, 1e2, 1e4)
#: Sigma at both ends of its schedule, and opacities at both ends of their range.
SIGMA_ENDS = (1e-4, 5.0)
OPACITY_ENDS = (0.0, 1.0)
NEAR_M = 0.02


# --------------------------------------------------------------------------------------------
# Rasteriser


@dataclass(frozen=True)
class RasterCase:
    """One rasteriser stress case; every number the scene is built from.

    Attributes:
        dtype: ``"float32"`` or ``"float64"``.
        scale: scene scale in metres (depths are 0.5-10 x scale; ``near`` is scaled too).
        kinds: one entry of :data:`TRIANGLE_KINDS` per triangle.
        sigma: per-triangle window sharpness (> 0).
        opacity: per-triangle vertex opacities in [0, 1] (three per triangle).
        width, height: image size (px).
        fx, fy, cx, cy: pinhole intrinsics (extremes allowed: 1e-2 to 1e5 px focal lengths,
            principal points off the image).
        seed: geometry seed (positions, sizes, colours).
    """

    dtype: str
    scale: float
    kinds: tuple[str, ...]
    sigma: tuple[float, ...]
    opacity: tuple[float, ...]
    width: int = 24
    height: int = 20
    fx: float = 20.0
    fy: float = 20.0
    cx: float = 11.5
    cy: float = 9.5
    seed: int = 0


def _torch_dtype(name: str):
    import torch

    return {"float32": torch.float32, "float64": torch.float64}[name]


def raster_camera(case: RasterCase):
    """The case's distortion-free pinhole :class:`~rig.camera.CameraModel`."""
    from rig.camera import CameraModel

    K = [[case.fx, 0.0, case.cx], [0.0, case.fy, case.cy], [0.0, 0.0, 1.0]]
    return CameraModel("pinhole", case.width, case.height, K, [])


def _triangle(kind: str, case: RasterCase, rng: np.random.Generator) -> np.ndarray:
    """Three camera-frame vertices ``(3, 3)`` (float64) of one triangle of ``kind``."""
    s, near = case.scale, NEAR_M * case.scale
    u = rng.uniform(-0.2, 1.2) * case.width
    v = rng.uniform(-0.2, 1.2) * case.height
    z = s * rng.uniform(0.5, 10.0)
    centre = np.array([(u - case.cx) / case.fx * z, (v - case.cy) / case.fy * z, z])
    # Size: 0.1 px to 3 image widths, as a length at depth z.
    size_px = 10 ** rng.uniform(-1.0, math.log10(3 * max(case.width, case.height)))
    radius = size_px * z / max(case.fx, case.fy)
    angles = rng.uniform(0, 2 * np.pi) + np.array([0.0, 2.1, 4.2]) + rng.uniform(-0.4, 0.4, 3)
    tilt = rng.uniform(-1.0, 1.0, 3) * 0.5
    offsets = np.stack([np.cos(angles), np.sin(angles), tilt * np.cos(angles - 1.0)], axis=1)
    tri = centre + radius * offsets
    if kind == "zero_area":
        tri[1] = tri[0]
    elif kind == "collinear":
        tri[2] = tri[0] + rng.uniform(-2.0, 2.0) * (tri[1] - tri[0])
    elif kind == "needle":
        mid = tri[0] + rng.uniform(0.0, 1.0) * (tri[1] - tri[0])
        tri[2] = mid + 10 ** rng.uniform(-7.0, -2.0) * (tri[2] - mid)
    elif kind == "near_graze":
        i = int(rng.integers(3))
        tri[i, 2] = near * (1.0 + 10 ** rng.uniform(-7.0, -1.0))
    elif kind == "near_cross":
        i = int(rng.integers(3))
        tri[i, 2] = near * rng.uniform(-2.0, 0.999)
    elif kind == "edge_on":
        # All three vertices on a plane through the camera centre (up to a tiny tilt).
        direction = centre / np.linalg.norm(centre)
        side = np.cross(direction, rng.normal(size=3))
        side /= np.linalg.norm(side)
        tri = np.stack([centre, centre + radius * direction, centre + radius * side]) + 10 ** rng.uniform(
            -9.0, -4.0
        ) * radius * np.cross(direction, side)
    elif kind == "huge":
        tri = centre + 100.0 * radius * offsets
    elif kind == "behind":
        tri[:, 2] = -np.abs(tri[:, 2])
    return tri


def raster_scene(case: RasterCase) -> dict[str, Any]:
    """Tensors of the case: ``vertices (3F, 3)``, ``faces (F, 3)``, ``colors (3F, 3)`` in [0, 1],
    ``opacities (3F,)``, ``sigma (F,)``, the camera and ``near``."""
    import torch

    rng = np.random.default_rng(case.seed)
    dtype = _torch_dtype(case.dtype)
    tris = np.stack([_triangle(k, case, rng) for k in case.kinds]) if case.kinds else np.zeros((0, 3, 3))
    n = len(case.kinds)
    return {
        "vertices": torch.as_tensor(tris.reshape(-1, 3), dtype=dtype),
        "faces": torch.arange(3 * n, dtype=torch.int64).reshape(n, 3),
        "colors": torch.as_tensor(rng.uniform(0, 1, (3 * n, 3)), dtype=dtype),
        "opacities": torch.as_tensor(np.asarray(case.opacity, dtype=np.float64), dtype=dtype),
        "sigma": torch.as_tensor(np.asarray(case.sigma, dtype=np.float64), dtype=dtype),
        "camera": raster_camera(case),
        "near": NEAR_M * case.scale,
    }


RASTER_OUTPUTS = ("rgb", "depth", "alpha", "normal", "median_depth", "distortion")


def check_raster(case: RasterCase, backend: str = "cpu") -> list[str]:
    """Render the case forward and backward; the problems found (empty: none).

    Checked: every output and every gradient finite; alpha in [0, 1]; rgb in [0, 1] (colours
    are); depth, median depth and distortion >= 0; normals no longer than 1; per-face largest
    weight in [0, 1].
    """
    import torch

    from splat.raster import render

    scene = raster_scene(case)
    leaves = [scene[k].clone().requires_grad_(True) for k in ("vertices", "colors", "opacities", "sigma")]
    vertices, colors, opacities, sigma = leaves
    out = render(
        vertices,
        scene["faces"],
        colors,
        opacities,
        sigma,
        scene["camera"],
        near=scene["near"],
        backend=backend,
    )
    problems = []
    eps = 1e-5 if case.dtype == "float32" else 1e-12
    for name in (*RASTER_OUTPUTS, "max_weight"):
        value = getattr(out, name).detach()
        if not bool(torch.isfinite(value).all()):
            problems.append(f"{name} not finite")
    alpha, rgb = out.alpha.detach(), out.rgb.detach()
    if alpha.numel() and (float(alpha.min()) < 0 or float(alpha.max()) > 1 + eps):
        problems.append(f"alpha outside [0, 1]: [{float(alpha.min())}, {float(alpha.max())}]")
    if rgb.numel() and (float(rgb.min()) < -eps or float(rgb.max()) > 1 + eps):
        problems.append(f"rgb outside [0, 1]: [{float(rgb.min())}, {float(rgb.max())}]")
    for name in ("depth", "median_depth", "distortion"):
        value = getattr(out, name).detach()
        if value.numel() and float(value.min()) < -eps * max(1.0, case.scale):
            problems.append(f"{name} negative: {float(value.min())}")
    if out.normal.numel() and float(out.normal.detach().norm(dim=-1).max()) > 1 + 1e3 * eps:
        problems.append("normal longer than 1")
    mw = out.max_weight
    if mw.numel() and (float(mw.min()) < 0 or float(mw.max()) > 1 + eps):
        problems.append("max_weight outside [0, 1]")
    # Backward: a fixed random weighting of every differentiable output.
    g = torch.Generator().manual_seed(case.seed)
    loss = sum(
        (
            torch.randn(getattr(out, n).shape, generator=g, dtype=torch.float64).to(alpha.dtype)
            * getattr(out, n)
        ).sum()
        for n in RASTER_OUTPUTS
    )
    grads = torch.autograd.grad(loss, leaves, allow_unused=True)
    for name, grad in zip(("vertices", "colors", "opacities", "sigma"), grads, strict=True):
        if grad is not None and not bool(torch.isfinite(grad).all()):
            problems.append(f"d loss / d {name} not finite")
    return problems


def random_raster_case(rng: np.random.Generator) -> RasterCase:
    """A random :class:`RasterCase` mixing every triangle kind, scale and extreme."""
    n = int(rng.integers(1, 7))
    kinds = tuple(str(k) for k in rng.choice(TRIANGLE_KINDS, n))

    def pick(ends: tuple[float, ...], lo: float, hi: float) -> float:
        return float(rng.choice(ends)) if rng.random() < 0.5 else float(rng.uniform(lo, hi))

    width, height = int(rng.integers(1, 40)), int(rng.integers(1, 40))
    focal = float(10 ** rng.uniform(-2, 10)) if rng.random() < 0.4 else float(rng.uniform(10, 60))
    return RasterCase(
        dtype=str(rng.choice(["float32", "float64"])),
        scale=float(rng.choice(SCALES)),
        kinds=kinds,
        sigma=tuple(pick(SIGMA_ENDS, 0.05, 3.0) for _ in range(n)),
        opacity=tuple(o for _ in range(n) for o in [pick(OPACITY_ENDS, 0.0, 1.0)] * 3),
        width=width,
        height=height,
        fx=focal,
        fy=focal * float(10 ** rng.uniform(-0.5, 0.5)),
        cx=float(rng.uniform(-0.5, 1.5) * width),
        cy=float(rng.uniform(-0.5, 1.5) * height),
        seed=int(rng.integers(2**31)),
    )


def check_raster_scale_invariance(case: RasterCase, backend: str = "cpu") -> list[str]:
    """The same scene at ``case.scale`` and at 1 m (``near`` scaled alike) must give the same
    images: rgb and alpha equal, depths scaled. Thresholds are in pixels or relative, so a
    1e-4 m or a 1e4 m scene renders like a 1 m one (up to rounding)."""
    import dataclasses

    import torch

    from splat.raster import render

    outs = []
    for scale in (1.0, case.scale):
        scene = raster_scene(dataclasses.replace(case, scale=scale))
        with torch.no_grad():
            outs.append(
                render(
                    scene["vertices"], scene["faces"], scene["colors"], scene["opacities"], scene["sigma"],
                    scene["camera"], near=scene["near"], backend=backend,
                )
            )  # fmt: skip
    unit, scaled = outs
    tol = 1e-3 if case.dtype == "float32" else 1e-7
    problems = []
    for name, factor in (("alpha", 1.0), ("rgb", 1.0), ("depth", case.scale), ("median_depth", case.scale)):
        a, b = getattr(unit, name).double() * factor, getattr(scaled, name).double()
        err = float((a - b).abs().max()) if a.numel() else 0.0
        if not err <= tol * factor:
            problems.append(f"{name} at scale {case.scale:g} differs from scale 1 by {err:.3g}")
    return problems


def check_raster_rejects_nonfinite(case: RasterCase, which: str, value: float) -> list[str]:
    """A NaN/Inf in ``which`` (vertices, colors, opacities or sigma) must be refused with an
    :class:`InputError` naming that input, before any kernel runs."""
    from splat.raster import render

    scene = raster_scene(case)
    tensors = {k: scene[k].clone() for k in ("vertices", "colors", "opacities", "sigma")}
    if tensors[which].numel() == 0:
        return []
    tensors[which].view(-1)[0] = value
    try:
        render(
            tensors["vertices"], scene["faces"], tensors["colors"], tensors["opacities"], tensors["sigma"],
            scene["camera"], near=scene["near"],
        )  # fmt: skip
    except InputError as exc:
        return [] if exc.field == which else [f"{which}={value}: InputError names {exc.field!r}"]
    return [f"{which}={value} was rendered instead of refused"]


# --------------------------------------------------------------------------------------------
# Photometric metrics


def check_photometric(a: np.ndarray, b: np.ndarray) -> list[str]:
    """PSNR and SSIM (both border modes) of images ``(H, W, 3)`` in [0, 1]: finite (PSNR may be
    ``inf`` only for identical images), SSIM in [-1, 1], identical images give SSIM 1 exactly."""
    from eval.photometric import psnr, ssim

    problems = []
    identical = np.array_equal(a, b)
    value = psnr(a, b)
    if math.isnan(value) or (math.isinf(value) and not identical) or (identical and value != math.inf):
        problems.append(f"psnr {value} (identical={identical})")
    modes = ["zero-pad"] + (["crop"] if min(a.shape[:2]) > 10 else [])
    for border in modes:
        value = ssim(a, b, border=border)
        if not (math.isfinite(value) and -1.0 - 1e-9 <= value <= 1.0 + 1e-9):
            problems.append(f"ssim ({border}) {value} outside [-1, 1]")
        if identical and value != 1.0:
            problems.append(f"ssim ({border}) of identical images is {value!r}, not 1")
    return problems


def random_image_pair(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Two images ``(H, W, 3)`` in [0, 1]: constant, noise, identical, saturated or tiny
    differences, 1-40 px a side."""
    h, w = int(rng.integers(1, 40)), int(rng.integers(1, 40))

    def image() -> np.ndarray:
        kind = rng.integers(4)
        if kind == 0:
            return np.full((h, w, 3), float(rng.choice([0.0, 1.0, rng.uniform()])))
        if kind == 1:
            return rng.uniform(0, 1, (h, w, 3))
        if kind == 2:
            return (rng.uniform(0, 1, (h, w, 3)) > 0.5).astype(np.float64)
        return np.clip(0.5 + 1e-9 * rng.normal(size=(h, w, 3)), 0, 1)

    a = image()
    choice = rng.integers(3)
    b = (
        a.copy()
        if choice == 0
        else image()
        if choice == 1
        else np.clip(a + 1e-12 * rng.normal(size=a.shape), 0, 1)
    )
    return a, b


# --------------------------------------------------------------------------------------------
# Geometric metrics


def check_point_sets(rec: np.ndarray, gt: np.ndarray, threshold: float) -> tuple[list[str], bool]:
    """:func:`~eval.geometry.compare_point_sets` on arbitrary input: either finite metrics in
    range, or an :class:`InputError` for empty / non-finite / misshapen input or a bad threshold.
    Returns the problems and whether an input error was (rightly) raised."""
    from eval.geometry import compare_point_sets

    rec, gt = np.asarray(rec, dtype=np.float64), np.asarray(gt, dtype=np.float64)
    bad_input = (
        rec.size == 0
        or gt.size == 0
        or not (np.all(np.isfinite(rec)) and np.all(np.isfinite(gt)))
        or not (math.isfinite(threshold) and threshold > 0)
    )
    try:
        m = compare_point_sets(rec, gt, threshold)
    except InputError:
        return ([] if bad_input else ["InputError on valid input"]), True
    if bad_input:
        return ["bad input gave numbers instead of an InputError"], False
    problems = []
    for name in ("precision", "recall", "fscore"):
        v = getattr(m, name)
        if not 0.0 <= v <= 1.0:
            problems.append(f"{name} {v} outside [0, 1]")
    for name in ("accuracy_m", "completeness_m", "chamfer_m"):
        v = getattr(m, name)
        if not (math.isfinite(v) and v >= 0):
            problems.append(f"{name} {v}")
    if np.array_equal(rec, gt) and not (m.chamfer_m == 0.0 and m.fscore == 1.0):
        problems.append(f"identical sets: chamfer {m.chamfer_m}, F {m.fscore}")
    return problems, False


def random_point_sets(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float]:
    """Point sets (empty, single, duplicated, huge or tiny coordinates, NaN) and a threshold."""

    def points() -> np.ndarray:
        n = int(rng.choice([0, 1, 2, int(rng.integers(3, 300))]))
        p = rng.normal(size=(n, 3)) * 10 ** rng.uniform(-4, 4) + 10 ** rng.uniform(-4, 6)
        if n and rng.random() < 0.2:
            p[:] = p[0]  # all duplicates
        if n and rng.random() < 0.1:
            p[int(rng.integers(n)), int(rng.integers(3))] = float(rng.choice([np.nan, np.inf, -np.inf]))
        return p

    rec = points()
    gt = rec.copy() if rng.random() < 0.2 else points()
    threshold = float(rng.choice([0.1, 1e-6, 1e6, 0.0, -1.0, np.nan])) if rng.random() < 0.3 else 0.1
    return rec, gt, threshold


# --------------------------------------------------------------------------------------------
# Trajectory alignment


def check_alignment(positions: np.ndarray, seed: int) -> list[str]:
    """ATE of a trajectory against a rigidly moved copy of itself must be ~0, whatever the
    configuration (a line, a point, a plane: the alignment is then not unique but its residual
    is), and ``T_ref_est`` must be a rotation."""
    from eval.trajectory_metrics import absolute_trajectory_error
    from rig.trajectory import Trajectory
    from rig.transforms import make_transform, rotation_error

    rng = np.random.default_rng(seed)
    n = len(positions)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    estimate = Trajectory.from_quaternions(np.arange(n, dtype=np.int64) * 10**8, positions, q)
    from scipy.spatial.transform import Rotation

    T = make_transform(Rotation.random(random_state=seed).as_matrix(), rng.normal(size=3) * 10)
    reference = estimate.transformed(T_left=T)
    scale = max(1.0, float(np.abs(positions).max()), 10.0)
    problems = []
    for use_orientation in (False, True):
        ate = absolute_trajectory_error(estimate, reference, use_orientation=use_orientation)
        if not (math.isfinite(ate.rmse_m) and ate.rmse_m <= 1e-9 * scale):
            problems.append(f"ATE {ate.rmse_m} of an exact copy (use_orientation={use_orientation})")
        if not rotation_error(ate.T_ref_est[:3, :3]) < 1e-9:
            problems.append("T_ref_est is not a rotation")
    return problems


def random_positions(rng: np.random.Generator) -> np.ndarray:
    """``(N, 3)`` positions: collinear, all equal, planar, general; 1e-4 m to 1e4 m."""
    n = int(rng.integers(3, 60))
    kind = rng.integers(4)
    scale = 10 ** rng.uniform(-4, 4)
    if kind == 0:
        p = np.outer(np.sort(rng.uniform(0, 1, n)), rng.normal(size=3))
    elif kind == 1:
        p = np.tile(rng.normal(size=3), (n, 1))
    elif kind == 2:
        p = np.c_[rng.normal(size=(n, 2)), np.zeros(n)]
    else:
        p = rng.normal(size=(n, 3))
    return p * scale + rng.normal(size=3) * scale


# --------------------------------------------------------------------------------------------
# Camera-LiDAR time offset


@dataclass(frozen=True)
class TimeOffsetCase:
    """Angular-velocity signals for :func:`~calib.time_offset.estimate_time_offset`.

    ``motion``: rad/s amplitude of the turning (0: none); ``overlap``: fraction of the camera
    span the LiDAR signal covers; ``axes``: 1 (planar turning) or 3; ``offset_s``: the true one.
    """

    motion: float
    overlap: float
    axes: int
    offset_s: float
    noise: float
    seed: int


def check_time_offset(case: TimeOffsetCase) -> list[str]:
    """Either ``poorly constrained`` or an ``ok`` offset whose error is within five of its own
    standard deviations (1 ms at least): never an ``ok`` answer that its uncertainty does not
    cover, never NaN with ``ok``."""
    from calib.time_offset import estimate_time_offset

    rng = np.random.default_rng(case.seed)
    t_cam = np.arange(0.0, 12.0, 1 / 15)
    t_lidar = np.arange(0.0, 12.0 * case.overlap, 1 / 200) + 12.0 * (1 - case.overlap) / 2

    def w(t: np.ndarray) -> np.ndarray:
        s = case.motion * np.c_[np.sin(1.3 * t), 0.5 * np.cos(0.7 * t), np.sin(2.1 * t + 1)]
        if case.axes == 1:
            s[:, :2] = 0
        return s

    w_cam = w(t_cam - case.offset_s) + case.noise * rng.normal(size=(len(t_cam), 3))
    w_lidar = w(t_lidar) + case.noise * rng.normal(size=(len(t_lidar), 3))
    r = estimate_time_offset(t_cam, w_cam, t_lidar, w_lidar)
    allowed = max(1e-3, 5 * r.std_s)
    if r.verdict == "ok" and not (
        math.isfinite(r.time_offset_s) and abs(r.time_offset_s - case.offset_s) <= allowed
    ):
        return [f"verdict ok with offset {r.time_offset_s} ± {r.std_s} (truth {case.offset_s})"]
    if r.verdict not in ("ok", "poorly constrained"):
        return [f"verdict {r.verdict!r}"]
    return []


def random_time_offset_case(rng: np.random.Generator) -> TimeOffsetCase:
    return TimeOffsetCase(
        motion=float(rng.choice([0.0, 1e-3, 0.05, 1.0])),
        overlap=float(rng.choice([1.0, 0.5, 0.05, 0.004])),
        axes=int(rng.choice([1, 3])),
        offset_s=float(rng.uniform(-0.1, 0.1)),
        noise=float(rng.choice([0.0, 0.01, 0.3])),
        seed=int(rng.integers(2**31)),
    )


# --------------------------------------------------------------------------------------------
# File readers

READER_KINDS = (
    "ply_ascii",
    "ply_binary",
    "obj",
    "pcd_ascii",
    "pcd_binary",
    "pcd_compressed",
    "kitti_bin",
    "tum",
    "euroc",
    "calib_yaml",
    "mcap",
)
MUTATIONS = ("truncate", "flip", "nan")


def _sample_points(n: int = 40, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(n, 3)).astype(np.float32)


def write_sample(kind: str, path: Path) -> Path:
    """Write a small valid file of ``kind`` (one of :data:`READER_KINDS`) at ``path``."""
    import trimesh

    if kind in ("ply_ascii", "ply_binary", "obj"):
        mesh = trimesh.creation.icosphere(subdivisions=1)
        encoding = "ascii" if kind == "ply_ascii" else "binary"
        data = (
            mesh.export(file_type="ply", encoding=encoding) if kind != "obj" else mesh.export(file_type="obj")
        )
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
    elif kind.startswith("pcd"):
        import open3d as o3d

        pts = _sample_points()
        cloud = o3d.t.geometry.PointCloud(o3d.core.Tensor(pts))
        cloud.point.intensity = o3d.core.Tensor(np.arange(len(pts), dtype=np.float32)[:, None])
        o3d.t.io.write_point_cloud(
            str(path), cloud, write_ascii=kind == "pcd_ascii", compressed=kind == "pcd_compressed"
        )
    elif kind == "kitti_bin":
        np.c_[_sample_points(), np.ones(40, np.float32)].astype("<f4").tofile(path)
    elif kind in ("tum", "euroc"):
        from rig.trajectory import Trajectory
        from rig.trajectory_io import write_trajectory

        rng = np.random.default_rng(0)
        q = rng.normal(size=(20, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        t = Trajectory.from_quaternions(np.arange(20, dtype=np.int64) * 10**8, rng.normal(size=(20, 3)), q)
        write_trajectory(t, path, kind)
    elif kind == "calib_yaml":
        from rig.calibration import Calibration, save_calibration
        from rig.camera import CameraModel

        camera = CameraModel(
            "pinhole", 320, 240, [[200, 0, 160], [0, 200, 120], [0, 0, 1]], [0.1, -0.05, 0, 0, 0]
        )
        save_calibration(Calibration(camera, np.eye(4), 0.015, {"rms_px": 0.3}), path)
    elif kind == "mcap":
        from rig.camera import CameraModel
        from rig.messages import Frame, ImuSample, Scan
        from rig.session import SessionWriter

        rng = np.random.default_rng(0)
        with SessionWriter(path, image_format="png", chunk_size=4096) as w:
            w.write_camera_info(
                CameraModel("pinhole", 16, 12, [[15, 0, 8], [0, 15, 6], [0, 0, 1]], []), 10**9
            )
            for i in range(12):
                t = 10**9 + i * 10**7
                w.write_frame(Frame(rng.integers(0, 255, (12, 16, 3), dtype=np.uint8), t, t, "cam"))
                w.write_imu(ImuSample(np.array([0.0, 0.0, 0.1]), np.array([0.0, 0.0, 9.8]), t, t))
                if i % 4 == 0:
                    pts = rng.normal(size=(50, 3)).astype(np.float32)
                    w.write_scan(Scan(pts, np.zeros(50, np.float32), np.ones(50, np.float32), t, t))
    else:
        raise ValueError(f"unknown sample kind {kind!r}")
    return path


def _suffix(kind: str) -> str:
    return {
        "ply_ascii": ".ply",
        "ply_binary": ".ply",
        "obj": ".obj",
        "kitti_bin": ".bin",
        "tum": ".tum",
        "euroc": ".csv",
        "calib_yaml": ".yaml",
        "mcap": ".mcap",
    }.get(kind, ".pcd")


def mutate(data: bytes, mutation: str, position: float, payload: bytes) -> bytes:
    """``truncate`` at ``position`` (fraction of the length), ``flip``: overwrite bytes there
    with ``payload``, ``nan``: replace the number at or after ``position`` (text) or the float32
    there (binary) with NaN."""
    i = min(int(position * len(data)), max(len(data) - 1, 0))
    if mutation == "truncate":
        return data[:i]
    if mutation == "flip":
        return data[:i] + payload + data[i + len(payload) :]
    if mutation == "nan":
        import re

        text = data.decode("latin-1")
        found = re.compile(r"-?\d+\.\d+(e[-+]?\d+)?").search(text, i) or re.compile(r"-?\d+\.\d+").search(
            text
        )
        if found and not text.startswith(("ply\nformat binary", "\x89MCAP")) and "DATA binary" not in text:
            return (text[: found.start()] + "nan" + text[found.end() :]).encode("latin-1")
        j = i - i % 4
        return data[:j] + np.array([np.nan], "<f4").tobytes() + data[j + 4 :]
    raise ValueError(f"unknown mutation {mutation!r}")


def read_back(kind: str, path: Path) -> Any:
    """Read ``path`` with the toolkit's reader for ``kind``; returns what it read."""
    if kind in ("ply_ascii", "ply_binary", "obj"):
        from rig.mesh_io import load_mesh

        return load_mesh(path)
    if kind.startswith("pcd") or kind == "kitti_bin":
        from calib.pointcloud_io import read_point_cloud

        return read_point_cloud(path)
    if kind in ("tum", "euroc"):
        from rig.trajectory_io import read_trajectory

        return read_trajectory(path, kind)
    if kind == "calib_yaml":
        from rig.calibration import load_calibration

        return load_calibration(path)
    if kind == "mcap":
        from rig.session import SessionReader, recover, session_info

        info = session_info(path)
        messages = sum(1 for _ in SessionReader(path).messages())
        salvage = recover(path, path.with_name(path.stem + "_fixed.mcap"))
        fixed = session_info(path.with_name(path.stem + "_fixed.mcap"))
        return {"info": info, "messages": messages, "salvage": salvage, "fixed": fixed}
    raise ValueError(f"unknown sample kind {kind!r}")


def _nonfinite_leak(kind: str, result: Any) -> str | None:
    """What non-finite or inconsistent data a reader returned, if any."""
    if kind in ("ply_ascii", "ply_binary", "obj"):
        bad = not np.all(np.isfinite(result.vertices))
    elif kind.startswith("pcd") or kind == "kitti_bin":
        bad = not np.all(np.isfinite(result.points))
    elif kind in ("tum", "euroc"):
        bad = not (np.all(np.isfinite(result.translations)) and np.all(np.isfinite(result.quaternions)))
    elif kind == "calib_yaml":
        bad = not (np.all(np.isfinite(result.T_cam_lidar)) and np.all(np.isfinite(result.camera.K)))
    else:
        if result["salvage"]["messages"] != result["info"]["messages"] or result["fixed"]["truncated"]:
            return (
                f"recover salvaged {result['salvage']['messages']} of {result['info']['messages']} messages"
            )
        return None
    return "returned NaN/Inf values" if bad else None


class time_limit:  # noqa: N801 (a context manager used like a function)
    """Raise :class:`TimeoutError` if the block runs longer than ``seconds`` (SIGALRM; main
    thread on POSIX only, elsewhere a no-op)."""

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        self._old: Any = None

    def __enter__(self) -> time_limit:
        import signal
        import threading

        if hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread():

            def expire(signum: int, frame: Any) -> None:
                raise TimeoutError(f"took longer than {self.seconds:g} s (a hang?)")

            self._old = signal.signal(signal.SIGALRM, expire)
            signal.setitimer(signal.ITIMER_REAL, self.seconds)
        return self

    def __exit__(self, *exc: object) -> None:
        import signal

        if self._old is not None:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, self._old)


def check_reader(
    kind: str, mutation: str, position: float, payload: bytes, workdir: Path
) -> tuple[list[str], bool]:
    """Mutate a valid ``kind`` file and read it back. Fine: it reads (and returns finite data),
    or raises an :class:`InputError` naming the file. Not fine: another exception (a library
    traceback), an InputError that does not say which file, NaN in the result, or a hang.
    Returns the problems and whether an InputError was raised."""
    source = write_sample(kind, workdir / f"valid{_suffix(kind)}")
    path = workdir / f"mutated{_suffix(kind)}"
    path.write_bytes(mutate(source.read_bytes(), mutation, position, payload))
    try:
        with time_limit(20.0):
            result = read_back(kind, path)
    except InputError as exc:
        if exc.path is None or Path(exc.path).name != path.name:
            return [f"{kind}/{mutation}: InputError does not name the file: {exc}"], True
        return [], True
    except TimeoutError as exc:
        return [f"{kind}/{mutation}@{position:.3f}: {exc}"], False
    except Exception as exc:
        where = traceback.extract_tb(exc.__traceback__)[-1]
        return [
            f"{kind}/{mutation}@{position:.3f}: {type(exc).__name__}: {str(exc)[:120]} "
            f"({Path(where.filename).name}:{where.lineno})"
        ], False
    leak = _nonfinite_leak(kind, result)
    return ([f"{kind}/{mutation}@{position:.3f}: {leak}"] if leak else []), False


# --------------------------------------------------------------------------------------------
# The suite

#: Cases per area for each profile.
PROFILES: dict[str, dict[str, int]] = {
    "ci": {
        "raster": 150,
        "raster_scale": 40,
        "raster_nonfinite": 20,
        "photometric": 60,
        "geometry": 80,
        "trajectory": 40,
        "time_offset": 6,
        "readers": 60,
    },
    "long": {
        "raster": 5000,
        "raster_scale": 1000,
        "raster_nonfinite": 200,
        "photometric": 1000,
        "geometry": 2000,
        "trajectory": 1000,
        "time_offset": 60,
        "readers": 1500,
    },
}


@dataclass
class AreaCounts:
    """Counts of one area: cases tried, failures found, non-finite events caught (a NaN/Inf or
    otherwise invalid input refused with an InputError), and the first failures' descriptions."""

    cases: int = 0
    failures: int = 0
    nonfinite_caught: int = 0
    seconds: float = 0.0
    examples: list[str] = field(default_factory=list)

    def add(self, problems: list[str], caught: bool = False) -> None:
        self.cases += 1
        self.nonfinite_caught += int(caught)
        if problems:
            self.failures += 1
            if len(self.examples) < 5:
                self.examples.extend(problems[: 5 - len(self.examples)])


def _guarded(fn: Callable[[], tuple[list[str], bool]]) -> tuple[list[str], bool]:
    try:
        return fn()
    except Exception as exc:  # a crash is a failure to count, not the end of the suite
        where = traceback.extract_tb(exc.__traceback__)[-1]
        return [f"{type(exc).__name__}: {str(exc)[:120]} ({Path(where.filename).name}:{where.lineno})"], False


def run_stability_suite(profile: str = "ci", seed: int = 0) -> dict[str, Any]:
    """Run the stress checks with a seeded random generator; counts per area.

    Returns ``{"profile", "seed", "seconds", "areas": {AREA: {"cases", "failures",
    "nonfinite_caught", "seconds", "examples"}}, "totals": {"cases", "failures",
    "nonfinite_caught"}}``. ``profile`` is ``"ci"`` (a few seconds) or ``"long"``.
    """
    if profile not in PROFILES:
        raise InputError(f"unknown profile {profile!r}; expected {' or '.join(PROFILES)}", field="profile")
    counts = PROFILES[profile]
    rng = np.random.default_rng(seed)
    areas: dict[str, AreaCounts] = {}
    start = time.perf_counter()

    def run(area: str, case: Callable[[], tuple[list[str], bool]]) -> None:
        c = areas.setdefault(area, AreaCounts())
        t0 = time.perf_counter()
        for _ in range(counts[area]):
            c.add(*_guarded(case))
        c.seconds = round(time.perf_counter() - t0, 3)

    run("raster", lambda: (check_raster(random_raster_case(rng)), False))
    run(
        "raster_scale",
        lambda: (check_raster_scale_invariance(_float64_regular(random_raster_case(rng))), False),
    )

    def raster_nonfinite() -> tuple[list[str], bool]:
        case = random_raster_case(rng)
        which = str(rng.choice(["vertices", "colors", "opacities", "sigma"]))
        problems = check_raster_rejects_nonfinite(case, which, float(rng.choice([np.nan, np.inf, -np.inf])))
        return problems, not problems

    run("raster_nonfinite", raster_nonfinite)

    def photometric() -> tuple[list[str], bool]:
        a, b = random_image_pair(rng)
        if rng.random() < 0.15:
            b = b.copy()
            b.flat[int(rng.integers(b.size))] = float(rng.choice([np.nan, np.inf]))
            try:
                check_photometric(a, b)
            except InputError:
                return [], True
            return ["non-finite image gave a number"], False
        return check_photometric(a, b), False

    run("photometric", photometric)
    run("geometry", lambda: check_point_sets(*random_point_sets(rng)))
    run("trajectory", lambda: (check_alignment(random_positions(rng), int(rng.integers(2**31))), False))
    run("time_offset", lambda: (check_time_offset(random_time_offset_case(rng)), False))
    with tempfile.TemporaryDirectory(prefix="lts-stability-") as tmp:

        def reader() -> tuple[list[str], bool]:
            kind = str(rng.choice(READER_KINDS))
            mutation = str(rng.choice(MUTATIONS))
            payload = rng.bytes(int(rng.integers(1, 9)))
            return check_reader(kind, mutation, float(rng.uniform()), payload, Path(tmp))

        run("readers", reader)
    result = {name: {**vars(c), "examples": list(c.examples)} for name, c in areas.items()}
    return {
        "profile": profile,
        "seed": seed,
        "seconds": round(time.perf_counter() - start, 3),
        "areas": result,
        "totals": {
            key: sum(c[key] for c in result.values()) for key in ("cases", "failures", "nonfinite_caught")
        },
    }


def _float64_regular(case: RasterCase) -> RasterCase:
    """The case in float64 with its near-plane grazers made regular: scale invariance is exact
    only up to rounding, and float32 projections of a vertex 1e-7 in front of the near plane
    lose digits differently at each scale."""
    import dataclasses

    kinds = tuple("regular" if k == "near_graze" else k for k in case.kinds)
    return dataclasses.replace(case, dtype="float64", kinds=kinds)


def bench_stability_command(
    profile: str = typer.Option("ci", "--profile", help="ci (a few seconds) or long (minutes)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the random cases."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Stress counts per area: cases tried, failures found, non-finite events caught (exit 1 on
    a failure)."""
    from rig.cli_support import console, emit_json

    result = run_stability_suite(profile, seed)
    if json_out:
        emit_json(result)
    else:
        for name, area in result["areas"].items():
            console.print(
                f"{name:18s} {area['cases']:6d} cases {area['failures']:4d} failures "
                f"{area['nonfinite_caught']:5d} non-finite caught  {area['seconds']:7.2f} s",
                highlight=False,
            )
            for example in area["examples"]:
                console.print(f"    {example}", highlight=False, markup=False)
    if result["totals"]["failures"]:
        raise SystemExit(1)
