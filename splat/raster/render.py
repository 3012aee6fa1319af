"""The public entry point: render triangles from one camera, choosing the backend by device."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch
from torch import Tensor

from rig.camera import CameraModel
from rig.errors import InputError
from splat.finite import all_finite
from splat.raster.binning import bin_triangles
from splat.raster.extension import cpu_extension, cuda_extension
from splat.raster.kernel import rasterize_kernel
from splat.raster.project import Intrinsics, project_triangles
from splat.raster.reference import rasterize_reference
from splat.raster.setup_kernel import project_triangles_kernel
from splat.raster.stats import DominantSums, dominant_sums

Backend = Literal["auto", "cpu", "cuda", "reference"]


@dataclass
class RenderOutput:
    """Everything one render produces (``H, W`` image size, ``F`` faces).

    Attributes:
        rgb: ``(H, W, 3)`` sum of w c (black background; add ``bg * (1 - alpha)`` for another).
        accumulated_depth: ``(H, W)`` sum of w z, camera depth (metres) not divided by alpha; see
            :meth:`expected_depth` for the depth itself.
        alpha: ``(H, W)`` accumulated opacity sum of w.
        normal: ``(H, W, 3)`` sum of w n, camera frame, normals facing the camera.
        median_depth: ``(H, W)`` depth of the triangle where transmittance crosses 0.5 (0: none).
        distortion: ``(H, W)`` 2DGS depth distortion sum_{i<j} w_i w_j (z_i - z_j)^2.
        dominant: ``(H, W)`` int64 face with the largest weight at each pixel, -1 for none.
        max_weight: ``(F,)`` largest blending weight of each face over the image (0 if unseen).
    """

    rgb: Tensor
    accumulated_depth: Tensor
    alpha: Tensor
    normal: Tensor
    median_depth: Tensor
    distortion: Tensor
    dominant: Tensor
    max_weight: Tensor

    def expected_depth(self) -> Tensor:
        """``(H, W)`` expected depth ``sum w z / sum w`` (metres; 0 where no triangle is seen)."""
        hit = self.alpha > 0
        return torch.where(hit, self.accumulated_depth / torch.where(hit, self.alpha, 1.0), 0.0)

    def dominant_sums(self, values: Tensor, valid: Tensor) -> DominantSums:
        """Count, sum and sum of squares ``(F,)`` of the per-pixel ``values`` ``(H, W)`` over the
        ``valid`` ``(H, W)`` pixels each face dominates (no gradient)."""
        return dominant_sums(self.dominant, values, valid, len(self.max_weight))


def _intrinsics(camera: CameraModel) -> Intrinsics:
    if camera.model != "pinhole" or np.any(camera.dist):
        raise InputError(
            "the rasteriser needs a distortion-free pinhole camera; undistort the images and use "
            "camera.undistorted()",
            field="camera",
        )
    return Intrinsics(camera.fx, camera.fy, camera.cx, camera.cy, int(camera.width), int(camera.height))


def _check(name: str, t: Tensor, shape: tuple[int | None, ...], dtype: torch.dtype | None) -> None:
    if t.dim() != len(shape) or any(s is not None and s != n for s, n in zip(shape, t.shape, strict=True)):
        want = "x".join("N" if s is None else str(s) for s in shape) or "scalar"
        raise InputError(f"expected shape ({want}), got {tuple(t.shape)}", field=name)
    if dtype is not None and t.dtype != dtype:
        raise InputError(f"expected dtype {dtype}, got {t.dtype}", field=name)
    if not all_finite(t):
        raise InputError("contains NaN or Inf", field=name)


def _select_backend(backend: Backend, device: torch.device) -> str:
    if backend == "auto":
        return "cuda" if device.type == "cuda" else "cpu"
    if backend in ("cpu", "cuda") and device.type != backend:
        raise InputError(f"backend {backend!r} needs {backend} tensors, got {device.type}", field="backend")
    if backend not in ("cpu", "cuda", "reference"):
        raise InputError(
            f"unknown backend {backend!r}; expected auto, cpu, cuda or reference", field="backend"
        )
    return backend


def render(
    vertices: Tensor,
    faces: Tensor,
    colors: Tensor,
    opacities: Tensor,
    sigma: Tensor | float,
    camera: CameraModel,
    T_cam_world: Tensor | None = None,
    *,
    near: float = 0.02,
    backend: Backend = "auto",
) -> RenderOutput:
    """Render triangles with Triangle Splatting (TS+) windows, differentiably.

    Args:
        vertices: ``(V, 3)`` float32/float64 world points (shared or per-triangle vertices).
        faces: ``(F, 3)`` int64 indices into ``vertices``.
        colors: ``(V, 3)`` vertex colours (barycentric inside a triangle).
        opacities: ``(V,)`` vertex opacities in [0, 1]; a triangle uses the min of its three.
        sigma: window sharpness, a scalar or ``(F,)`` per face, > 0.
        camera: distortion-free pinhole camera (image size and intrinsics).
        T_cam_world: ``(4, 4)`` world-to-camera transform (OpenCV camera frame); identity if None.
        near: triangles with a vertex closer than this (metres) are culled.
        backend: ``"auto"`` picks the compiled kernel for the tensors' device; ``"cpu"``/``"cuda"``
            force one; ``"reference"`` is the slow pure-PyTorch specification (opt-in only).

    Returns:
        A :class:`RenderOutput`; gradients flow to vertices, colours, opacities and sigma.

    Raises:
        InputError: malformed or non-finite inputs. BackendUnavailableError: the compiled backend
        cannot be built here (the message names the missing compiler or package).
    """
    intr = _intrinsics(camera)
    _check("vertices", vertices, (None, 3), None)
    if not vertices.is_floating_point():
        raise InputError(f"expected a float32 or float64 tensor, got {vertices.dtype}", field="vertices")
    dtype, device = vertices.dtype, vertices.device
    _check("faces", faces, (None, 3), torch.int64)
    if len(faces) and (int(faces.min()) < 0 or int(faces.max()) >= len(vertices)):
        raise InputError(f"indices must lie in [0, {len(vertices)})", field="faces")
    _check("colors", colors, (len(vertices), 3), dtype)
    _check("opacities", opacities, (len(vertices),), dtype)
    sigma = torch.as_tensor(sigma, dtype=dtype, device=device)
    if sigma.dim() == 0:
        sigma = sigma.expand(len(faces))
    _check("sigma", sigma, (len(faces),), dtype)
    if len(sigma) and not bool((sigma > 0).all()):
        raise InputError("must be > 0", field="sigma")
    if T_cam_world is None:
        T_cam_world = torch.eye(4, dtype=dtype, device=device)
    _check("T_cam_world", T_cam_world, (4, 4), dtype)
    chosen = _select_backend(backend, device)

    geometry = (vertices, faces, colors, opacities, sigma, T_cam_world, intr, near)
    if chosen == "reference":
        tris = project_triangles(*geometry)
        bins = bin_triangles(tris.bounds, intr.width, intr.height)
        images = rasterize_reference(tris.params, bins, intr.width, intr.height)
    else:
        ext = cpu_extension() if chosen == "cpu" else cuda_extension()
        tris = project_triangles_kernel(*geometry, ext)
        bins = bin_triangles(tris.bounds, intr.width, intr.height, ext if chosen == "cpu" else None)
        images = rasterize_kernel(tris.params, tris.bounds, bins, intr.width, intr.height, ext)

    # -1 (no triangle) indexes the appended -1.
    dominant = torch.cat([tris.index, tris.index.new_full((1,), -1)])[images.dominant]
    max_weight = torch.zeros(len(faces), dtype=dtype, device=device)
    max_weight[tris.index] = images.max_weight.detach()
    return RenderOutput(
        images.rgb, images.accumulated_depth, images.alpha, images.normal, images.median,
        images.distortion, dominant, max_weight,
    )  # fmt: skip
