"""The CUDA rasteriser: an nvcc compile check everywhere nvcc exists, and the kernel-vs-reference
checks on a GPU (skipped without one)."""

from __future__ import annotations

import shutil
import subprocess
import sysconfig
from pathlib import Path

import pytest
import torch
from raster_cases import CASES, INPUTS, OUTPUTS, gradients, rel_l2
from torch.utils import cpp_extension

from splat.raster.extension import CSRC
from splat.raster.scenes import TriangleScene

needs_gpu = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("nvcc") is None, reason="needs nvcc")
def test_cuda_source_compiles_with_nvcc(tmp_path: Path) -> None:
    includes = [*cpp_extension.include_paths(), sysconfig.get_paths()["include"]]
    generated = Path("c10/cuda/impl/cuda_cmake_macros.h")
    if not any((Path(p) / generated).exists() for p in includes):
        # A CPU-only PyTorch ships c10/cuda headers without this configure-time one; its content
        # is a single define.
        (tmp_path / generated).parent.mkdir(parents=True)
        (tmp_path / generated).write_text("#pragma once\n#define C10_CUDA_BUILD_SHARED_LIBS\n")
        includes.insert(0, str(tmp_path))
    cmd = ["nvcc", "-c", str(CSRC / "raster_cuda.cu"), "-o", str(tmp_path / "raster_cuda.o")]
    cmd += ["-std=c++20", "-O3", "--fmad=false", "-arch=sm_80", "-Xcompiler", "-fPIC", f"-I{CSRC}"]
    for path in includes:
        cmd += ["-isystem", str(path)]
    cmd += ["-DTORCH_EXTENSION_NAME=lts_raster_cuda_check", "-DTORCH_API_INCLUDE_EXTENSION_H"]
    cmd += ["-D__CUDA_NO_HALF_OPERATORS__", "-D__CUDA_NO_HALF_CONVERSIONS__", "--expt-relaxed-constexpr"]
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr[-4000:]
    assert (tmp_path / "raster_cuda.o").stat().st_size > 0


def _on_cuda(scene: TriangleScene) -> TriangleScene:
    moved = [t.cuda() for t in scene.tensors()]
    return TriangleScene(*moved, scene.camera)


@pytest.mark.gpu
@needs_gpu
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32], ids=["f64", "f32"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_cuda_gradients_match_the_reference(case: str, dtype: torch.dtype) -> None:
    scene = CASES[case](dtype)
    tolerance, floor = (1e-5, 1e-9) if dtype == torch.float64 else (1e-3, 1e-3)
    for name in OUTPUTS:
        ref = gradients(scene, "reference", name)
        gpu = gradients(_on_cuda(scene), "cuda", name)
        for label, a, b in zip(INPUTS, ref, gpu, strict=True):
            assert bool(torch.isfinite(b).all()), f"d {name} / d {label} not finite"
            err = rel_l2(a, b.cpu(), floor)
            assert err < tolerance, f"d {name} / d {label}: rel L2 {err:.2e}"
