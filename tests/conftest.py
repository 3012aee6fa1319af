"""Shared fixtures: paths to the real sensor data beside the project, hypothesis profiles."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

PROJECT_ROOT = Path(__file__).resolve().parents[1]
REAL_DATA = PROJECT_ROOT.parent / "shared" / "data" / "real"
# Shared test helpers (console_script.py) import by name: the suite runs with --import-mode=importlib.
sys.path.append(str(Path(__file__).parent))

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


@pytest.fixture(scope="session")
def quick_room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``lts sim --quick``: 3 s of the room preset, 160x120, Mid-360-like LiDAR (8000 points/scan)."""
    from rig.sim.config import SimConfig
    from rig.sim.simulate import simulate

    out = tmp_path_factory.mktemp("quick_room")
    simulate(SimConfig().quick(), out)
    return out


@pytest.fixture
def lts_cli(monkeypatch, capsys):
    """``lts ARGS...`` run in this process as the console script does; returns
    ``(status, stdout, stderr)``."""
    from console_script import run_console_script

    from lts.cli import main

    return lambda *args: run_console_script(main, list(args), monkeypatch, capsys)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Files with slow tests run first (stable order otherwise): with ``make test``'s worker
    processes the longest files start at once instead of ending the run on one worker while the
    other has nothing left to do."""
    slow_files = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow_files)
