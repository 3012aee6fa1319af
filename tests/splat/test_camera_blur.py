"""The camera's blur: a Gaussian the renders pass through, fitted on the training views."""

from __future__ import annotations

import pytest
import torch

from rig.errors import InputError
from splat.camera_blur import blurred, fit_blur, summary_width_px


def sharp_image(seed: int, height: int = 48, width: int = 64) -> torch.Tensor:
    """``(H, W, 3)`` blocks of random colour: hard edges, as opaque triangles render them."""
    g = torch.Generator().manual_seed(seed)
    blocks = torch.rand(height // 4, width // 4, 3, generator=g)
    return blocks.repeat_interleave(4, dim=0).repeat_interleave(4, dim=1)


def test_no_width_is_no_blur_and_a_flat_image_stays_flat() -> None:
    image = sharp_image(0)
    assert blurred(image, 0.0) is image
    flat = torch.full((20, 30, 3), 0.25)
    torch.testing.assert_close(blurred(flat, 0.7), flat)


def test_a_point_spreads_with_the_variance_of_the_width() -> None:
    point = torch.zeros(41, 41, 3)
    point[20, 20] = 1.0
    spread = blurred(point, 0.8)[..., 0]
    offsets = torch.arange(41, dtype=torch.float32) - 20
    assert float(spread.sum()) == pytest.approx(1.0, abs=1e-5)
    assert float((spread.sum(dim=0) * offsets**2).sum()) == pytest.approx(0.8**2, rel=0.02)


def test_the_blur_passes_gradients_to_the_render() -> None:
    render = sharp_image(1).requires_grad_()
    blurred(render, 0.6).square().sum().backward()
    assert render.grad is not None and bool(torch.isfinite(render.grad).all())


@pytest.mark.parametrize("width", [0.0, 0.45, 0.9])
def test_the_fit_finds_the_width_the_images_were_blurred_by(width: float) -> None:
    renders = [sharp_image(seed) for seed in range(3)]
    views = [(render, blurred(render, width), None) for render in renders]
    fitted, sharp, through = fit_blur(views)
    assert fitted == pytest.approx(width, abs=0.02)
    assert through >= sharp and (width == 0.0 or through > sharp + 3)


def test_the_fit_leaves_out_the_masked_pixels() -> None:
    render = sharp_image(2)
    image = blurred(render, 0.6)
    mask = torch.zeros(image.shape[:2], dtype=torch.bool)
    mask[:, :20] = True
    image[:, :20] = render[:, :20]  # unblurred where a moving object hides the scene
    assert fit_blur([(render, image, mask)])[0] == pytest.approx(0.6, abs=0.02)
    assert fit_blur([(render, image, None)])[0] < 0.6


def test_with_no_pixel_to_fit_the_width_is_zero() -> None:
    render = sharp_image(3)
    everything = torch.ones(render.shape[:2], dtype=torch.bool)
    width, sharp, through = fit_blur([(render, render, everything)])
    assert width == 0.0 and sharp != sharp and through != through  # NaN: nothing measured


def test_a_runs_width_is_read_from_its_summary_and_a_bad_one_named(tmp_path) -> None:
    path = tmp_path / "summary.json"
    assert summary_width_px({"camera_blur": {"width_px": 0.61}}, path) == 0.61
    assert summary_width_px({}, path) == 0.0  # a run from before the blur was fitted
    for bad in ("wide", -0.5, True, [0.5]):
        with pytest.raises(InputError, match=r"summary\.json.*camera_blur\.width_px.*0 to 100"):
            summary_width_px({"camera_blur": {"width_px": bad}}, path)
