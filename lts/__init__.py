"""lts: the app layer above the five library packages — the ``lts`` command line, the pipeline
(``lts reconstruct``), the demo, the benchmarks and the stress suite.

It is the only place that knows the order of the stages; it calls the library entry points
(``calib``, ``slam_bridge``, ``splat``, ``eval``) directly.
"""

from __future__ import annotations

from rig.lazy import lazy_exports

_EXPORTS = {
    "ReconstructOptions": "lts.pipeline",
    "ReconstructResult": "lts.pipeline",
    "reconstruct": "lts.pipeline",
    "run_demo": "lts.demo",
    "StageRecord": "lts.stages",
    "StageRunner": "lts.stages",
    "fingerprint": "lts.stages",
}
__all__, __getattr__ = lazy_exports(__name__, _EXPORTS)
