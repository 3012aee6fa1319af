"""Shared fixtures: paths to the real sensor data beside the project, hypothesis profiles."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

PROJECT_ROOT = Path(__file__).resolve().parents[1]
REAL_DATA = PROJECT_ROOT.parent / "shared" / "data" / "real"

# "ci" keeps property tests short enough for the suite's time budget; "long" is for bug hunts:
#   HYPOTHESIS_PROFILE=long .venv/bin/pytest
settings.register_profile("ci", max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile(
    "long", max_examples=2000, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture(scope="session")
def real_data() -> Path:
    """Root of ../shared/data/real (skips the test when the shared data is not beside the project)."""
    if not REAL_DATA.is_dir():
        pytest.skip(f"real sensor data not found at {REAL_DATA}")
    return REAL_DATA


@pytest.fixture
def lts_cli(monkeypatch, capsys):
    """Run ``lts ARGS...`` in this process as the console script does (one-line errors, exit
    statuses); returns ``(status, stdout, stderr)``."""
    import sys

    from eval.cli import main

    def run(*args) -> tuple[int, str, str]:
        monkeypatch.setattr(sys, "argv", ["lts", *map(str, args)])
        monkeypatch.setenv("COLUMNS", "400")
        code = 0
        try:
            main()
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        out, err = capsys.readouterr()
        return code, out, err

    return run
