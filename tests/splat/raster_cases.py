"""Small scenes and helpers shared by the rasteriser tests."""

from __future__ import annotations

import torch
from torch import Tensor

from splat.raster import RenderOutput, render
from splat.raster.scenes import TriangleScene, pinhole, random_scene

CAMERA = pinhole(48, 32)
OUTPUTS = ("rgb", "accumulated_depth", "alpha", "normal", "median_depth", "distortion")
INPUTS = ("vertices", "colors", "opacities", "sigma")


def _scene(vertices, faces, colors, opacities, sigma, dtype) -> TriangleScene:
    as_t = lambda x: torch.as_tensor(x, dtype=dtype)  # noqa: E731
    return TriangleScene(
        as_t(vertices).reshape(-1, 3),
        torch.as_tensor(faces, dtype=torch.int64).reshape(-1, 3),
        as_t(colors).reshape(-1, 3),
        as_t(opacities).reshape(-1),
        as_t(sigma).reshape(-1),
        CAMERA,
    )


def random_case(dtype: torch.dtype) -> TriangleScene:
    """40 semi-transparent triangles of 4-30 px."""
    return random_scene(40, CAMERA, size_px=(4.0, 30.0), seed=3, dtype=dtype)


def dense_opaque_case(dtype: torch.dtype) -> TriangleScene:
    """30 large, nearly opaque triangles: alpha hits the 0.99 clamp and pixels saturate."""
    s = random_scene(
        30, CAMERA, size_px=(30.0, 60.0), opacity=(0.995, 1.0), sigma=(0.2, 1.0), seed=5, dtype=dtype
    )
    return s


def mesh_case(dtype: torch.dtype) -> TriangleScene:
    """A bumpy grid mesh whose faces share vertices (index buffer), with per-face sigma."""
    g = torch.Generator().manual_seed(11)
    n = 6
    ys, xs = torch.meshgrid(torch.linspace(-1, 1, n), torch.linspace(-1.4, 1.4, n), indexing="ij")
    z = 2.5 + 0.3 * torch.rand(n, n, generator=g) + 0.5 * xs
    vertices = torch.stack([xs, ys, z], -1).reshape(-1, 3)
    faces = []
    for i in range(n - 1):
        for j in range(n - 1):
            a, b, c, d = i * n + j, i * n + j + 1, (i + 1) * n + j, (i + 1) * n + j + 1
            faces += [[a, b, c], [b, d, c]]
    nv = len(vertices)
    return _scene(
        vertices,
        faces,
        torch.rand(nv, 3, generator=g),
        0.4 + 0.6 * torch.rand(nv, generator=g),
        0.5 + torch.rand(len(faces), generator=g),
        dtype,
    )


def edge_case(dtype: torch.dtype) -> TriangleScene:
    """Degenerate and extreme triangles beside ordinary ones."""
    tris = [
        [[0.0, 0.0, 2.0], [0.3, 0.0, 2.0], [0.0, 0.3, 2.0]],  # ordinary
        [[0.1, 0.1, 2.0], [0.1, 0.1, 2.0], [0.4, 0.2, 2.1]],  # zero area (repeated vertex)
        [[-0.2, 0.0, 2.0], [0.0, 0.1, 2.0], [0.2, 0.2, 2.0]],  # collinear
        [[-0.3, -0.2, -0.5], [0.3, -0.2, 1.5], [0.0, 0.3, 1.5]],  # crosses the near plane
        [[-20.0, -20.0, 5.0], [30.0, -20.0, 5.0], [0.0, 30.0, 5.0]],  # larger than the image
        [[-0.5, -0.3, 1.8], [0.2, -0.3, 1.6], [-0.2, 0.2, 1.7]],  # ordinary, tilted
        [[0.0, -0.5, 2.0], [0.0, 0.5, 2.0], [0.0, 0.0, 3.0]],  # edge-on (plane through camera)
    ]
    n = len(tris)
    g = torch.Generator().manual_seed(2)
    sigma = torch.full((n,), 1.0)
    sigma[0], sigma[5] = 1e-4, 5.0
    return _scene(
        tris, torch.arange(3 * n), torch.rand(3 * n, 3, generator=g), torch.full((3 * n,), 0.7), sigma, dtype
    )


CASES = {"random": random_case, "dense_opaque": dense_opaque_case, "mesh": mesh_case, "edges": edge_case}


def render_scene(
    scene: TriangleScene, backend: str, global_sigma: bool = False
) -> tuple[RenderOutput, list[Tensor]]:
    """Render with fresh leaf tensors; returns the output and the leaves (vertices, colours,
    opacities, sigma)."""
    sigma = scene.sigma[:1].mean() if global_sigma else scene.sigma
    leaves = [
        t.detach().clone().requires_grad_(True)
        for t in (scene.vertices, scene.colors, scene.opacities, sigma)
    ]
    v, c, o, s = leaves
    return render(v, scene.faces, c, o, s, scene.camera, backend=backend), leaves


def weighted(out: RenderOutput, name: str, seed: int) -> Tensor:
    """A scalar loss: the output weighted by fixed random weights."""
    image = getattr(out, name)
    g = torch.Generator().manual_seed(seed)
    weights = torch.randn(image.shape, generator=g, dtype=torch.float64)
    return (weights.to(image.device, image.dtype) * image).sum()


def gradients(scene: TriangleScene, backend: str, name: str, global_sigma: bool = False) -> list[Tensor]:
    """Gradients of ``weighted(output name)`` w.r.t. vertices, colours, opacities, sigma."""
    out, leaves = render_scene(scene, backend, global_sigma)
    grads = torch.autograd.grad(weighted(out, name, seed=7), leaves, allow_unused=True)
    return [torch.zeros_like(x) if g is None else g for g, x in zip(grads, leaves, strict=True)]


def rel_l2(a: Tensor, b: Tensor, floor: float = 0.0) -> float:
    """``|a - b| / max(|a|, |b|, floor)`` (0 when all are zero); ``floor`` keeps rounding noise
    on quantities that are exactly zero in theory (e.g. distortion of a non-overlapping mesh)
    from counting as a relative error."""
    scale = max(float(a.norm()), float(b.norm()), floor)
    return 0.0 if scale == 0 else float((a - b).norm()) / scale
