"""The compiled CPU kernel against the reference: outputs, gradients, edge cases, determinism."""

from __future__ import annotations

import pytest
import torch
from raster_cases import CAMERA, CASES, INPUTS, OUTPUTS, gradients, rel_l2, render_scene

from rig.errors import InputError
from splat.raster import render
from splat.raster.binning import bin_triangles
from splat.raster.extension import cpu_extension
from splat.raster.project import Intrinsics, project_triangles
from splat.raster.scenes import pinhole, random_scene

TOLERANCE = {torch.float64: 1e-5, torch.float32: 1e-3}
# Absolute floor for quantities that are zero in theory but rounding noise in practice (gradients
# of the distortion of a mesh whose faces do not overlap); real gradients here have norms >= 1.
FLOOR = {torch.float64: 1e-9, torch.float32: 1e-3}
DTYPES = pytest.mark.parametrize("dtype", [torch.float64, torch.float32], ids=["f64", "f32"])


def _finite(*tensors: torch.Tensor) -> bool:
    return all(bool(torch.isfinite(t).all()) for t in tensors)


@DTYPES
@pytest.mark.parametrize("case", sorted(CASES))
def test_outputs_match_the_reference(case: str, dtype: torch.dtype) -> None:
    scene = CASES[case](dtype)
    ref, _ = render_scene(scene, "reference")
    cpu, _ = render_scene(scene, "cpu")
    for name in (*OUTPUTS, "max_weight"):
        a, b = getattr(ref, name).detach(), getattr(cpu, name).detach()
        assert _finite(a, b), name
        err = rel_l2(a, b, FLOOR[dtype])
        assert err < TOLERANCE[dtype], f"{name}: {err:.2e}"
    assert float(ref.alpha.detach().max()) > 0
    # Discrete outputs agree wherever the dominant weight is not (numerically) tied.
    assert float((ref.dominant != cpu.dominant).float().mean()) < 0.01


@DTYPES
@pytest.mark.parametrize("case", sorted(CASES))
def test_gradients_match_the_reference(case: str, dtype: torch.dtype) -> None:
    scene = CASES[case](dtype)
    for name in OUTPUTS:
        ref = gradients(scene, "reference", name)
        cpu = gradients(scene, "cpu", name)
        for label, a, b in zip(INPUTS, ref, cpu, strict=True):
            assert _finite(a, b), f"d {name} / d {label} not finite"
            err = rel_l2(a, b, FLOOR[dtype])
            assert err < TOLERANCE[dtype], f"d {name} / d {label}: rel L2 {err:.2e}"


@pytest.mark.parametrize("case", ["mesh", "dense_opaque"])
def test_global_sigma_gradient_matches_the_reference(case: str) -> None:
    scene = CASES[case](torch.float64)
    for name in OUTPUTS:
        ref = gradients(scene, "reference", name, global_sigma=True)[3]
        cpu = gradients(scene, "cpu", name, global_sigma=True)[3]
        assert ref.shape == () and rel_l2(ref, cpu, FLOOR[torch.float64]) < 1e-5, name


def test_dense_opaque_scene_saturates() -> None:
    out, _ = render_scene(CASES["dense_opaque"](torch.float64), "cpu")
    alpha = out.alpha.detach()
    # Early stop leaves transmittance >= 1e-4: accumulated alpha stays at most 1 - 1e-4.
    assert float(alpha.max()) > 0.999
    assert float(alpha.max()) <= 1 - 1e-4 + 1e-12


def test_edge_cases_are_culled_without_garbage() -> None:
    scene = CASES["edges"](torch.float64)
    out, leaves = render_scene(scene, "cpu")
    seen = out.max_weight > 0
    # Zero-area, collinear, near-plane-crossing and edge-on triangles are culled; the ordinary
    # ones, the sharp/soft ones and the one larger than the image are drawn.
    assert seen.tolist() == [True, False, False, False, True, True, False]
    assert bool((out.alpha > 0).all())  # the huge triangle covers the whole image
    sum(getattr(out, n).sum() for n in OUTPUTS).backward()
    assert all(_finite(leaf.grad) for leaf in leaves)
    assert float(leaves[0].grad[3:12].abs().max()) == 0.0  # culled faces get no gradient


@pytest.mark.parametrize("backend", ["reference", "cpu"])
def test_empty_and_transparent_scenes_render_nothing(backend: str) -> None:
    scene = CASES["random"](torch.float64)
    for faces, opacity in ((scene.faces[:0], 1.0), (scene.faces, 1 / 256)):
        v = scene.vertices.clone().requires_grad_(True)
        out = render(
            v, faces, scene.colors, torch.full_like(scene.opacities, opacity), 1.0, CAMERA, backend=backend
        )
        assert float(out.alpha.detach().abs().max()) == 0.0 and bool((out.dominant == -1).all())
        (out.rgb.sum() + out.accumulated_depth.sum()).backward()
        assert float(v.grad.abs().max()) == 0.0


@pytest.mark.parametrize("field", ["vertices", "colors", "opacities", "sigma"])
def test_nan_input_is_a_clear_error(field: str) -> None:
    scene = CASES["random"](torch.float32)
    inputs = {
        "vertices": scene.vertices,
        "colors": scene.colors,
        "opacities": scene.opacities,
        "sigma": scene.sigma,
    }
    inputs[field] = inputs[field].clone()
    inputs[field].view(-1)[4] = float("nan")
    with pytest.raises(InputError, match=f"{field}: contains NaN"):
        render(
            inputs["vertices"], scene.faces, inputs["colors"], inputs["opacities"], inputs["sigma"], CAMERA
        )


def test_bad_arguments_are_clear_errors() -> None:
    scene = CASES["random"](torch.float32)
    v, f, c, o, s = scene.tensors()
    with pytest.raises(InputError, match="faces"):
        render(v, f + len(v), c, o, s, CAMERA)
    with pytest.raises(InputError, match="sigma: must be > 0"):
        render(v, f, c, o, 0.0, CAMERA)
    with pytest.raises(InputError, match="backend"):
        render(v, f, c, o, s, CAMERA, backend="cuda")


def test_cpu_kernel_is_deterministic() -> None:
    camera = pinhole(96, 64)
    scene = random_scene(3000, camera, seed=9)

    def run():
        leaves = [
            t.clone().requires_grad_(True)
            for t in (scene.vertices, scene.colors, scene.opacities, scene.sigma)
        ]
        out = render(leaves[0], scene.faces, *leaves[1:], camera)
        loss = sum((getattr(out, n) * (i + 1)).sum() for i, n in enumerate(OUTPUTS))
        loss.backward()
        return [getattr(out, n) for n in (*OUTPUTS, "dominant", "max_weight")] + [x.grad for x in leaves]

    first, second = run(), run()
    assert all(torch.equal(a, b) for a, b in zip(first, second, strict=True))


def test_pose_gradient_matches_the_reference() -> None:
    scene = CASES["random"](torch.float64)
    x, y, z = 0.03, -0.05, 0.08  # small rotation vector
    R = torch.linalg.matrix_exp(torch.tensor([[0, -z, y], [z, 0, -x], [-y, x, 0]], dtype=torch.float64))
    pose = torch.eye(4, dtype=torch.float64)
    pose[:3, :3], pose[:3, 3] = R, torch.tensor([0.05, -0.02, 0.1], dtype=torch.float64)
    grads = []
    for backend in ("reference", "cpu"):
        T = pose.clone().requires_grad_(True)
        out = render(*scene.tensors(), CAMERA, T, backend=backend)
        (out.rgb.sum() + out.accumulated_depth.sum()).backward()
        grads.append(T.grad)
    assert float(grads[0].norm()) > 0
    assert rel_l2(*grads) < 1e-5


def test_cpu_binning_matches_the_pytorch_binning() -> None:
    camera = pinhole(100, 70)  # not a multiple of the tile size
    scene = random_scene(2000, camera, size_px=(1.0, 60.0), seed=4)
    intr = Intrinsics(camera.fx, camera.fy, camera.cx, camera.cy, camera.width, camera.height)
    tris = project_triangles(*scene.tensors(), torch.eye(4), intr, 0.02)
    ours = bin_triangles(tris.bounds, camera.width, camera.height, cpu_extension())
    spec = bin_triangles(tris.bounds, camera.width, camera.height)
    for name in ("tile_offsets", "tile_slots", "slot_tri", "tri_offsets"):
        assert torch.equal(getattr(ours, name), getattr(spec, name)), name
    assert len(spec.tile_slots) > len(tris.bounds)
