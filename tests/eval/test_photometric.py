from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

from eval.photometric import lpips, psnr, ssim


def real_pairs(real_data: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """Real photographs against degraded copies (blur, noise, JPEG, a shifted neighbour frame)."""
    rgb = sorted((real_data / "rgbd_3dmatch").rglob("*color*.png"))[:2]
    images = [cv2.imread(str(p), cv2.IMREAD_COLOR) for p in rgb]
    kitti = cv2.imread(str(real_data / "kitti_frames" / "image_2" / "000000.png"), cv2.IMREAD_COLOR)
    rng = np.random.default_rng(0)
    noisy = np.clip(images[0] + rng.normal(0, 12, images[0].shape), 0, 255).astype(np.uint8)
    _, jpeg = cv2.imencode(".jpg", kitti, [cv2.IMWRITE_JPEG_QUALITY, 30])
    return [
        (images[0], cv2.GaussianBlur(images[0], (7, 7), 2.0)),
        (images[0], noisy),
        (images[0], images[1]),
        (kitti, cv2.imdecode(jpeg, cv2.IMREAD_COLOR)),
    ]


def test_psnr_and_ssim_match_scikit_image_on_real_images(real_data: Path) -> None:
    for a, b in real_pairs(real_data):
        fa, fb = a.astype(np.float64) / 255.0, b.astype(np.float64) / 255.0
        ref_psnr = peak_signal_noise_ratio(fa, fb, data_range=1.0)
        ref_ssim = structural_similarity(
            fa,
            fb,
            gaussian_weights=True,
            sigma=1.5,
            use_sample_covariance=False,
            data_range=1.0,
            channel_axis=2,
        )
        assert psnr(a, b) == pytest.approx(ref_psnr, abs=1e-4)
        assert ssim(a, b) == pytest.approx(ref_ssim, abs=1e-4)
        assert abs(ssim(a, b, border="zero-pad") - ref_ssim) < 0.02  # 3DGS convention: borders differ


def test_identical_and_constant_images() -> None:
    image = torch.rand(3, 32, 40, dtype=torch.float64)
    assert psnr(image, image) == float("inf")
    assert ssim(image, image) == pytest.approx(1.0, abs=1e-12)
    flat = torch.full((3, 32, 40), 0.5)
    assert np.isfinite(ssim(flat, flat)) and ssim(flat, flat) == pytest.approx(1.0)
    assert ssim(flat, torch.zeros_like(flat)) < 0.1


def test_shape_mismatch_is_an_error() -> None:
    with pytest.raises(ValueError, match="differ in shape"):
        psnr(torch.zeros(3, 8, 8), torch.zeros(3, 8, 9))


def test_psnr_over_a_mask_counts_only_its_pixels() -> None:
    rendered = torch.zeros(3, 8, 8, dtype=torch.float64)
    target = rendered.clone()
    target[:, :4] = 0.1  # error only in the top half
    top = torch.zeros(8, 8, dtype=torch.bool)
    top[:4] = True
    assert psnr(rendered, target, mask=top) == pytest.approx(20.0)
    assert psnr(rendered, target) == pytest.approx(20.0 + 10 * np.log10(2))
    assert psnr(rendered, target, mask=~top) == float("inf")
    with pytest.raises(ValueError, match="no pixel"):
        psnr(rendered, target, mask=torch.zeros(8, 8, dtype=torch.bool))
    with pytest.raises(ValueError, match="mask of shape"):
        psnr(rendered, target, mask=top[:4])


def test_lpips_is_null_with_a_reason_when_unavailable() -> None:
    result = lpips(torch.rand(3, 32, 32), torch.rand(3, 32, 32))
    if result.value is None:
        assert result.reason
    else:
        assert 0.0 <= result.value < 2.0
