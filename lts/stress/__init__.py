"""The stress suite: numerical stability and bad input, runnable without pytest.

Each *area* has a case builder driven by a small parameter record and a check that returns the
problems it found (an empty list: the case passed):

=================  ==========================================================================
module             area
=================  ==========================================================================
``raster``         the rasteriser: degenerate triangles, extreme scales and intrinsics, NaN/Inf
``photometric``    PSNR and SSIM
``geometry``       point-set metrics (Chamfer, F-score)
``trajectory``     trajectory alignment (ATE)
``time_offset``    the camera-LiDAR time offset
``readers``        every file reader, on truncated, corrupted and NaN files (from ``samples``)
=================  ==========================================================================

The pytest suite in ``tests/stress`` draws the parameters with hypothesis;
:func:`~lts.stress.suite.run_stability_suite` draws them with a seeded random generator and counts,
per area, the cases tried, the failures found and the non-finite events caught (a NaN/Inf fed in
on purpose and rejected with :class:`~rig.errors.InputError`, or a degenerate input answered with
an explicit refusal). ``lts bench stability`` is :mod:`lts.stress.cli`. Hypothesis is a test
dependency only; nothing here needs it.

Names are imported on first use (PEP 562) so that importing the package does not load torch.
"""

from __future__ import annotations

from rig.lazy import lazy_exports

_EXPORTS = {
    "PROFILES": "lts.stress.suite",
    "AreaCounts": "lts.stress.suite",
    "run_stability_suite": "lts.stress.suite",
    "RasterCase": "lts.stress.raster",
    "TRIANGLE_KINDS": "lts.stress.raster",
    "check_raster": "lts.stress.raster",
    "check_raster_rejects_nonfinite": "lts.stress.raster",
    "check_raster_scale_invariance": "lts.stress.raster",
    "random_raster_case": "lts.stress.raster",
    "check_photometric": "lts.stress.photometric",
    "check_point_sets": "lts.stress.geometry",
    "check_alignment": "lts.stress.trajectory",
    "TimeOffsetCase": "lts.stress.time_offset",
    "check_time_offset": "lts.stress.time_offset",
    "MUTATIONS": "lts.stress.readers",
    "check_reader": "lts.stress.readers",
    "READER_KINDS": "lts.stress.samples",
    "write_sample": "lts.stress.samples",
    "time_limit": "lts.stress.guards",
}
__all__, __getattr__ = lazy_exports(__name__, _EXPORTS)
