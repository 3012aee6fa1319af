"""Forward+backward timing and peak memory of the rasteriser backends, side by side."""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import statistics
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import torch

from splat.raster.extension import BackendUnavailableError, cpu_extension, cuda_extension
from splat.raster.render import render
from splat.raster.scenes import TriangleScene, pinhole, random_scene

_STATUS = Path("/proc/self/status")
_CLEAR_REFS = Path("/proc/self/clear_refs")


@dataclass
class BenchRow:
    backend: str
    n_triangles: int
    width: int
    height: int
    ms_fwd_bwd: float
    peak_mb: float


def available_backends() -> dict[str, str]:
    """Backends that can run here, mapped to their device; unavailable ones are left out."""
    found = {"reference": "cpu"}
    try:
        cpu_extension()
        found["cpu"] = "cpu"
    except BackendUnavailableError:
        pass
    if torch.cuda.is_available():
        try:
            cuda_extension()
            found["cuda"] = "cuda"
        except BackendUnavailableError:
            pass
    return found


def _rss_kib(field: str) -> int:
    for line in _STATUS.read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    raise OSError(f"{field} not in {_STATUS}")


def _peak_mb(step: Callable[[], None], device: str) -> float:
    """Memory one call of ``step`` needs beyond what was in use before it, in MiB.

    CPU (Linux, glibc): growth of the resident set's high-water mark (reset through
    /proc/self/clear_refs) after returning free heap memory; CUDA: the allocator's peak.
    """
    if device == "cuda":
        torch.cuda.synchronize()
        torch.cuda.reset_peak_memory_stats()
        base = torch.cuda.memory_allocated()
        step()
        torch.cuda.synchronize()
        return (torch.cuda.max_memory_allocated() - base) / 2**20
    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    libc.malloc_trim(0)  # hand freed heap memory back, so that the step's own peak shows
    base = _rss_kib("VmRSS")
    _CLEAR_REFS.write_text("5")  # resets VmHWM to the current resident set
    step()
    return max(_rss_kib("VmHWM") - base, 0) / 1024


def _time_ms(step: Callable[[], None], device: str, repeats: int) -> float:
    step()  # warm-up (and the one-time kernel build)
    times = []
    for _ in range(repeats):
        if device == "cuda":
            torch.cuda.synchronize()
        start = time.perf_counter()
        step()
        if device == "cuda":
            torch.cuda.synchronize()
        times.append((time.perf_counter() - start) * 1e3)
    return statistics.median(times)


def _step(scene: TriangleScene, backend: str, device: str) -> Callable[[], None]:
    tensors = [t.to(device) for t in scene.tensors()]

    def step() -> None:
        leaves = [t.detach().requires_grad_(t.is_floating_point()) for t in tensors]
        out = render(*leaves, scene.camera, backend=backend)
        outputs = (out.rgb, out.accumulated_depth, out.alpha, out.normal, out.median_depth, out.distortion)
        loss = sum(x.sum() for x in outputs)
        loss.backward()

    return step


def run_bench(
    sizes: list[int],
    width: int = 320,
    height: int = 240,
    repeats: int = 5,
    backends: dict[str, str] | None = None,
    report: Callable[[BenchRow], None] = lambda row: None,
) -> dict:
    """Benchmark every backend on random 2-20 px float32 scenes of each size.

    Returns ``{"rows": [BenchRow as dict], "speedup_vs_reference": {backend: x}}`` with x the
    geometric mean over sizes of reference time / backend time, and where the CPU kernel runs
    ``"cpu_simd": {"instruction_set": name, "float_lanes": n}``.
    """
    backends = available_backends() if backends is None else backends
    camera = pinhole(width, height)
    rows: list[BenchRow] = []
    for n in sizes:
        scene = random_scene(n, camera, seed=n)
        for backend, device in backends.items():
            step = _step(scene, backend, device)
            ms = _time_ms(step, device, repeats)
            row = BenchRow(backend, n, width, height, round(ms, 2), round(_peak_mb(step, device), 1))
            rows.append(row)
            report(row)
    speedup = {}
    for backend in backends:
        if backend == "reference" or "reference" not in backends:
            continue
        ratios = [
            ref.ms_fwd_bwd / row.ms_fwd_bwd
            for ref in rows
            if ref.backend == "reference"
            for row in rows
            if row.backend == backend and row.n_triangles == ref.n_triangles
        ]
        speedup[backend] = round(math.exp(statistics.fmean(math.log(r) for r in ratios)), 2)
    result = {"rows": [asdict(r) for r in rows], "speedup_vs_reference": speedup}
    if "cpu" in backends:
        instruction_set, lanes = cpu_extension().simd()
        result["cpu_simd"] = {"instruction_set": instruction_set, "float_lanes": lanes}
    return result
