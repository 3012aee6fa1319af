"""LPIPS without the lpips or torchvision packages: the network, where its weights are found, bad
weights files, the checksums of ``lts weights download`` and the download itself from local
``file://`` sources (no test touches the network)."""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import pytest
import torch

sys.path.insert(0, str(Path(__file__).parent))
from lpips_weights_file import random_lpips_state, write_random_lpips_weights

from eval import lpips_weights
from eval.lpips_net import CHANNELS, LpipsAlex, load_network
from eval.lpips_weights import (
    ALEXNET,
    HOW_TO_GET,
    LPIPS_HEADS,
    WeightSource,
    download_weights,
    load_lpips,
    verify,
)
from eval.photometric import lpips
from rig.errors import InputError


@pytest.fixture
def no_weights_here(tmp_path, monkeypatch) -> None:
    """Empty lidar-ts and torch caches and no lpips package: no weights anywhere."""
    monkeypatch.setenv("LTS_CACHE_DIR", str(tmp_path / "lts-cache"))
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "torch-home"))
    monkeypatch.setattr(lpips_weights, "lpips_package_heads", lambda: None)


def _images(seed: int = 1) -> tuple[torch.Tensor, torch.Tensor]:
    generator = torch.Generator().manual_seed(seed)
    return torch.rand(2, 3, 48, 64, generator=generator), torch.rand(2, 3, 48, 64, generator=generator)


def _torchvision_and_lpips_files(folder: Path, seed: int = 0) -> tuple[Path, Path]:
    """The random state split as the two published files are: torchvision's AlexNet (with a
    classifier LPIPS does not use) and the lpips package's heads (``linK.model.1.weight``)."""
    state = random_lpips_state(seed)
    trunk = {k: v for k, v in state.items() if k.startswith("features.")}
    trunk["classifier.1.weight"] = torch.zeros(8, 4)
    heads = {f"lin{k}.model.1.weight": state[f"heads.{k}.weight"] for k in range(len(CHANNELS))}
    folder.mkdir(parents=True, exist_ok=True)
    torch.save(trunk, folder / ALEXNET.name)
    torch.save(heads, folder / LPIPS_HEADS.name)
    return folder / ALEXNET.name, folder / LPIPS_HEADS.name


def _source_of(path: Path) -> WeightSource:
    data = path.read_bytes()
    return WeightSource(path.name, path.as_uri(), len(data), hashlib.sha256(data).hexdigest())


def test_identical_images_are_at_distance_zero_and_different_ones_are_not(tmp_path) -> None:
    weights = write_random_lpips_weights(tmp_path / "w.pt")
    a, b = _images()
    assert lpips(a, a, weights).value == 0.0
    value = lpips(a, b, weights).value
    assert value > 0 and value == pytest.approx(lpips(b, a, weights).value, rel=1e-6)
    network = load_network(weights)
    per_image = network(a, b)
    assert per_image.shape == (2,) and value == pytest.approx(float(per_image.mean()), rel=1e-6)
    # numpy (H, W, 3) uint8 images go through the same scaling as tensors in [0, 1]
    image = (a[0].permute(1, 2, 0).numpy() * 255).round().astype("uint8")
    assert lpips(image, image, network).value == 0.0


def test_without_weights_the_reason_says_how_to_get_them(no_weights_here) -> None:
    a, b = _images()
    result = lpips(a, b)
    assert result.value is None and result.reason == HOW_TO_GET
    assert "lts weights download" in result.reason and "--lpips-weights" in result.reason


def test_the_cache_file_is_found(no_weights_here, tmp_path) -> None:
    a, b = _images()
    expected = lpips(a, b, write_random_lpips_weights(tmp_path / "w.pt")).value
    lpips_weights.cache_path().parent.mkdir(parents=True)
    write_random_lpips_weights(lpips_weights.cache_path())
    assert lpips(a, b).value == pytest.approx(expected, rel=1e-6)


def test_torchvision_and_lpips_package_files_are_combined(no_weights_here, tmp_path, monkeypatch) -> None:
    a, b = _images()
    expected = lpips(a, b, write_random_lpips_weights(tmp_path / "w.pt")).value
    hub = Path(torch.hub.get_dir()) / "checkpoints"
    _, heads = _torchvision_and_lpips_files(hub)
    monkeypatch.setattr(lpips_weights, "lpips_package_heads", lambda: heads)
    network = load_lpips()
    assert network is not None
    assert lpips(a, b, network).value == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"not a torch file", "not a torch weights file"),
        ({"features.0.weight": torch.zeros(64, 3, 11, 11)}, "missing features.0.bias"),
        ("wrong shape", "wrong shape heads.0.weight (1, 65, 1, 1) not (1, 64, 1, 1)"),
        ("extra key", "unexpected classifier.1.weight"),
        ([1, 2, 3], "not a state dict of tensors"),
    ],
)
def test_a_bad_weights_file_is_an_error_naming_it(tmp_path, content, message) -> None:
    path = tmp_path / "bad.pt"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content == "wrong shape":
        torch.save({**random_lpips_state(), "heads.0.weight": torch.ones(1, 65, 1, 1)}, path)
    elif content == "extra key":
        torch.save({**random_lpips_state(), "classifier.1.weight": torch.ones(2, 2)}, path)
    else:
        torch.save(content, path)
    with pytest.raises(InputError, match=r"bad\.pt") as error:
        lpips(*_images(), path)
    assert message in str(error.value) and "\n" not in str(error.value)


def test_images_too_small_for_alexnet_are_an_error(tmp_path) -> None:
    network = LpipsAlex()
    with pytest.raises(InputError, match="at least 31x31"):
        lpips(torch.rand(3, 30, 64), torch.rand(3, 30, 64), network)


def test_checksums_are_verified_on_local_files(tmp_path) -> None:
    path = tmp_path / "alex.pth"
    path.write_bytes(b"weights")
    source = _source_of(path)
    verify(path, source)
    with pytest.raises(InputError, match=r"alex.pth: size: 7 bytes, expected 8"):
        verify(path, WeightSource("alex.pth", source.url, 8, source.sha256))
    with pytest.raises(InputError, match=r"alex.pth: sha256: SHA-256 .* is not the published 00"):
        verify(path, WeightSource("alex.pth", source.url, source.size, "00" * 32))


def test_the_published_checksums_match_torchvision_s_file_name() -> None:
    # torchvision names its files with the first 8 hex digits of their SHA-256
    assert ALEXNET.name == f"alexnet-owt-{ALEXNET.sha256[:8]}.pth"
    assert ALEXNET.url.endswith(ALEXNET.name) and LPIPS_HEADS.url.endswith("v0.1/alex.pth")
    assert len(LPIPS_HEADS.sha256) == 64 and LPIPS_HEADS.size == 6009


def test_download_checks_and_combines_the_two_files(no_weights_here, tmp_path) -> None:
    trunk, heads = _torchvision_and_lpips_files(tmp_path / "published")
    messages: list[str] = []
    out = download_weights(
        tmp_path / "out" / "lpips.pt", _source_of(trunk), _source_of(heads), messages.append
    )
    assert out == tmp_path / "out" / "lpips.pt"
    assert [m.split()[0] for m in messages] == ["downloading", "downloading"]
    a, b = _images()
    expected = lpips(a, b, write_random_lpips_weights(tmp_path / "w.pt")).value
    assert lpips(a, b, out).value == pytest.approx(expected, rel=1e-6)
    assert sorted(p.name for p in out.parent.iterdir()) == ["lpips.pt"]  # no partial files left


def test_a_download_with_the_wrong_checksum_writes_nothing(no_weights_here, tmp_path) -> None:
    trunk, heads = _torchvision_and_lpips_files(tmp_path / "published")
    tampered = WeightSource(heads.name, heads.as_uri(), heads.stat().st_size, "0" * 64)
    with pytest.raises(InputError, match="sha256"):
        download_weights(tmp_path / "out" / "lpips.pt", _source_of(trunk), tampered)
    assert list((tmp_path / "out").iterdir()) == []


def test_weights_download_keeps_an_existing_file_without_fetching(lts_cli, tmp_path) -> None:
    existing = write_random_lpips_weights(tmp_path / "w.pt")
    before = existing.read_bytes()
    code, _, err = lts_cli("weights", "download", "--out", existing)
    assert code == 0 and "already there" in err and "--force" in err
    assert existing.read_bytes() == before
    code, _, err = lts_cli("weights", "download", "--bogus")
    assert code == 2 and "--bogus" in err
