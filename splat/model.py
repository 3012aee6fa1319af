"""The triangle model: independent triangles, their learnable parameters and activations.

Each triangle owns its three vertices (``F`` triangles, ``3F`` vertices), so triangles can move,
be cloned, subdivided and pruned one by one. Parameters (all leaf tensors, rows = triangles):

- ``vertices`` ``(F, 3, 3)`` world positions;
- ``colors`` ``(F, 3, 3)`` per-vertex colour logits (``sigmoid`` → RGB in [0, 1], barycentric
  inside the triangle);
- ``opacity`` ``(F,)`` opacity logits; the activated opacity is
  ``floor + (1 - floor) · sigmoid(logit)`` with the TS+ rising ``opacity_floor`` (1 → opaque).

``sigma`` (the window sharpness, annealed by the schedule) and ``opacity_floor`` are schedule
state, not learnt. The optional ``background`` ``(K, 3)`` (spherical-harmonic coefficients and map texels,
see :mod:`splat.background`) is learnt too but is not per triangle, so it is kept out of ``params``
(whose rows densification and pruning edit) and out of the exported meshes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from rig.atomic_file import atomic_path
from rig.camera import CameraModel
from rig.errors import InputError
from splat.background import background_image, background_pixels, layout_of
from splat.finite import all_finite
from splat.raster import RenderOutput, render

PARAM_NAMES = ("vertices", "colors", "opacity")
#: Colour logits are clamped to this range so that sigmoid saturation keeps a usable gradient.
LOGIT_LIMIT = 8.0


def logit(p: Tensor | float, eps: float = 1e-4) -> Tensor:
    """Inverse sigmoid of ``p`` clamped to ``[eps, 1 - eps]``."""
    p = torch.as_tensor(p).clamp(eps, 1 - eps)
    return torch.log(p / (1 - p))


@dataclass
class TriangleModel:
    """Independent triangles with per-vertex colours and per-triangle opacity.

    Attributes:
        params: ``{"vertices": (F, 3, 3), "colors": (F, 3, 3), "opacity": (F,)}`` leaf tensors.
        sigma: window sharpness (> 0; smaller is sharper).
        opacity_floor: lower bound of the activated opacity in [0, 1].
        background: ``(K, 3)`` leaf background coefficients, or None for a black background.
        background_sphere: ``(4,)`` the sphere the background lies on (centre, radius; m, world), or
            None: at infinity (:func:`splat.background.background_sphere`).
    """

    params: dict[str, Tensor]
    sigma: float = 1.0
    opacity_floor: float = 0.0
    background: Tensor | None = None
    background_sphere: Tensor | None = None

    @classmethod
    def from_triangles(
        cls, triangles: Tensor, colors: Tensor, opacity: Tensor | float = 0.5, sigma: float = 1.0
    ) -> TriangleModel:
        """A model from triangle corners ``(F, 3, 3)``, RGB in [0, 1] ``(F, 3, 3)`` and opacity in
        (0, 1) — a scalar or ``(F,)``."""
        if triangles.dim() != 3 or triangles.shape[1:] != (3, 3):
            raise InputError(f"expected triangles of shape (F, 3, 3), got {tuple(triangles.shape)}")
        if colors.shape != triangles.shape:
            raise InputError(f"expected colours of shape {tuple(triangles.shape)}, got {tuple(colors.shape)}")
        n = len(triangles)
        opacity = torch.as_tensor(opacity, dtype=triangles.dtype).expand(n)
        params = {
            "vertices": triangles.detach().clone(),
            "colors": logit(colors.detach().to(triangles.dtype)).clamp(-LOGIT_LIMIT, LOGIT_LIMIT),
            "opacity": logit(opacity.detach()).to(triangles.dtype).clone(),
        }
        for p in params.values():
            p.requires_grad_(True)
        return cls(params, sigma)

    @property
    def n_triangles(self) -> int:
        return len(self.params["vertices"])

    @property
    def device(self) -> torch.device:
        return self.params["vertices"].device

    def trainable(self) -> list[Tensor]:
        """Every learnt tensor: the per-triangle ``params`` and the background, if any."""
        return [*self.params.values(), *([] if self.background is None else [self.background])]

    def triangle_opacity(self) -> Tensor:
        """``(F,)`` activated opacity in ``[opacity_floor, 1]``."""
        return self.opacity_floor + (1.0 - self.opacity_floor) * torch.sigmoid(self.params["opacity"])

    def triangle_colors(self) -> Tensor:
        """``(F, 3, 3)`` activated per-vertex RGB in [0, 1]."""
        return torch.sigmoid(self.params["colors"])

    def render(
        self,
        camera: CameraModel,
        T_cam_world: Tensor,
        *,
        backend: str = "auto",
        background_mask: Tensor | None = None,
    ) -> RenderOutput:
        """Render the model from one camera (``T_cam_world`` ``(4, 4)``); see :func:`splat.render`.
        With a background, ``rgb`` ``(H, W, 3)`` is composited over it (``+ bg · (1 - alpha)``) where
        ``background_mask`` ``(H, W)`` bool is True (None: everywhere); the other images are the
        triangles' alone."""
        n = self.n_triangles
        vertices = self.params["vertices"].reshape(3 * n, 3)
        faces = torch.arange(3 * n, device=self.device).view(n, 3)
        colors = self.triangle_colors().reshape(3 * n, 3)
        opacities = self.triangle_opacity().repeat_interleave(3)
        out = render(vertices, faces, colors, opacities, self.sigma, camera, T_cam_world, backend=backend)
        if self.background is None:
            return out
        shows = (1.0 - out.alpha).clamp(min=0.0)
        if background_mask is None:
            bg = background_image(self.background, camera, T_cam_world, self.background_sphere)
            return replace(out, rgb=out.rgb + bg * shows[..., None])
        # Only the masked pixels (indoors often none): the harmonics are not evaluated elsewhere.
        pixels = background_mask.reshape(-1).nonzero().squeeze(1)
        bg = background_pixels(self.background, camera, T_cam_world, pixels, self.background_sphere)
        # index_put's backward gathers the image's gradient, quick in any memory layout; index_add's
        # index_select is 4x slower on the D-SSIM term's channel-first gradient (4.6 ms a step on the
        # 20 s street).
        placed = torch.zeros_like(out.rgb).view(-1, 3).index_put((pixels,), bg).view_as(out.rgb)
        return replace(out, rgb=out.rgb + placed * shows[..., None])

    @torch.no_grad()
    def render_at(
        self, camera: CameraModel, T_world_cam: np.ndarray, background_mask: Tensor | None = None
    ) -> RenderOutput:
        """:meth:`render` without gradients from a camera pose ``T_world_cam`` ``(4, 4)`` (camera to
        world, numpy): for evaluation and viewing."""
        T_cam_world = torch.as_tensor(np.linalg.inv(T_world_cam), dtype=torch.float32, device=self.device)
        return self.render(camera, T_cam_world, background_mask=background_mask)

    def to_state(self) -> dict:
        """Plain tensors (detached, CPU) and schedule state, for ``torch.save`` (``background`` only
        when the model has one)."""
        state = {
            **{name: p.detach().cpu().clone() for name, p in self.params.items()},
            "sigma": self.sigma,
            "opacity_floor": self.opacity_floor,
        }
        if self.background is not None:
            state["background"] = self.background.detach().cpu().clone()
        if self.background_sphere is not None:
            state["background_sphere"] = self.background_sphere.detach().cpu().clone()
        return state

    @classmethod
    def from_state(
        cls, state: dict, device: torch.device | str = "cpu", path: Path | None = None
    ) -> TriangleModel:
        """Inverse of :meth:`to_state`; errors name the file and the missing/malformed field. A state
        without ``background`` (written before backgrounds existed, or with none) loads without one,
        one without ``background_sphere`` with its background at infinity."""
        params = {}
        for name in PARAM_NAMES:
            if name not in state or not isinstance(state[name], Tensor):
                raise InputError("missing model tensor", path=path, field=name)
            params[name] = state[name].to(device).clone().requires_grad_(True)
        n = len(params["vertices"])
        shapes = {"vertices": (n, 3, 3), "colors": (n, 3, 3), "opacity": (n,)}
        for name, shape in shapes.items():
            if tuple(params[name].shape) != shape:
                got = tuple(params[name].shape)
                raise InputError(f"expected shape {shape}, got {got}", path=path, field=name)
            if not all_finite(params[name]):
                raise InputError("holds NaN or Inf", path=path, field=name)
        background = _background_from_state(state, device, path)
        sphere = _sphere_from_state(state, device, path)
        sigma, floor = float(state.get("sigma", 1.0)), float(state.get("opacity_floor", 0.0))
        return cls(params, sigma, floor, background, sphere)


def _background_from_state(state: dict, device: torch.device | str, path: Path | None) -> Tensor | None:
    """The state's background coefficients ``(K, 3)`` as a leaf that requires grad, or None."""
    background = state.get("background")
    if background is None:
        return None
    if not isinstance(background, Tensor):
        raise InputError("expected a tensor", path=path, field="background")
    if background.dim() != 2 or background.shape[1] != 3:
        got = tuple(background.shape)
        raise InputError(f"expected shape (K, 3), got {got}", path=path, field="background")
    try:
        layout_of(len(background))
    except ValueError as error:
        raise InputError(str(error), path=path, field="background") from None
    if not all_finite(background):
        raise InputError("holds NaN or Inf", path=path, field="background")
    return background.to(device).clone().requires_grad_(True)


def _sphere_from_state(state: dict, device: torch.device | str, path: Path | None) -> Tensor | None:
    """The state's background sphere ``(4,)`` (centre, radius), or None (at infinity)."""
    sphere = state.get("background_sphere")
    if sphere is None:
        return None
    field = "background_sphere"
    if not isinstance(sphere, Tensor) or tuple(sphere.shape) != (4,):
        raise InputError("expected a tensor of shape (4,): centre and radius", path=path, field=field)
    if not all_finite(sphere) or float(sphere[3]) <= 0:
        raise InputError("expected a finite centre and a radius > 0", path=path, field=field)
    return sphere.to(device=device, dtype=torch.float32).clone()


def save_model(model: TriangleModel, path: str | Path) -> None:
    """Write the model to ``path`` atomically (a temporary file renamed into place)."""
    with atomic_path(path) as tmp:
        torch.save(model.to_state(), tmp)


def load_model(path: str | Path, device: torch.device | str = "cpu") -> TriangleModel:
    """Read a model written by :func:`save_model` (errors name the file)."""
    path = Path(path)
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise InputError("no such model file", path=path) from None
    except Exception as exc:  # torch raises many types for truncated or foreign files
        raise InputError(f"cannot read model ({type(exc).__name__}: {exc})", path=path) from None
    if not isinstance(state, dict):
        raise InputError("not a triangle model file", path=path)
    return TriangleModel.from_state(state, device, path)
