"""ATE and RPE of a trajectory against a reference, and ``lts trajectory compare``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from eval.trajectory_metrics import relative_pose_error
from rig.errors import InputError
from rig.trajectory import Trajectory
from rig.trajectory_io import write_tum
from rig.transforms import make_transform

LTS = Path(sys.executable).parent / "lts"


def _drive(n: int = 40, step: np.ndarray | None = None) -> Trajectory:
    """A car turning gently: 0.5 m forward and 1° of yaw per pose, 0.1 s apart."""
    step = (
        make_transform(Rotation.from_euler("z", 1, degrees=True).as_matrix(), [0.5, 0, 0])
        if step is None
        else step
    )
    poses = [np.eye(4)]
    for _ in range(n - 1):
        poses.append(poses[-1] @ step)
    return Trajectory.from_poses(np.arange(n, dtype=np.int64) * 10**8, np.stack(poses))


def test_rpe_is_zero_for_a_rigidly_moved_copy_and_sees_a_scale_error() -> None:
    reference = _drive()
    moved = reference.transformed(
        T_left=make_transform(Rotation.from_euler("xyz", [3, 5, 40], degrees=True).as_matrix(), [10, -2, 1])
    )
    exact = relative_pose_error(moved, reference)
    assert exact.translation_rmse_m < 1e-9 and exact.rotation_rmse_deg < 1e-6 and exact.pairs == 39
    step = make_transform(Rotation.from_euler("z", 1, degrees=True).as_matrix(), [0.52, 0, 0])
    long = relative_pose_error(_drive(step=step), reference, delta=10)
    assert long.translation_rmse_m == pytest.approx(0.2, rel=0.02) and long.rotation_rmse_deg < 1e-6
    with pytest.raises(InputError, match="delta"):
        relative_pose_error(moved, reference, delta=0)


def test_lts_trajectory_compare(tmp_path: Path) -> None:
    reference = _drive()
    write_tum(reference, tmp_path / "ref.tum")
    poses = reference.poses.copy()
    poses[:, 1, 3] += 0.01 * (-1.0) ** np.arange(len(reference))  # ±1 cm sideways
    noisy = Trajectory.from_poses(reference.t_ns, poses)
    write_tum(noisy, tmp_path / "est.tum")
    result = subprocess.run(
        [LTS, "trajectory", "compare", tmp_path / "est.tum", tmp_path / "ref.tum", "--json"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["ate_rmse_m"] == pytest.approx(0.01, rel=0.05) and report["poses"] == 40
    assert report["rpe_translation_rmse_m"] == pytest.approx(0.02, rel=0.05)
    bad = subprocess.run(
        [LTS, "trajectory", "compare", tmp_path / "est.tum", tmp_path / "ref.tum", "--align", "scale"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert bad.returncode == 2 and "--align" in bad.stderr and "Traceback" not in bad.stderr
