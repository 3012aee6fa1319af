import subprocess
import sys
from pathlib import Path

import numpy as np
import open3d as o3d
import trimesh

from eval.geometry import compare_meshes
from rig.session import SessionWriter
from rig.session.ros_messages import typestore
from slam_bridge.slam_dir import load_slam_dir


def room() -> trimesh.Trimesh:
    """The inside of a 6 × 4 × 2.5 m box (normals facing in)."""
    box = trimesh.creation.box(extents=[6.0, 4.0, 2.5])
    box.invert()
    return box


def write_odometry_mcap(path: Path, positions: np.ndarray, t0_ns: int) -> None:
    types = typestore().types
    with SessionWriter(path) as writer:
        for i, p in enumerate(positions):
            t = t0_ns + i * 100_000_000
            sec, nsec = divmod(t, 1_000_000_000)
            header = types["std_msgs/msg/Header"](
                stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id="camera_init"
            )
            pose = types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
                orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            )
            twist = types["geometry_msgs/msg/Twist"](
                linear=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
            )
            msg = types["nav_msgs/msg/Odometry"](
                header=header,
                child_frame_id="body",
                pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                twist=types["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=np.zeros(36)),
            )
            writer.write_message("/Odometry", msg, t, t)


def test_fast_lio_map_and_odometry_import_to_a_mesh(tmp_path: Path) -> None:
    truth = room()
    points, _ = trimesh.sample.sample_surface(truth, 200_000, seed=0)
    points += np.random.default_rng(0).normal(0, 0.005, points.shape)
    (tmp_path / "PCD").mkdir()
    o3d.io.write_point_cloud(
        str(tmp_path / "PCD" / "scans.pcd"), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    )
    positions = np.c_[np.linspace(-2, 2, 30), np.zeros(30), np.full(30, -0.8)]
    write_odometry_mcap(tmp_path / "run.mcap", positions, 1_700_000_000_000_000_000)

    lts = Path(sys.executable).parent / "lts"
    result = subprocess.run(
        [lts, "slam", "import", tmp_path, "--out", tmp_path / "slam"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    mesh, trajectory = load_slam_dir(tmp_path / "slam")
    assert len(trajectory) == 30
    np.testing.assert_allclose(trajectory.translations, positions, atol=1e-9)
    metrics = compare_meshes(mesh, truth, threshold_m=0.05, samples=50_000)
    assert metrics.fscore > 0.95, metrics
    # Normals face the trajectory (into the room): the mesh encloses it with inward-facing faces.
    centres = mesh.triangles_center
    inward = np.einsum("ij,ij->i", mesh.face_normals, -centres) > 0
    assert inward.mean() > 0.95
