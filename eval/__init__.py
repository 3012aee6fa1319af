"""eval: photometric and geometric metrics, leaned-view holes, physics collision test, the
evaluation of a training run (``lts eval``) and its HTML report.

Names are imported on first use (PEP 562) so that ``lts --help``, which imports this package, does
not load torch.
"""

from __future__ import annotations

from rig.lazy import lazy_exports

_EXPORTS = {
    "GeometricMetrics": "eval.geometry",
    "compare_meshes": "eval.geometry",
    "compare_point_sets": "eval.geometry",
    "frustum_mask": "eval.geometry",
    "sample_surface": "eval.geometry",
    "LpipsResult": "eval.photometric",
    "LpipsAlex": "eval.lpips_net",
    "load_lpips": "eval.lpips_weights",
    "download_weights": "eval.lpips_weights",
    "lpips": "eval.photometric",
    "psnr": "eval.photometric",
    "color_aligned": "eval.photometric",
    "ssim": "eval.photometric",
    "HoleResult": "eval.leaned_views",
    "leaned_poses": "eval.leaned_views",
    "mesh_hole_fraction": "eval.leaned_views",
    "hit_mask": "eval.leaned_views",
    "raycaster": "eval.leaned_views",
    "CollisionComparison": "eval.physics",
    "DropResult": "eval.physics",
    "compare_drops": "eval.physics",
    "drop_probes": "eval.physics",
    "footprint_grid": "eval.physics",
    "RunEvaluation": "eval.run_eval",
    "evaluate_run": "eval.run_eval",
    "write_eval_json": "eval.run_eval",
    "RunInputs": "eval.run_inputs",
    "resolve_run_inputs": "eval.run_inputs",
    "write_report": "eval.report",
}
__all__, __getattr__ = lazy_exports(__name__, _EXPORTS)
