"""Building the compiled rasteriser: a clear error when the toolchain is missing, and a message
on the first build."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from splat.raster.extension import CSRC, BackendUnavailableError, cpu_extension


def test_missing_compiler_is_named(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("LTS_CACHE_DIR", str(tmp_path))  # nothing built there yet
    monkeypatch.setenv("CXX", "no-such-compiler")
    with pytest.raises(BackendUnavailableError, match=r"C\+\+ compiler.*no-such-compiler.*reference"):
        cpu_extension.__wrapped__()


@pytest.mark.slow
def test_first_build_is_announced(tmp_path: Path) -> None:
    code = (
        "import torch; from splat.raster import render; from splat.raster.scenes import pinhole;"
        "v = torch.tensor([[0., 0, 2], [0.3, 0, 2], [0, 0.3, 2]]);"
        "out = render(v, torch.arange(3)[None], torch.ones(3, 3), torch.ones(3), 1.0, pinhole(32, 24));"
        "print(float(out.alpha.max()) > 0)"
    )
    env = {**os.environ, "LTS_CACHE_DIR": str(tmp_path)}
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=900
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert "compiling the CPU rasteriser, once" in result.stderr
    assert result.stdout.strip() == "True"


def test_a_wheel_carries_every_source_the_build_needs() -> None:
    """An install from a wheel (not editable) builds from the package's own csrc/ folder."""
    pyproject = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    patterns = pyproject["tool"]["setuptools"]["package-data"]["splat.raster"]
    carried = {path for pattern in patterns for path in CSRC.parent.glob(pattern)}
    assert set(CSRC.iterdir()) <= carried
