"""Rasteriser stress area: random scenes of degenerate triangles (zero-area, needles, near-plane
grazers, edge-on, huge, behind the camera) at 1e-4 m to 1e4 m, sigma and opacity at their ends and
extreme intrinsics, rendered forward and backward by :func:`splat.raster.render`."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import torch

from rig.camera import CameraModel
from rig.errors import InputError
from splat.raster import render

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
#: Near plane of a 1 m scene (metres; scaled with the scene).
NEAR_M = 0.02
#: The differentiable outputs of :func:`~splat.raster.render` that the checks weigh.
RASTER_OUTPUTS = ("rgb", "accumulated_depth", "alpha", "normal", "median_depth", "distortion")


@dataclasses.dataclass(frozen=True)
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


def _torch_dtype(name: str) -> torch.dtype:
    return {"float32": torch.float32, "float64": torch.float64}[name]


def raster_camera(case: RasterCase) -> CameraModel:
    """The case's distortion-free pinhole :class:`~rig.camera.CameraModel`."""
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


def check_raster(case: RasterCase, backend: str = "cpu") -> list[str]:
    """Render the case forward and backward; the problems found (empty: none).

    Checked: every output and every gradient finite; alpha in [0, 1]; rgb in [0, 1] (colours
    are); depth, median depth and distortion >= 0; normals no longer than 1; per-face largest
    weight in [0, 1].
    """
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
    for name in ("accumulated_depth", "median_depth", "distortion"):
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
    for name, factor in (
        ("alpha", 1.0),
        ("rgb", 1.0),
        ("accumulated_depth", case.scale),
        ("median_depth", case.scale),
    ):
        a, b = getattr(unit, name).double() * factor, getattr(scaled, name).double()
        err = float((a - b).abs().max()) if a.numel() else 0.0
        if not err <= tol * factor:
            problems.append(f"{name} at scale {case.scale:g} differs from scale 1 by {err:.3g}")
    return problems


def check_raster_rejects_nonfinite(case: RasterCase, which: str, value: float) -> list[str]:
    """A NaN/Inf in ``which`` (vertices, colors, opacities or sigma) must be refused with an
    :class:`InputError` naming that input, before any kernel runs."""
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


def float64_regular(case: RasterCase) -> RasterCase:
    """The case in float64 with its near-plane grazers made regular: scale invariance is exact
    only up to rounding, and float32 projections of a vertex 1e-7 in front of the near plane
    lose digits differently at each scale."""
    kinds = tuple("regular" if k == "near_graze" else k for k in case.kinds)
    return dataclasses.replace(case, dtype="float64", kinds=kinds)


def stress_raster(rng: np.random.Generator) -> tuple[list[str], bool]:
    """One random case through :func:`check_raster`: its problems, and ``False`` (no input is
    invalid on purpose)."""
    return check_raster(random_raster_case(rng)), False


def stress_raster_scale(rng: np.random.Generator) -> tuple[list[str], bool]:
    """One random case (made :func:`float64_regular`) through :func:`check_raster_scale_invariance`:
    its problems, and ``False``."""
    return check_raster_scale_invariance(float64_regular(random_raster_case(rng))), False


def stress_raster_nonfinite(rng: np.random.Generator) -> tuple[list[str], bool]:
    """One random case with a NaN/Inf in one random input through
    :func:`check_raster_rejects_nonfinite`: its problems, and whether the value was refused."""
    case = random_raster_case(rng)
    which = str(rng.choice(["vertices", "colors", "opacities", "sigma"]))
    problems = check_raster_rejects_nonfinite(case, which, float(rng.choice([np.nan, np.inf, -np.inf])))
    return problems, not problems
