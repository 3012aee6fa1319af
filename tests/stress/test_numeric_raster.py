"""Numerical stability of the rasteriser (CPU kernel; the reference where said), float32/float64:
degenerate triangles, 1e-4 m to 1e4 m scenes, the near plane, sigma and opacity at their ends,
extreme intrinsics. Outputs and gradients stay finite and in range; NaN/Inf inputs are refused."""

from __future__ import annotations

import pytest
import torch
from conftest import examples
from hypothesis import given
from hypothesis import strategies as st

from lts.stress.raster import (
    OPACITY_ENDS,
    SCALES,
    SIGMA_ENDS,
    TRIANGLE_KINDS,
    RasterCase,
    check_raster,
    check_raster_rejects_nonfinite,
    check_raster_scale_invariance,
    float64_regular,
)
from rig.camera import CameraModel
from splat.raster import render
from splat.raster.extension import cpu_extension
from splat.raster.project import Intrinsics, project_triangles
from splat.raster.setup_kernel import project_triangles_kernel


@st.composite
def raster_cases(draw: st.DrawFn) -> RasterCase:
    n = draw(st.integers(1, 6))
    kinds = st.sampled_from(TRIANGLE_KINDS)
    sigma = st.one_of(st.sampled_from(SIGMA_ENDS), st.floats(0.05, 3.0))
    opacity = st.one_of(st.sampled_from(OPACITY_ENDS), st.floats(0.0, 1.0))
    width, height = draw(st.integers(1, 40)), draw(st.integers(1, 40))
    focal = draw(st.one_of(st.floats(10.0, 60.0), st.floats(-2.0, 10.0).map(lambda e: 10.0**e)))
    return RasterCase(
        dtype=draw(st.sampled_from(["float32", "float64"])),
        scale=draw(st.sampled_from(SCALES)),
        kinds=tuple(draw(kinds) for _ in range(n)),
        sigma=tuple(draw(sigma) for _ in range(n)),
        opacity=tuple(o for _ in range(n) for o in [draw(opacity)] * 3),
        width=width,
        height=height,
        fx=focal,
        fy=focal * draw(st.floats(0.3, 3.0)),
        cx=draw(st.floats(-0.5, 1.5)) * width,
        cy=draw(st.floats(-0.5, 1.5)) * height,
        seed=draw(st.integers(0, 2**31 - 1)),
    )


@examples(300)
@given(raster_cases())
def test_outputs_and_gradients_stay_finite_and_in_range(case: RasterCase) -> None:
    assert check_raster(case) == []


@examples(60)
@given(raster_cases())
def test_reference_backend_too(case: RasterCase) -> None:
    assert check_raster(case, backend="reference") == []


@examples(80)
@given(raster_cases())
def test_a_tiny_or_huge_scene_renders_like_a_one_metre_one(case: RasterCase) -> None:
    assert check_raster_scale_invariance(float64_regular(case)) == []


@examples(20)
@given(
    raster_cases(),
    st.sampled_from(["vertices", "colors", "opacities", "sigma"]),
    st.sampled_from([float("nan"), float("inf"), float("-inf")]),
)
def test_nonfinite_inputs_are_refused_naming_the_input(case: RasterCase, which: str, value: float) -> None:
    assert check_raster_rejects_nonfinite(case, which, value) == []


@pytest.mark.parametrize("sigma", SIGMA_ENDS)
@pytest.mark.parametrize("opacity", OPACITY_ENDS)
@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_every_kind_at_the_ends_of_sigma_and_opacity(sigma: float, opacity: float, dtype: str) -> None:
    for scale in SCALES:
        case = RasterCase(
            dtype, scale, TRIANGLE_KINDS, (sigma,) * len(TRIANGLE_KINDS), (opacity,) * 3 * len(TRIANGLE_KINDS)
        )
        assert check_raster(case) == [], scale


# Regressions ----------------------------------------------------------------------------------


def _one_triangle(vertices, fx: float, sigma: float, dtype: torch.dtype):
    camera = CameraModel("pinhole", 24, 20, [[fx, 0, 12], [0, fx, 10], [0, 0, 1]], [])
    v = torch.tensor(vertices, dtype=dtype)
    return (
        v,
        torch.tensor([[0, 1, 2]]),
        torch.full((3, 3), 0.5, dtype=dtype),
        torch.ones(3, dtype=dtype),
        camera,
        sigma,
    )


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("backend", ["cpu", "reference"])
def test_support_box_billions_of_pixels_off_the_image_is_empty_not_a_crash(
    backend: str, dtype: torch.dtype
) -> None:
    """Bug: a visible triangle whose support (the region alpha >= 1/255, shrunk about the
    incentre) lay > 2^31 px off the image had its pixel box cast from float to int32 unclamped:
    undefined, INT_MIN on x86, a box 2^31 px wide that the CPU binning walked out of bounds
    (segmentation fault). Fix: clamp both box corners to [-1, size] before the cast."""
    v, f, c, o, camera, sigma = _one_triangle([[0, 0, 1], [10, 0, 1], [10, 10, 1]], 1e9, 50.0, dtype)
    intr = Intrinsics(1e9, 1e9, 12, 10, 24, 20)
    args = (v, f, c, o, torch.tensor([sigma], dtype=dtype), torch.eye(4, dtype=dtype), intr, 0.02)
    for tris in (project_triangles(*args), project_triangles_kernel(*args, cpu_extension())):
        x0, y0, x1, y1 = tris.bounds[0].tolist()
        assert -1 <= x1 < x0 <= 24 or -1 <= y1 < y0 <= 20  # empty, inside the int range
    out = render(v, f, c, o, sigma, camera, backend=backend)
    assert bool(torch.isfinite(out.alpha).all())


@pytest.mark.parametrize("backend", ["cpu", "reference"])
def test_float32_projection_overflow_is_culled_alike_by_both_backends(backend: str) -> None:
    """Bug: a float32 vertex so far off axis that its projection overflowed passed the reference
    culling (inf compares >= anything) and then made NaN boxes: a 1e17-byte allocation. The
    kernel culled it (NaN compares false): the two disagreed. Fix: cull non-finite projections
    in both."""
    v, f, c, o, _, _ = _one_triangle(
        [[0, 0, 1], [1e30, 0, 0.0201], [1e30, 1e28, 0.0201]], 100.0, 5.0, torch.float32
    )
    camera = CameraModel("pinhole", 24, 20, [[100, 0, 12], [0, 100, 10], [0, 0, 1]], [])
    out = render(v, f, c, o, 5.0, camera, backend=backend)
    assert float(out.max_weight[0]) == 0.0 and bool(torch.isfinite(out.alpha).all())


@pytest.mark.parametrize("backend", ["cpu", "reference"])
def test_float32_normal_of_a_tiny_triangle_is_a_unit_vector(backend: str) -> None:
    """Bug: the unit normal divided the cross product of the edges by sqrt(N.N); for float32
    triangles with ~1e-13 m edges (a 1e-4 m scene seen with a 1e9 px focal length) N.N underflows
    to 0: normals and every vertex gradient became inf/NaN. Fix: scale N by its largest
    component before squaring (safe_length / _length)."""
    s = 2e-13
    case = dict(
        vertices=torch.tensor([[0.0, 0.0, 5e-4], [s, 0.0, 5e-4], [0.0, s, 5e-4]], dtype=torch.float32),
        camera=CameraModel("pinhole", 24, 20, [[1e10, 0, 2], [0, 1e10, 2], [0, 0, 1]], []),
    )
    v = case["vertices"].clone().requires_grad_(True)
    out = render(
        v, torch.tensor([[0, 1, 2]]), torch.full((3, 3), 0.5), torch.ones(3), 1.0, case["camera"],
        near=2e-6, backend=backend,
    )  # fmt: skip
    assert float(out.max_weight[0]) > 0  # drawn, not culled
    seen = out.alpha.detach() > 0
    lengths = out.normal.detach()[seen].norm(dim=-1) / out.alpha.detach()[seen]
    assert torch.allclose(lengths, torch.ones_like(lengths), atol=1e-4)
    (grad,) = torch.autograd.grad(out.normal.sum() + out.rgb.sum() + out.accumulated_depth.sum(), [v])
    assert bool(torch.isfinite(grad).all())
