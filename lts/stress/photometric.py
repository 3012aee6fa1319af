"""Photometric-metrics stress area: PSNR and SSIM of constant, noisy, saturated, identical and
nearly identical images of 1-40 px a side, and of images holding a NaN/Inf."""

from __future__ import annotations

import math

import numpy as np

from eval.photometric import psnr, ssim
from rig.errors import InputError


def check_photometric(a: np.ndarray, b: np.ndarray) -> list[str]:
    """PSNR and SSIM (both border modes) of images ``(H, W, 3)`` in [0, 1]: finite (PSNR may be
    ``inf`` only for identical images), SSIM in [-1, 1], identical images give SSIM 1 exactly."""
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


def stress_photometric(rng: np.random.Generator) -> tuple[list[str], bool]:
    """One random image pair through :func:`check_photometric`, 15 % of the time with a
    NaN/Inf pixel that must be refused: the problems, and whether a non-finite image was refused."""
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
