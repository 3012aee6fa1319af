"""Build (once, cached by the sources' contents) and load a compiled C++/CUDA extension.

The project's hand-written kernels (the rasteriser and the training loss's fused terms in
``splat/raster/csrc``, the calibration's photo-consistency sums in ``calib/csrc``) are PyTorch C++
extensions: PyTorch brings the build (ninja, pybind11) and the tensors that carry NumPy arrays in
without a copy. PyTorch is imported only when an extension is loaded.
"""

from __future__ import annotations

import hashlib
import os
import platform
import shutil
import sysconfig
import time
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

from rig.user_cache import cache_dir

# -ffp-contract=off keeps a*x + b*y + d bit-identical to PyTorch's and NumPy's (no fused
# multiply-add), so the kernels' decisions match their specifications exactly. -fopenmp:
# at::parallel_for is inline and runs serially in code compiled without it (libgomp is the one
# PyTorch already loaded).
CPU_FLAGS = ["-O3", "-march=native", "-ffp-contract=off", "-fopenmp"]
LINK_FLAGS = ["-fopenmp"]
CUDA_FLAGS = ["-O3", "--fmad=false"]

#: A build lock older than this (s) belongs to a compile that was killed (the longest takes ~80 s).
STALE_LOCK_S = 600.0


class NativeBuildError(RuntimeError):
    """A compiled extension cannot be built or loaded here; the message says what is missing."""


def extensions_dir() -> Path:
    """Where built extensions live: ``extensions/`` in :func:`rig.user_cache.cache_dir`."""
    return cache_dir() / "extensions"


def load_extension(
    prefix: str,
    sources: Sequence[Path],
    headers: Sequence[Path],
    what: str,
    instead: str,
    build_s: int,
    cuda: bool = False,
) -> ModuleType:
    """The extension built from ``sources`` (including ``headers``, which live beside the first
    source), named ``prefix`` plus a digest of the sources, the flags and this machine's CPU:
    loaded from :func:`extensions_dir` when built before, else compiled there (announced, once,
    as taking about ``build_s`` seconds). ``what`` names it in messages ("the CPU rasteriser");
    ``instead`` tells the user what works without it. Raises :class:`NativeBuildError` when it
    can be neither built nor loaded."""
    import torch
    import torch.utils.cpp_extension as cpp

    from rig.cli_support import console

    flags = CPU_FLAGS + LINK_FLAGS + (CUDA_FLAGS if cuda else [])
    digest = hashlib.sha256()
    for part in [*headers, *sources]:
        digest.update(part.read_bytes())
    digest.update(" ".join([*flags, torch.__version__, platform.python_version(), _cpu_model()]).encode())
    name = f"{prefix}_{digest.hexdigest()[:12]}"
    build_dir = extensions_dir() / name
    built = build_dir / f"{name}.so"
    if built.exists():
        # The name hashes the sources' contents: load the library as is. torch's loader would
        # rebuild it for a checkout at another path (ninja tracks paths) and wait on its lock.
        return _import_library(name, built, what)
    _remove_stale_lock(build_dir / "lock")
    missing = _missing_toolchain(cuda)
    if missing:
        raise NativeBuildError(f"cannot build {what}: missing {'; '.join(missing)}. {instead}")
    console.print(f"compiling {what}, once, ~{build_s} s", highlight=False)
    build_dir.mkdir(parents=True, exist_ok=True)
    try:
        return cpp.load(
            name=name,
            sources=[str(s) for s in sources],
            extra_cflags=CPU_FLAGS,
            extra_ldflags=LINK_FLAGS,
            extra_cuda_cflags=CUDA_FLAGS if cuda else None,
            extra_include_paths=[str(Path(sources[0]).parent)],
            build_directory=str(build_dir),
            verbose=False,
        )
    except (RuntimeError, OSError, ImportError) as exc:
        raise NativeBuildError(f"building {what} in {build_dir} failed: {exc}") from exc


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


def _import_library(name: str, path: Path, what: str) -> ModuleType:
    """The compiled extension module ``name`` at ``path`` (torch must be imported first)."""
    import importlib.util

    import torch  # noqa: F401  (the library links against torch's)

    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise NativeBuildError(f"cannot load {what} from {path}")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except (ImportError, OSError) as exc:  # e.g. a library cut short by a killed build
        raise NativeBuildError(f"cannot load {what} from {path}: {exc}") from exc
    return module


def _remove_stale_lock(lock: Path) -> None:
    """Remove a build lock left by a compile that was killed (older than :data:`STALE_LOCK_S`):
    torch would otherwise wait on it forever."""
    if lock.exists() and time.time() - lock.stat().st_mtime > STALE_LOCK_S:
        lock.unlink(missing_ok=True)
