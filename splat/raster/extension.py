"""Build (once, cached) and load the compiled rasteriser extensions."""

from __future__ import annotations

from functools import cache
from pathlib import Path
from types import ModuleType

from rig.native_build import NativeBuildError, load_extension

CSRC = Path(__file__).parent / "csrc"
HEADERS = [
    CSRC / name
    for name in ("triangle_math.h", "lane_math.h", "triangle_setup.h", "bins.h", "cpu_ops.h", "pixel_io.h")
]
#: The CPU extension: the rasteriser (with the module's bindings), the per-triangle set-up, the
#: training loss's fused terms and the densification's error sums.
CPU_SOURCES = (
    "raster_cpu.cpp", "setup_cpu.cpp", "ssim_cpu.cpp", "normal_loss_cpu.cpp", "error_sums_cpu.cpp",
)  # fmt: skip
#: What works without a compiled rasteriser, for the messages that say one cannot be built.
INSTEAD = "Use backend='reference' for the (slow) pure-PyTorch rasteriser."

#: A compiled backend cannot be built or loaded here; the message says what is missing.
BackendUnavailableError = NativeBuildError


@cache
def cpu_extension() -> ModuleType:
    """The C++/OpenMP rasteriser, with the training loss's fused SSIM and normal term and the
    densification's error sums (compiled on first use)."""
    sources = [CSRC / name for name in CPU_SOURCES]
    return load_extension("lts_raster_cpu", sources, HEADERS, "the CPU rasteriser", INSTEAD, build_s=25)


@cache
def optional_cpu_extension() -> ModuleType | None:
    """:func:`cpu_extension`, or None where it cannot be built: for the fused kernels whose PyTorch
    compositions (their specifications) can stand in."""
    try:
        return cpu_extension()
    except BackendUnavailableError:
        return None


@cache
def cuda_extension() -> ModuleType:
    """The CUDA rasteriser (compiled on first use; needs a CUDA build of PyTorch and nvcc)."""
    source = CSRC / "raster_cuda.cu"
    return load_extension("lts_raster_cuda", [source], HEADERS, "the CUDA rasteriser", INSTEAD, 50, cuda=True)
