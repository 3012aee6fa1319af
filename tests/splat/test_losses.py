"""The training losses against their library definitions."""

from __future__ import annotations

from types import SimpleNamespace

import kornia
import pytest
import torch

from splat import losses
from splat.losses import (
    composed_normal_loss,
    composed_ssim_map,
    dssim,
    image_moments,
    masked_mean,
    normal_loss,
    ssim_map,
)


@pytest.mark.parametrize(("height", "width"), [(24, 32), (61, 47)])
def test_ssim_map_has_kornias_values_and_gradients(height, width):
    generator = torch.Generator().manual_seed(0)
    target = torch.rand(height, width, 3, generator=generator, dtype=torch.float64)
    # A render near the target, as in training (SSIM's gradient is small and smooth there).
    noise = torch.randn(height, width, 3, generator=generator, dtype=torch.float64)
    start = (target + 0.1 * noise).clamp(0, 1)
    ours = start.clone().requires_grad_()
    theirs = start.clone().requires_grad_()

    values = ssim_map(ours, target)
    reference = kornia.metrics.ssim(
        theirs.permute(2, 0, 1)[None], target.permute(2, 0, 1)[None], window_size=11
    )[0].permute(1, 2, 0)
    torch.testing.assert_close(values, reference, rtol=0, atol=1e-12)
    values.square().sum().backward()
    reference.square().sum().backward()
    torch.testing.assert_close(ours.grad, theirs.grad, rtol=0, atol=1e-12)


def test_dssim_of_an_image_with_itself_is_zero_and_keep_selects_pixels():
    image = torch.rand(20, 30, 3, generator=torch.Generator().manual_seed(1))
    assert float(dssim(image, image)) == pytest.approx(0.0, abs=1e-6)
    noisy = (image + 0.2 * torch.rand(20, 30, 3, generator=torch.Generator().manual_seed(2))).clamp(0, 1)
    keep = torch.zeros(20, 30, dtype=torch.bool)
    keep[:, :15] = True
    expected = 1 - ssim_map(noisy, image)[keep].mean()
    # The same mean, summed in another order (float32).
    assert float(dssim(noisy, image, keep)) == pytest.approx(float(expected), rel=1e-5)
    assert float(dssim(noisy, image, keep)) != pytest.approx(float(dssim(noisy, image)))


def test_dssim_with_the_targets_moments_at_hand_is_the_same():
    generator = torch.Generator().manual_seed(3)
    target = torch.rand(30, 40, 3, generator=generator)
    render = torch.rand(30, 40, 3, generator=generator)
    given, computed = render.clone().requires_grad_(), render.clone().requires_grad_()
    with_moments = dssim(given, target, target_moments=image_moments(target))
    without = dssim(computed, target)
    with_moments.backward()
    without.backward()
    assert torch.equal(with_moments, without)
    assert torch.equal(given.grad, computed.grad)


@pytest.mark.parametrize("shape", [(7, 9, 3), (7, 9), (50,)])
def test_masked_mean_is_the_mean_of_the_selected_entries_with_its_gradient(shape):
    generator = torch.Generator().manual_seed(3)
    values = torch.randn(*shape, generator=generator, dtype=torch.float64)
    mask = torch.rand(*shape[: 2 if len(shape) > 1 else 1], generator=generator) > 0.6
    ours, theirs = values.clone().requires_grad_(), values.clone().requires_grad_()
    result, expected = masked_mean(ours, mask), theirs[mask].mean()
    torch.testing.assert_close(result, expected, rtol=1e-12, atol=0)
    result.backward()
    expected.backward()
    torch.testing.assert_close(ours.grad, theirs.grad, rtol=0, atol=1e-15)


@pytest.mark.parametrize(("height", "width"), [(6, 9), (61, 83), (150, 40)])
def test_the_fused_cpu_ssim_has_the_composed_values_and_gradients(height, width):
    """Float32 on the CPU goes through the extension's kernel: the smallest image it takes (one row
    more than the window's radius, both borders' reflections on one row), and several row blocks."""
    generator = torch.Generator().manual_seed(4)
    target = torch.rand(height, width, 3, generator=generator)
    start = (target + 0.1 * torch.randn(height, width, 3, generator=generator)).clamp(0, 1)
    upstream = torch.rand(height, width, 3, generator=generator)
    fused, composed = start.clone().requires_grad_(), start.clone().requires_grad_()
    assert losses._fused_kernel(fused) is not None

    values = ssim_map(fused, target)
    reference = composed_ssim_map(composed, target, image_moments(target))
    torch.testing.assert_close(values, reference, rtol=0, atol=1e-5)
    (values * upstream).sum().backward()
    (reference * upstream).sum().backward()
    torch.testing.assert_close(fused.grad, composed.grad, rtol=1e-4, atol=1e-5)


def test_the_fused_cpu_normal_loss_has_the_composed_value_and_gradient():
    """Pixels without a prior, with too little alpha and with a zero rendered normal among them."""
    generator = torch.Generator().manual_seed(5)
    normal = torch.randn(40, 50, 3, generator=generator)
    normal[0, :5] = 0.0  # no rendered normal: its length is clamped
    prior = torch.nn.functional.normalize(torch.randn(40, 50, 3, generator=generator), dim=-1)
    prior[5:9] = 0.0  # no prior
    alpha = torch.rand(40, 50, generator=generator)
    alpha[:, :3] = 0.0  # nothing rendered
    fused, composed = normal.clone().requires_grad_(), normal.clone().requires_grad_()
    assert losses._fused_kernel(fused) is not None

    value = normal_loss(SimpleNamespace(normal=fused, alpha=alpha), prior)
    reference = composed_normal_loss(SimpleNamespace(normal=composed, alpha=alpha), prior)
    torch.testing.assert_close(value, reference, rtol=1e-5, atol=0)
    value.backward()
    reference.backward()
    torch.testing.assert_close(fused.grad, composed.grad, rtol=1e-4, atol=1e-9)
    assert fused.grad[5:9].abs().sum() == 0 and fused.grad[:, :3].abs().sum() == 0


def test_the_fused_normal_loss_without_a_pixel_to_average_is_zero():
    normal = torch.randn(4, 6, 3).requires_grad_()
    loss = normal_loss(SimpleNamespace(normal=normal, alpha=torch.ones(4, 6)), torch.zeros(4, 6, 3))
    loss.backward()
    assert float(loss.detach()) == 0.0 and normal.grad.abs().sum() == 0
