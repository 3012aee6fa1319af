"""eval: photometric and geometric metrics, leaned views, physics collision test, reports, benchmarks.

The offline ``lts`` command line is mounted in :mod:`eval.cli`.
"""
