"""LPIPS v0.1 with the AlexNet trunk (Zhang et al. 2018, "The Unreasonable Effectiveness of Deep
Features as a Perceptual Metric") in plain torch: no ``lpips`` or ``torchvision`` package.

The distance of two images: both are scaled as the lpips package's ScalingLayer does, AlexNet's
conv features are taken after the ReLUs of its five conv layers, each feature vector is
unit-normalised over channels, the squared differences are weighted per channel by a learned
1×1 head, averaged over the pixels and summed over the five layers.

State dict keys: the trunk keeps torchvision's ``alexnet().features`` indices
(``features.0.weight``, ..., ``features.10.bias``) so torchvision's ImageNet file loads as it is;
the heads are ``heads.K.weight`` ``(1, C_K, 1, 1)``, the lpips package's ``linK.model.1.weight``.
"""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from rig.errors import InputError

#: Channels of the five compared layers.
CHANNELS = (64, 192, 384, 256, 256)
#: Indices in ``features`` of the ReLUs whose outputs are compared (lpips's relu1 ... relu5).
TAPS = (1, 4, 7, 9, 11)
#: The lpips package's ScalingLayer: ``(x - shift) / scale`` for ``x`` in [-1, 1].
SHIFT = (-0.030, -0.088, -0.188)
SCALE = (0.458, 0.448, 0.450)
#: The smallest image side AlexNet's two pooled stages leave a pixel of.
MIN_SIDE = 31
_EPS = 1e-10


def _unit(features: torch.Tensor) -> torch.Tensor:
    """``(B, C, H, W)`` features divided by their norm over channels (lpips's normalize_tensor)."""
    return features / (torch.sqrt(torch.sum(features**2, dim=1, keepdim=True)) + _EPS)


class LpipsAlex(nn.Module):
    """The LPIPS v0.1 "alex" network; :meth:`forward` gives the distance of image pairs."""

    def __init__(self) -> None:
        super().__init__()
        # torchvision's alexnet().features without its last max-pool, which LPIPS does not use
        self.features = nn.Sequential(
            nn.Conv2d(3, 64, kernel_size=11, stride=4, padding=2),
            nn.ReLU(),
            nn.MaxPool2d(kernel_size=3, stride=2),
            nn.Conv2d(64, 192, kernel_size=5, padding=2),
            nn.ReLU(),
            nn.MaxPool2d(kernel_size=3, stride=2),
            nn.Conv2d(192, 384, kernel_size=3, padding=1),
            nn.ReLU(),
            nn.Conv2d(384, 256, kernel_size=3, padding=1),
            nn.ReLU(),
            nn.Conv2d(256, 256, kernel_size=3, padding=1),
            nn.ReLU(),
        )
        self.heads = nn.ModuleList(nn.Conv2d(c, 1, kernel_size=1, bias=False) for c in CHANNELS)
        self.register_buffer("shift", torch.tensor(SHIFT).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("scale", torch.tensor(SCALE).view(1, 3, 1, 1), persistent=False)
        self.requires_grad_(False)
        self.eval()

    def _taps(self, images: torch.Tensor) -> list[torch.Tensor]:
        x = (images * 2 - 1 - self.shift) / self.scale
        taps = []
        for index, layer in enumerate(self.features):
            x = layer(x)
            if index in TAPS:
                taps.append(x)
        return taps

    def forward(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        """``(B,)`` distances of images ``a``, ``b`` ``(B, 3, H, W)`` float in [0, 1] (0 for
        identical images), both sides at least :data:`MIN_SIDE` pixels."""
        total = torch.zeros(a.shape[0], device=a.device, dtype=a.dtype)
        for head, fa, fb in zip(self.heads, self._taps(a), self._taps(b), strict=True):
            total = total + head((_unit(fa) - _unit(fb)) ** 2).mean(dim=(1, 2, 3))
        return total


def combined_state(
    alexnet: dict[str, torch.Tensor], lpips_heads: dict[str, torch.Tensor]
) -> dict[str, torch.Tensor]:
    """The :class:`LpipsAlex` state from torchvision's AlexNet state dict (its ``features.*``;
    the classifier is dropped) and the lpips package's ``v0.1/alex.pth`` (``linK.model.1.weight``)."""
    state = {key: value for key, value in alexnet.items() if key.startswith("features.")}
    for index in range(len(CHANNELS)):
        key = f"lin{index}.model.1.weight"
        if key in lpips_heads:
            state[f"heads.{index}.weight"] = lpips_heads[key]
    return state


def _describe(keys: list[str]) -> str:
    return ", ".join(keys[:3]) + (f" (+{len(keys) - 3} more)" if len(keys) > 3 else "")


def network_from_state(state: object, source: str | Path) -> LpipsAlex:
    """An :class:`LpipsAlex` holding ``state``; an :class:`~rig.errors.InputError` naming
    ``source`` when keys are missing or extra, or a tensor has the wrong shape or is not finite."""
    network = LpipsAlex()
    expected = network.state_dict()
    if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise InputError("not a state dict of tensors (expected LPIPS alex weights)", path=source)
    problems = []
    if missing := [key for key in expected if key not in state]:
        problems.append(f"missing {_describe(missing)}")
    if extra := [key for key in state if key not in expected]:
        problems.append(f"unexpected {_describe(extra)}")
    if shapes := [
        f"{key} {tuple(state[key].shape)} not {tuple(value.shape)}"
        for key, value in expected.items()
        if key in state and state[key].shape != value.shape
    ]:
        problems.append(f"wrong shape {_describe(shapes)}")
    if problems:
        raise InputError(
            f"not LPIPS alex weights: {'; '.join(problems)} (make them with lts weights download)",
            path=source,
        )
    if not all(bool(torch.isfinite(value).all()) for value in state.values()):
        raise InputError("LPIPS weights hold NaN or Inf", path=source)
    network.load_state_dict({key: value.float() for key, value in state.items()})
    return network


def read_torch_file(path: str | Path) -> object:
    """What a torch file holds, read safely (``weights_only``, tensors on the CPU: the lpips
    package's heads were saved from CUDA); errors name the file."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such LPIPS weights file", path=path)
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for foreign or truncated files
        raise InputError(f"not a torch weights file ({type(exc).__name__})", path=path) from None


def load_network(path: str | Path) -> LpipsAlex:
    """The :class:`LpipsAlex` of a weights file (one torch state dict, as ``lts weights
    download`` writes); errors name the file."""
    return network_from_state(read_torch_file(path), path)
