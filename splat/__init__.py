"""splat: triangle model, differentiable rasteriser (reference / CPU / CUDA), losses, training, export.

Names are imported on first use (PEP 562) so that ``lts --help``, which imports this package,
does not load torch.
"""

from __future__ import annotations

from rig.lazy import lazy_exports

_EXPORTS = {
    "BackendUnavailableError": "splat.raster",
    "ErrorStats": "splat.raster",
    "RenderOutput": "splat.raster",
    "render": "splat.raster",
}
__all__, __getattr__ = lazy_exports(__name__, _EXPORTS)
