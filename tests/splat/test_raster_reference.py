"""The pure-PyTorch reference rasteriser: rendering semantics and finite-difference gradients."""

from __future__ import annotations

import math

import pytest
import torch
from raster_cases import CAMERA, INPUTS, OUTPUTS, gradients, random_case, rel_l2, weighted

from splat.raster import render
from splat.strategy.variance import depth_error, normal_error

F64 = torch.float64


def _triangle(z: float = 2.0, opacity: float = 1.0, sigma: float = 1.0, offset=(0.0, 0.0)) -> list:
    """A fronto-parallel triangle about 24 px wide near the image centre."""
    x0, y0 = offset
    s = 0.7 * z / 2.0
    return [[x0 - s, y0 + s / 2, z], [x0 + s, y0 + s / 2, z], [x0, y0 - s, z]], opacity, sigma


def _render(tris: list, backend: str, colors=None):
    vertices = torch.tensor([v for t in tris for v in t[0]], dtype=F64)
    n = len(tris)
    colors = (
        torch.rand(3 * n, 3, dtype=F64, generator=torch.Generator().manual_seed(0))
        if colors is None
        else colors
    )
    opac = torch.tensor([t[1] for t in tris for _ in range(3)], dtype=F64)
    sigma = torch.tensor([t[2] for t in tris], dtype=F64)
    return render(vertices, torch.arange(3 * n).reshape(n, 3), colors, opac, sigma, CAMERA, backend=backend)


@pytest.fixture(params=["reference", "cpu"])
def backend(request) -> str:
    return request.param


def test_window_is_one_at_the_incentre_and_zero_outside(backend: str) -> None:
    out = _render([_triangle(opacity=0.5)], backend)
    # The window peaks at 1 (alpha = o) near the incentre and vanishes outside the triangle.
    assert 0.45 < float(out.alpha.max()) <= 0.5
    inside = out.alpha > 0
    assert 0 < int(inside.sum()) < 0.5 * CAMERA.width * CAMERA.height
    assert not bool(inside[0].any()) and not bool(inside[:, 0].any())
    assert bool((out.alpha[inside] >= 1 / 255 - 1e-12).all())
    assert bool((out.dominant[inside] == 0).all()) and bool((out.dominant[~inside] == -1).all())
    assert float(out.max_weight[0]) == pytest.approx(float(out.alpha.max()))


def test_opacity_clamps_at_099_and_sigma_sharpens(backend: str) -> None:
    assert float(_render([_triangle(opacity=1.0, sigma=0.05)], backend).alpha.max()) == pytest.approx(0.99)
    soft = _render([_triangle(sigma=5.0)], backend).alpha
    sharp = _render([_triangle(sigma=1e-4)], backend).alpha
    # sigma -> 0 gives a solid triangle (alpha 0.99 on every covered pixel); sigma = 5 a small core.
    assert float(sharp[sharp > 0].min()) == pytest.approx(0.99)
    assert int((soft > 0).sum()) < int((sharp > 0).sum())


def test_front_to_back_order_by_depth_not_by_face_order(backend: str) -> None:
    # Opaque, sharp windows: alpha is exactly the 0.99 clamp wherever a triangle covers a pixel.
    near, far = _triangle(z=2.0, sigma=1e-4), _triangle(z=3.0, sigma=1e-4)
    colors = torch.tensor([[1.0, 0, 0]] * 3 + [[0, 0, 1.0]] * 3, dtype=F64)
    out = _render([far, near], backend, colors)
    w_near, w_far = 0.99, 0.99 * (1 - 0.99)
    both = (out.alpha - (w_near + w_far)).abs() < 1e-12
    n = int(both.sum())
    assert n > 10
    # The near triangle (face 1, blue) composites first although it is listed second.
    torch.testing.assert_close(out.rgb[both], torch.tensor([[w_far, 0.0, w_near]], dtype=F64).expand(n, 3))
    torch.testing.assert_close(
        out.accumulated_depth[both], torch.full((n,), w_near * 2 + w_far * 3, dtype=F64)
    )
    assert bool((out.dominant[both] == 1).all())
    # T = 0.01 < 0.5 behind the near triangle: the median is its depth.
    torch.testing.assert_close(out.median_depth[both], torch.full((n,), 2.0, dtype=F64))
    # 2DGS distortion: w1 w2 (z1 - z2)^2
    torch.testing.assert_close(out.distortion[both], torch.full((n,), w_near * w_far, dtype=F64))


def test_depth_is_perspective_correct_and_normals_face_the_camera(backend: str) -> None:
    # A plane through (0, 0, 2) with normal (0, 0.6, -0.8) (tilted, facing the camera).
    n = torch.tensor([0.0, 0.6, -0.8], dtype=F64)
    a, b = torch.tensor([1.0, 0, 0], dtype=F64), torch.linalg.cross(n, torch.tensor([1.0, 0, 0], dtype=F64))
    c = torch.tensor([0.0, 0.0, 2.0], dtype=F64)
    pts = [c + 0.6 * (math.cos(t) * a + math.sin(t) * b) for t in (0.3, 2.4, 4.4)]
    reverse = [pts[0], pts[2], pts[1]]  # the other winding: the normal must still face the camera
    for tri in (pts, reverse):
        out = _render([([p.tolist() for p in tri], 1.0, 1e-4)], backend)
        hit = out.alpha > 0
        ys, xs = torch.nonzero(hit, as_tuple=True)
        rays = torch.stack(
            [(xs - CAMERA.cx) / CAMERA.fx, (ys - CAMERA.cy) / CAMERA.fy, torch.ones_like(xs, dtype=F64)], -1
        )
        plane_depth = (n @ c) / (rays @ n)
        torch.testing.assert_close(out.expected_depth()[hit], plane_depth)
        assert not bool(out.expected_depth()[~hit].any())
        torch.testing.assert_close(out.normal[hit] / out.alpha[hit, None], n.expand(len(xs), 3))


def test_sums_of_the_geometric_errors_over_dominated_pixels(backend: str) -> None:
    vertices, faces = (
        torch.tensor([v for v in _triangle(opacity=1.0, sigma=0.3)[0]], dtype=F64),
        torch.arange(3)[None],
    )
    target = torch.full((CAMERA.height, CAMERA.width), 2.5, dtype=F64)
    target[:, : CAMERA.width // 2] = 0.0  # no LiDAR return on the left half
    normal_target = torch.zeros(CAMERA.height, CAMERA.width, 3, dtype=F64)
    normal_target[..., 2] = -1.0
    out = render(
        vertices, faces, torch.ones(3, 3, dtype=F64), torch.ones(3, dtype=F64), 0.3, CAMERA,
        backend=backend,
    )  # fmt: skip
    depth_sums = out.dominant_sums(*depth_error(out, target))
    known = torch.ones(CAMERA.height, CAMERA.width, dtype=torch.bool)
    normal_sums = out.dominant_sums(*normal_error(out, normal_target, known))
    owned = (out.dominant == 0) & (target > 0)
    err = (target - out.accumulated_depth)[owned]
    assert int(depth_sums.count[0]) == int(owned.sum()) > 0
    assert float(depth_sums.sum[0]) == pytest.approx(float(err.sum()))
    assert float(depth_sums.sum_sq[0]) == pytest.approx(float((err**2).sum()))
    # The rendered normal is (0, 0, -1) scaled by alpha: unit normal error 0 on every owned pixel.
    assert int(normal_sums.count[0]) == int((out.dominant == 0).sum())
    assert float(normal_sums.sum_sq[0]) == pytest.approx(0.0, abs=1e-20)
    assert float(depth_sums.variance()[0]) == pytest.approx(float(err.var(unbiased=False)))


# Which inputs each output depends on smoothly (colours only reach rgb; the median depth is the
# depth of one triangle, so only its vertices move it).
DEPENDS = {name: ("vertices", "opacities", "sigma") for name in OUTPUTS} | {
    "rgb": ("vertices", "colors", "opacities", "sigma"),
    "median_depth": ("vertices",),
}


@pytest.mark.parametrize("name", OUTPUTS)
def test_reference_gradients_match_central_differences(name: str) -> None:
    """Directional derivatives along random directions, per input, in float64."""
    scene = random_case(F64)
    analytic = gradients(scene, "reference", name)
    g = torch.Generator().manual_seed(1)
    eps = 1e-6
    for label, leaf, grad in zip(
        INPUTS, [scene.vertices, scene.colors, scene.opacities, scene.sigma], analytic, strict=True
    ):
        fd, an = [], []
        for _ in range(3):
            u = torch.randn(leaf.shape, generator=g, dtype=F64)
            losses = []
            for sign in (1.0, -1.0):
                shifted = {k: getattr(scene, k) for k in INPUTS} | {label: leaf + sign * eps * u}
                with torch.no_grad():
                    out = render(
                        shifted["vertices"], scene.faces, shifted["colors"], shifted["opacities"],
                        shifted["sigma"], scene.camera, backend="reference",
                    )  # fmt: skip
                losses.append(float(weighted(out, name, seed=7)))
            fd.append((losses[0] - losses[1]) / (2 * eps))
            an.append(float((grad * u).sum()))
        fd_t, an_t = torch.tensor(fd), torch.tensor(an)
        if label in DEPENDS[name]:
            assert float(an_t.norm()) > 0, f"{name} should depend on {label}"
        assert rel_l2(an_t, fd_t) < 1e-5, f"d {name} / d {label}: {an} vs {fd}"
