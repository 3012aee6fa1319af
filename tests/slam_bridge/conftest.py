"""Virtual-rig sessions shared by the slam_bridge tests."""

from pathlib import Path

import pytest
from truth_slam import write_truth_slam


def simulate_room(out: Path, **overrides) -> Path:
    from rig.sim.config import SimConfig
    from rig.sim.simulate import simulate

    simulate(SimConfig(**overrides), out)
    return out


@pytest.fixture(scope="session")
def gt_slam_dir(quick_room: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A SLAM folder made of the ground truth: the true mesh and the true LiDAR trajectory."""
    return write_truth_slam(quick_room, tmp_path_factory.mktemp("gt_slam"))
