from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from rig import InputError, Trajectory, make_transform
from rig.trajectory_io import ns_to_seconds_text
from slam_bridge.immesh import T_LC, import_immesh
from slam_bridge.slam_dir import load_slam_dir


def known_scene() -> tuple[trimesh.Trimesh, Trajectory]:
    """A closed box (12 outward faces) and a short trajectory inside... outside it, looking at it."""
    box = trimesh.creation.box(extents=[2.0, 1.0, 0.5])
    t_ns = 1_650_000_000_000_000_000 + np.arange(8, dtype=np.int64) * 100_000_000
    rotations = Rotation.from_euler(
        "zyx", np.c_[np.linspace(0, 0.6, 8), np.full(8, 0.05), np.zeros(8)]
    ).as_matrix()
    positions = np.c_[np.linspace(3.0, 4.0, 8), np.linspace(-1.0, 1.0, 8), np.full(8, 0.3)]
    return box, Trajectory.from_poses(t_ns, make_transform(rotations, positions))


def write_immesh_folder(
    folder: Path, mesh: trimesh.Trimesh, trajectory: Trajectory, log_in_subdir: bool = True
) -> None:
    """What ImMesh writes: a PCL binary PLY with unused vertices and some flipped, duplicated and
    degenerate faces, and a conjugated, 6-decimal TUM-like log."""
    rng = np.random.default_rng(0)
    unused = rng.uniform(-5, 5, (40, 3))
    vertices = np.vstack([unused[:20], mesh.vertices, unused[20:]])
    faces = mesh.faces + 20
    faces[[1, 4, 7]] = faces[[1, 4, 7]][:, ::-1]  # flipped
    faces = np.vstack([faces, faces[2][::-1], [[20, 20, 21]]])  # a duplicate and a degenerate face
    trimesh.Trimesh(vertices, faces, process=False).export(folder / "rec_mesh.ply", encoding="binary")
    logged = T_LC @ trajectory.poses @ np.linalg.inv(T_LC)
    quats = Rotation.from_matrix(logged[:, :3, :3]).as_quat()
    lines = [
        f"{ns_to_seconds_text(int(t))[:-3]} " + " ".join(f"{v:.6f}" for v in [*T[:3, 3], *q])
        for t, T, q in zip(trajectory.t_ns, logged, quats, strict=True)
    ]
    log_dir = folder / "Log" if log_in_subdir else folder
    log_dir.mkdir(exist_ok=True)
    (log_dir / "kitti_log_voxelmap.txt").write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("log_in_subdir", [True, False])
def test_immesh_folder_imports_to_the_known_mesh_and_trajectory(tmp_path: Path, log_in_subdir: bool) -> None:
    mesh, trajectory = known_scene()
    write_immesh_folder(tmp_path, mesh, trajectory, log_in_subdir)
    report = import_immesh(tmp_path, tmp_path / "slam")
    assert (report.unused_vertices, report.duplicate_faces, report.degenerate_faces) == (40, 1, 1)

    imported_mesh, imported = load_slam_dir(tmp_path / "slam")
    np.testing.assert_array_equal(imported.t_ns, trajectory.t_ns - trajectory.t_ns % 1000)
    assert np.abs(imported.poses - trajectory.poses).max() < 1e-5
    # Exactly the box: same vertices, the same 12 faces, all wound outwards again.
    assert len(imported_mesh.vertices) == 8 and len(imported_mesh.faces) == 12
    np.testing.assert_allclose(
        np.sort(imported_mesh.vertices, axis=0), np.sort(mesh.vertices, axis=0), atol=1e-6
    )
    assert imported_mesh.is_watertight and imported_mesh.is_winding_consistent
    assert imported_mesh.volume == pytest.approx(mesh.volume, rel=1e-6)  # positive: outward normals


def test_missing_files_are_named(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"no rec_mesh\.ply"):
        import_immesh(tmp_path, tmp_path / "out")
    trimesh.creation.box().export(tmp_path / "rec_mesh.ply")
    with pytest.raises(InputError, match=r"kitti_log_voxelmap\.txt"):
        import_immesh(tmp_path, tmp_path / "out")


def test_lts_slam_import_cli(tmp_path: Path) -> None:
    import json
    import subprocess
    import sys

    mesh, trajectory = known_scene()
    write_immesh_folder(tmp_path, mesh, trajectory)
    lts = Path(sys.executable).parent / "lts"
    args = [lts, "slam", "import", "--format", "immesh", tmp_path, "--out", tmp_path / "slam", "--json"]
    result = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["unused_vertices"] == 40
    assert (tmp_path / "slam" / "mesh.ply").is_file() and (tmp_path / "slam" / "trajectory.tum").is_file()
    generic = [lts, "slam", "import", "--format", "generic", tmp_path / "slam", "--out", tmp_path / "again"]
    assert subprocess.run(generic, capture_output=True, timeout=120).returncode == 0
    bad = subprocess.run(
        [lts, "slam", "import", "--format", "nope", tmp_path, "--out", tmp_path / "x"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 2 and "unknown format 'nope'" in bad.stderr


def test_pin_slam_folder_is_detected_and_imported(tmp_path: Path) -> None:
    import subprocess
    import sys

    from rig.trajectory_io import write_tum

    mesh, trajectory = known_scene()
    (tmp_path / "mesh").mkdir()
    trimesh.creation.icosphere().export(tmp_path / "mesh" / "mesh_frame_100.ply")
    mesh.export(tmp_path / "mesh" / "mesh_frame_1200.ply")  # the latest frame's mesh is the map
    write_tum(trajectory, tmp_path / "run_slam_poses_tum.txt")
    write_tum(
        type(trajectory).from_poses(trajectory.t_ns, trajectory.poses * 0 + np.eye(4)),
        tmp_path / "run_odom_poses_tum.txt",
    )
    lts = Path(sys.executable).parent / "lts"
    result = subprocess.run(
        [lts, "slam", "import", tmp_path, "--out", tmp_path / "slam"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    imported_mesh, imported = load_slam_dir(tmp_path / "slam")
    assert len(imported_mesh.faces) == 12
    assert np.abs(imported.poses - trajectory.poses).max() < 1e-12  # the loop-closed poses, not odometry
    unknown = subprocess.run(
        [lts, "slam", "import", tmp_path / "mesh", "--out", tmp_path / "x"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert unknown.returncode == 2 and "give --format" in unknown.stderr
