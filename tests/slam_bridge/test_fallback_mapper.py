import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from eval.geometry import compare_meshes
from eval.trajectory_metrics import absolute_trajectory_error
from rig.lidar_odometry import thinned
from rig.session import SessionReader
from rig.trajectory_io import read_tum
from slam_bridge.fallback_mapper import (
    canonical_order,
    cube_depth_images,
    fill_small_holes,
    run_mapper,
)
from slam_bridge.slam_dir import load_slam_dir

LTS = Path(sys.executable).parent / "lts"


def test_cube_map_puts_each_direction_on_its_face() -> None:
    directions = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    faces = cube_depth_images(directions * np.arange(2, 8)[:, None], resolution=8)
    for index, (T_sensor_face, depth) in enumerate(faces):
        assert np.count_nonzero(depth) == 1
        assert depth.max() == pytest.approx(index + 2)
        # The face camera's optical axis is the direction that landed on it.
        np.testing.assert_allclose(T_sensor_face[:3, 2], directions[index], atol=1e-12)


def test_small_holes_are_filled_only_between_agreeing_returns() -> None:
    depth = np.zeros((5, 5), dtype=np.float32)
    depth[2, 1], depth[2, 3] = 2.0, 2.05  # agree: the gap between them is filled
    depth[0, 0], depth[0, 2] = 1.0, 5.0  # a depth edge: left empty
    filled = fill_small_holes(depth)
    assert filled[2, 2] == pytest.approx(2.025)
    assert filled[0, 1] == 0.0


def test_mapper_on_a_quick_session(quick_room: Path) -> None:
    reader = SessionReader(quick_room / "session.mcap")
    result = run_mapper(reader.scans("/lidar/points"))
    truth = read_tum(quick_room / "ground_truth" / "trajectory_lidar.tum")
    ate = absolute_trajectory_error(result.trajectory, truth, use_orientation=True)
    assert result.scans_used == 30
    assert ate.rmse_m < 0.05
    assert len(result.mesh.faces) > 1000


def test_lts_slam_run_writes_the_same_slam_folder_with_one_or_two_threads(
    quick_room: Path, tmp_path: Path
) -> None:
    """Run as a user would, with one thread per library and twice with two: the same bytes (the
    registration runs on one thread whatever the machine; the sweeps' covariances, the TSDF and
    the canonical mesh order do not depend on the thread count)."""
    outputs = []
    for threads in ("1", "2", "2"):
        out = tmp_path / f"slam{len(outputs)}"
        env = {
            **os.environ,
            "OMP_NUM_THREADS": threads,
            "OPENBLAS_NUM_THREADS": threads,
            "MKL_NUM_THREADS": threads,
        }
        args = [LTS, "slam", "run", quick_room / "session.mcap", "--out", out, "--json"]
        result = subprocess.run(args, capture_output=True, text=True, timeout=600, env=env)
        assert result.returncode == 0, result.stderr
        summary = json.loads(result.stdout)
        mesh, trajectory = load_slam_dir(out)
        assert summary["poses"] == len(trajectory) == 30 and len(mesh.faces) == summary["faces"] > 1000
        assert summary["quality"]["verdict"] == "ok" and 0.1 <= summary["settings"]["voxel_m"] < 0.2
        assert json.loads((out / "mapping.json").read_text()) == summary
        outputs.append([(out / name).read_bytes() for name in ("trajectory.tum", "mesh.ply")])
    assert outputs[0] == outputs[1] == outputs[2]


@pytest.mark.slow
def test_mapper_on_the_default_room_meets_the_accuracy_targets(tmp_path: Path) -> None:
    from rig.sim.config import SimConfig
    from rig.sim.simulate import simulate

    simulate(SimConfig(), tmp_path)  # 20 s of the room preset
    result = run_mapper(SessionReader(tmp_path / "session.mcap").scans("/lidar/points"))
    truth = read_tum(tmp_path / "ground_truth" / "trajectory_lidar.tum")
    ate = absolute_trajectory_error(result.trajectory, truth, use_orientation=True)
    assert ate.rmse_m < 0.03
    mesh = result.mesh.copy()
    mesh.apply_transform(ate.T_ref_est)
    metrics = compare_meshes(mesh, trimesh.load(tmp_path / "ground_truth" / "mesh.ply", process=False), 0.1)
    assert metrics.fscore > 0.8


def test_canonical_order_numbers_one_surface_one_way() -> None:
    mesh = trimesh.creation.icosphere(subdivisions=2)
    rng = np.random.default_rng(0)
    shuffle, turn = rng.permutation(len(mesh.vertices)), rng.integers(0, 3, len(mesh.faces))
    inverse = np.argsort(shuffle)
    faces = np.take_along_axis(inverse[mesh.faces], (turn[:, None] + np.arange(3)) % 3, axis=1)
    faces = faces[rng.permutation(len(faces))]
    want = canonical_order(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    got = canonical_order(np.asarray(mesh.vertices)[shuffle], faces)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert trimesh.Trimesh(*got).is_winding_consistent and trimesh.Trimesh(*got).volume > 0


def test_thinned_sweeps_keep_every_ring() -> None:
    """A 64-ring sweep stored column by column, thinned to a quarter: every ring keeps its share
    (every fourth point would keep every fourth ring)."""
    chosen = thinned(64 * 1024, 16_384)
    assert abs(len(chosen) - 16_384) < 100
    per_ring = np.bincount(chosen % 64, minlength=64)
    assert per_ring.min() > 0.9 * per_ring.mean()
    per_column = np.bincount(chosen // 64, minlength=1024)
    assert np.all(per_column >= 8)
    assert thinned(100, 200) == slice(None)


def test_an_empty_mesh_is_said_in_the_summary() -> None:
    """A few sweeps map a trajectory but no surface the TSDF keeps: the summary says so and what to do."""
    from slam_bridge.map_session import MapSummary
    from slam_bridge.mapping_quality import MappingQuality

    settings = {"voxel_m": 0.6, "map_voxel_m": 1.8, "max_range_m": 60.0, "tsdf_voxel_m": 0.24}
    summary = MapSummary(
        "slam", 3, 3, 0, 0.5, 0.0, {**settings, "static_reregistration": True}, MappingQuality("ok")
    )
    assert "the mesh is empty" in summary.describe()[-1]
    assert not any("empty" in line for line in MapSummary(**{**summary.__dict__, "faces": 10}).describe())
