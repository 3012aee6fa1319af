"""A stand-in LPIPS weights file for tests: random tensors of the right keys and shapes (the real
weights are downloaded by ``lts weights download``, which no test runs)."""

from __future__ import annotations

from pathlib import Path

import torch

from eval.lpips_net import LpipsAlex


def random_lpips_state(seed: int = 0) -> dict[str, torch.Tensor]:
    """A state dict for :class:`LpipsAlex`: small random trunk weights and non-negative heads
    (as the learned ones are), so distances are non-negative."""
    generator = torch.Generator().manual_seed(seed)
    state = {}
    for key, value in LpipsAlex().state_dict().items():
        tensor = torch.randn(value.shape, generator=generator) * 0.05
        state[key] = tensor.abs() if key.startswith("heads.") else tensor
    return state


def write_random_lpips_weights(path: Path, seed: int = 0) -> Path:
    """Save :func:`random_lpips_state` at ``path`` and return it."""
    torch.save(random_lpips_state(seed), path)
    return path
