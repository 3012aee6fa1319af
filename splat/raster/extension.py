"""Build (once, cached) and load the compiled rasteriser extensions."""

from __future__ import annotations

import hashlib
import os
import platform
import shutil
import sysconfig
import time
from functools import cache
from pathlib import Path
from types import ModuleType

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
# -ffp-contract=off keeps a*x + b*y + d bit-identical to PyTorch's (no fused multiply-add), so the
# kernel's skip/stop decisions match the reference exactly. -fopenmp: at::parallel_for is inline
# and runs serially in code compiled without it (libgomp is the one PyTorch already loaded).
CPU_FLAGS = ["-O3", "-march=native", "-ffp-contract=off", "-fopenmp"]
LINK_FLAGS = ["-fopenmp"]
CUDA_FLAGS = ["-O3", "--fmad=false"]


class BackendUnavailableError(RuntimeError):
    """A compiled backend cannot be built or loaded here; the message says what is missing."""


def cache_root() -> Path:
    """Where built extensions live (``$LTS_CACHE_DIR`` or ``~/.cache/lidar-ts``)."""
    return Path(os.environ.get("LTS_CACHE_DIR", Path.home() / ".cache" / "lidar-ts")) / "extensions"


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith(("model name", "flags")):
                return line
    except OSError:
        pass
    return platform.processor()


def _missing_toolchain(cuda: bool) -> list[str]:
    import torch.utils.cpp_extension as cpp

    missing = []
    compiler = os.environ.get("CXX", "c++")
    if shutil.which(compiler) is None:
        missing.append(f"a C++ compiler ({compiler!r} not on PATH; install g++ or set CXX)")
    if not cpp.is_ninja_available():
        missing.append("ninja (pip install ninja)")
    if not (Path(sysconfig.get_paths()["include"]) / "Python.h").exists():
        missing.append("the Python development headers (Python.h; e.g. apt install python3.11-dev)")
    if cuda:
        import torch

        if torch.version.cuda is None:
            missing.append("a CUDA build of PyTorch (this one is CPU-only)")
        if cpp.CUDA_HOME is None:
            missing.append("the CUDA toolkit (nvcc; set CUDA_HOME)")
    return missing


#: A build lock older than this (s) belongs to a compile that was killed (one takes about 25 s).
STALE_LOCK_S = 600.0


def _load(target: str, sources: list[Path], cuda: bool) -> ModuleType:
    import torch
    import torch.utils.cpp_extension as cpp

    from rig.cli_support import console

    flags = CPU_FLAGS + LINK_FLAGS + (CUDA_FLAGS if cuda else [])
    digest = hashlib.sha256()
    for part in [*HEADERS, *sources]:
        digest.update(part.read_bytes())
    digest.update(" ".join([*flags, torch.__version__, platform.python_version(), _cpu_model()]).encode())
    name = f"lts_raster_{target}_{digest.hexdigest()[:12]}"
    build_dir = cache_root() / name
    built = build_dir / f"{name}.so"
    if built.exists():
        # The name hashes the sources' contents: load the library as is. torch's loader would
        # rebuild it for a checkout at another path (ninja tracks paths) and wait on its lock.
        return _import_library(name, built)
    _remove_stale_lock(build_dir / "lock")
    missing = _missing_toolchain(cuda)
    if missing:
        raise BackendUnavailableError(
            f"cannot build the {target.upper()} rasteriser: missing {'; '.join(missing)}. "
            "Use backend='reference' for the (slow) pure-PyTorch rasteriser."
        )
    console.print(f"compiling the {target.upper()} rasteriser, once, ~25 s", highlight=False)
    build_dir.mkdir(parents=True, exist_ok=True)
    try:
        return cpp.load(
            name=name,
            sources=[str(s) for s in sources],
            extra_cflags=CPU_FLAGS,
            extra_ldflags=LINK_FLAGS,
            extra_cuda_cflags=CUDA_FLAGS if cuda else None,
            extra_include_paths=[str(CSRC)],
            build_directory=str(build_dir),
            verbose=False,
        )
    except (RuntimeError, OSError, ImportError) as exc:
        raise BackendUnavailableError(
            f"building the {target.upper()} rasteriser in {build_dir} failed: {exc}"
        ) from exc


def _import_library(name: str, path: Path) -> ModuleType:
    """The compiled extension module ``name`` at ``path`` (torch must be imported first)."""
    import importlib.util

    import torch  # noqa: F401  (the library links against torch's)

    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise BackendUnavailableError(f"cannot load the rasteriser library {path}")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except (ImportError, OSError) as exc:  # e.g. a library cut short by a killed build
        raise BackendUnavailableError(f"cannot load the rasteriser library {path}: {exc}") from exc
    return module


def _remove_stale_lock(lock: Path) -> None:
    """Remove a build lock left by a compile that was killed (older than :data:`STALE_LOCK_S`):
    torch would otherwise wait on it forever."""
    if lock.exists() and time.time() - lock.stat().st_mtime > STALE_LOCK_S:
        lock.unlink(missing_ok=True)


@cache
def cpu_extension() -> ModuleType:
    """The C++/OpenMP rasteriser, with the training loss's fused SSIM and normal term and the
    densification's error sums (compiled on first use)."""
    return _load("cpu", [CSRC / name for name in CPU_SOURCES], cuda=False)


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
    return _load("cuda", [CSRC / "raster_cuda.cu"], cuda=True)
