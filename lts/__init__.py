"""lts: the app layer above the five library packages — the ``lts`` command line, the pipeline
(``lts reconstruct``), the demo, the benchmarks and the stress suite.

It is the only place that knows the order of the stages; it calls the library entry points
(``calib``, ``slam_bridge``, ``splat``, ``eval``) directly.
"""
