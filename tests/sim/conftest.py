"""A quick simulated run shared by the virtual-rig tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.sim.config import SimConfig


@pytest.fixture(scope="session")
def quick_config() -> SimConfig:
    return SimConfig(seed=7).quick()


@pytest.fixture(scope="session")
def quick_run(tmp_path_factory: pytest.TempPathFactory, quick_config: SimConfig) -> Path:
    """Output folder of ``lts sim OUT --quick --seed 7`` (through the Python API)."""
    from rig.sim.simulate import simulate

    out = tmp_path_factory.mktemp("sim_quick")
    simulate(quick_config, out)
    return out
