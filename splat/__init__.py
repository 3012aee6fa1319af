"""splat: triangle model, differentiable rasteriser (reference / CPU / CUDA), losses, densification
strategies, training, export.

The run folder layout is in :mod:`splat.run_dir`; ``lts train`` is :mod:`splat.train_cli`.

Names are imported on first use (PEP 562) so that ``lts --help``, which imports this package,
does not load torch.
"""

from __future__ import annotations

from rig.lazy import lazy_exports

_EXPORTS = {
    "BackendUnavailableError": "splat.raster",
    "DominantSums": "splat.raster",
    "RenderOutput": "splat.raster",
    "render": "splat.raster",
    "TriangleModel": "splat.model",
    "load_model": "splat.model",
    "save_model": "splat.model",
    "TrainConfig": "splat.config",
    "make_config": "splat.config",
    "load_config": "splat.config",
    "TrainResult": "splat.trainer",
    "TrainingDivergedError": "splat.trainer",
    "TrainingInterruptedError": "splat.trainer",
    "train": "splat.trainer",
    "background_image": "splat.background",
    "background_sphere": "splat.background",
    "constant_background": "splat.background",
    "ViewExposures": "splat.exposure",
    "PoseCorrections": "splat.pose_corrections",
    "FarVertexSteps": "splat.far_vertex_steps",
    "export_mesh": "splat.export",
    "decouple_and_scale": "splat.init_mesh",
    "ground_fill": "splat.init_mesh",
    "delaunay_triangles": "splat.init_delaunay",
    "Strategy": "splat.strategy",
    "VarianceStrategy": "splat.strategy",
    "OpacityStrategy": "splat.strategy",
}
__all__, __getattr__ = lazy_exports(__name__, _EXPORTS)
