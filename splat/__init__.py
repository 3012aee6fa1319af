"""splat: triangle model, differentiable rasteriser (reference / CPU / CUDA), losses, training, export."""

from __future__ import annotations

from typing import Any

# The rasteriser imports torch; load it on first use so that `import splat` (and `lts --help`,
# which mounts splat.cli) stays fast.
_RASTER_EXPORTS = {"render", "RenderOutput", "ErrorStats", "BackendUnavailableError"}

__all__ = sorted(_RASTER_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _RASTER_EXPORTS:
        from splat import raster

        return getattr(raster, name)
    raise AttributeError(f"module 'splat' has no attribute {name!r}")
