"""Differentiable triangle rasteriser (Triangle Splatting / TS+ windows).

Stages: per-triangle set-up (:mod:`~splat.raster.project`, PyTorch; compiled twin in
:mod:`~splat.raster.setup_kernel`) → :mod:`~splat.raster.binning` (16x16 tiles) → a rasteriser:
the pure-PyTorch :mod:`~splat.raster.reference` (the specification), or a compiled kernel
(``csrc/``, CPU or CUDA) via :mod:`~splat.raster.kernel`. :func:`render` runs them all.
"""

from splat.raster.extension import BackendUnavailableError
from splat.raster.render import RenderOutput, render
from splat.raster.stats import DominantSums

__all__ = ["BackendUnavailableError", "DominantSums", "RenderOutput", "render"]
