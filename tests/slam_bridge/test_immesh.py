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
    # A folder of one mesh and one trajectory (as lts slam import writes) is told apart as generic.
    detected = [lts, "slam", "import", tmp_path / "again", "--out", tmp_path / "detected"]
    assert subprocess.run(detected, capture_output=True, timeout=120).returncode == 0
    assert (tmp_path / "detected" / "trajectory.tum").read_bytes() == (
        tmp_path / "again" / "trajectory.tum"
    ).read_bytes()
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
    assert unknown.returncode == 2 and "lts slam import --format" in unknown.stderr


# --- ImMesh bags: /aft_mapped_to_init (nav_msgs/Odometry) and /cloud_registered (PointCloud2) ---

BAG_KINDS = ("ros1", "ros2", "mcap")


def registered_clouds(mesh: trimesh.Trimesh, count: int) -> list[np.ndarray]:
    """``count`` clouds of points on ``mesh`` (world frame, as ImMesh registers them)."""
    points, _ = trimesh.sample.sample_surface(mesh, 60_000, seed=1)
    return np.array_split(points.astype(np.float32), count)


def write_bag(
    path: Path,
    kind: str,
    trajectory: Trajectory,
    clouds: list[np.ndarray] | None = None,
    odometry_topic: str = "/aft_mapped_to_init",
    cloud_topic: str = "/cloud_registered",
) -> Path:
    """A bag as recorded while ImMesh runs: one Odometry (body pose in camera_init) per pose and
    one registered cloud per pose, stamped like the poses. ``kind``: ROS 1 ``.bag``, rosbag2
    folder, or bare ``.mcap``."""
    from rosbags.typesys import Stores, get_typestore

    ros1 = kind == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    types = store.types

    def header(i: int, t_ns: int) -> object:
        sec, nanosec = divmod(int(t_ns), 1_000_000_000)
        stamp = types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
        extra = {"seq": i} if ros1 else {}
        return types["std_msgs/msg/Header"](**extra, stamp=stamp, frame_id="camera_init")

    messages = []
    vector = types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    for i, (t, T) in enumerate(zip(trajectory.t_ns, trajectory.poses, strict=True)):
        q = Rotation.from_matrix(T[:3, :3]).as_quat()
        pose = types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=T[0, 3], y=T[1, 3], z=T[2, 3]),
            orientation=types["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
        )
        odometry = types["nav_msgs/msg/Odometry"](
            header=header(i, t),
            child_frame_id="body",
            pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=types["geometry_msgs/msg/TwistWithCovariance"](
                twist=types["geometry_msgs/msg/Twist"](linear=vector, angular=vector), covariance=np.zeros(36)
            ),
        )
        messages.append((odometry_topic, "nav_msgs/msg/Odometry", int(t), odometry))
        if clouds is not None:
            xyz = clouds[i]
            fields = [
                types["sensor_msgs/msg/PointField"](name=name, offset=4 * k, datatype=7, count=1)
                for k, name in enumerate("xyz")
            ]
            cloud = types["sensor_msgs/msg/PointCloud2"](
                header=header(i, t),
                height=1,
                width=len(xyz),
                fields=fields,
                is_bigendian=False,
                point_step=12,
                row_step=12 * len(xyz),
                data=np.ascontiguousarray(xyz).view(np.uint8).reshape(-1),
                is_dense=True,
            )
            messages.append((cloud_topic, "sensor_msgs/msg/PointCloud2", int(t), cloud))

    if kind == "mcap":
        from rig.session import SessionWriter

        with SessionWriter(path) as writer:
            for topic, _, t, msg in messages:
                writer.write_message(topic, msg, t, t)
        return path
    if ros1:
        from rosbags.rosbag1 import Writer
    else:
        from rosbags.rosbag2 import Writer
    with Writer(path) as writer:
        connections = {}
        for topic, msgtype, t, msg in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
            data = store.serialize_ros1(msg, msgtype) if ros1 else store.serialize_cdr(msg, msgtype)
            writer.write(connections[topic], t, data)
    return path


BAG_NAMES = {"ros1": "run.bag", "ros2": "run_bag", "mcap": "run.mcap"}


@pytest.mark.parametrize("kind", BAG_KINDS)
def test_immesh_bag_imports_its_odometry_and_a_mesh_of_the_registered_clouds(
    tmp_path: Path, kind: str
) -> None:
    from eval.geometry import compare_meshes

    mesh, trajectory = known_scene()
    write_bag(tmp_path / BAG_NAMES[kind], kind, trajectory, registered_clouds(mesh, len(trajectory)))
    report = import_immesh(tmp_path, tmp_path / "slam")  # no rec_mesh.ply, no log: all from the bag

    imported_mesh, imported = load_slam_dir(tmp_path / "slam")
    np.testing.assert_array_equal(imported.t_ns, trajectory.t_ns)
    assert np.abs(imported.poses - trajectory.poses).max() < 1e-6  # no KITTI conjugation on the bag
    metrics = compare_meshes(imported_mesh, mesh, threshold_m=0.05, samples=50_000)
    assert metrics.fscore > 0.95, metrics
    assert report.mesh_from == f"{tmp_path / BAG_NAMES[kind]} /cloud_registered"
    assert report.trajectory_from == f"{tmp_path / BAG_NAMES[kind]} /aft_mapped_to_init"
    assert report.log_vs_bag_m is None


def test_bag_odometry_wins_over_the_log_which_must_agree_with_it(tmp_path: Path) -> None:
    mesh, trajectory = known_scene()
    write_immesh_folder(tmp_path, mesh, trajectory)
    write_bag(tmp_path / "run.bag", "ros1", trajectory)  # odometry only: the mesh is rec_mesh.ply
    report = import_immesh(tmp_path, tmp_path / "slam")
    imported_mesh, imported = load_slam_dir(tmp_path / "slam")
    # The log alone is good to ~1e-6 (6 decimals, conjugation); the bag's double-precision poses come through.
    assert np.abs(imported.poses - trajectory.poses).max() < 1e-12
    assert report.trajectory_from.endswith("run.bag /aft_mapped_to_init")
    assert report.mesh_from == str(tmp_path / "rec_mesh.ply") and len(imported_mesh.faces) == 12
    assert report.log_vs_bag_m < 1e-5

    other_run = trajectory.transformed(T_left=make_transform(np.eye(3), np.full(3, 0.5)))  # 0.866 m away
    (tmp_path / "run.bag").unlink()
    write_bag(tmp_path / "run.bag", "ros1", other_run)
    with pytest.raises(
        InputError, match=r"run\.bag: the odometry and .*kitti_log_voxelmap\.txt differ by up to 0\.866 m"
    ):
        import_immesh(tmp_path, tmp_path / "slam2")


def test_missing_or_mistyped_bag_topics_are_named(tmp_path: Path) -> None:
    mesh, trajectory = known_scene()
    fast_lio_style = write_bag(tmp_path / "a.bag", "ros1", trajectory, odometry_topic="/Odometry")
    with pytest.raises(InputError) as error:
        import_immesh(fast_lio_style, tmp_path / "out")
    message = str(error.value)
    assert str(fast_lio_style) in message and "no topic /aft_mapped_to_init" in message
    assert "/Odometry (nav_msgs/msg/Odometry)" in message and "--odometry-topic" in message

    odometry_only = write_bag(tmp_path / "b.bag", "ros1", trajectory)  # and no rec_mesh.ply to fall back on
    with pytest.raises(
        InputError,
        match=r"b\.bag: /cloud_registered: no topic /cloud_registered in the bag; "
        r"it has: /aft_mapped_to_init \(nav_msgs/msg/Odometry\)",
    ):
        import_immesh(odometry_only, tmp_path / "out")

    swapped = write_bag(
        tmp_path / "c.bag",
        "ros1",
        trajectory,
        registered_clouds(mesh, len(trajectory)),
        odometry_topic="/cloud_registered",
        cloud_topic="/aft_mapped_to_init",
    )
    with pytest.raises(
        InputError, match=r"/aft_mapped_to_init holds sensor_msgs/msg/PointCloud2, expected Odometry"
    ):
        import_immesh(swapped, tmp_path / "out")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match=r"empty: no rec_mesh\.ply .* and no bag with /cloud_registered"):
        import_immesh(tmp_path / "empty", tmp_path / "out")


def test_lts_slam_import_reads_a_bag_given_alone_or_with_options(tmp_path: Path) -> None:
    import json
    import subprocess
    import sys

    mesh, trajectory = known_scene()
    bag = write_bag(
        tmp_path / "run.mcap",
        "mcap",
        trajectory,
        registered_clouds(mesh, len(trajectory)),
        odometry_topic="/odom",
    )
    lts = Path(sys.executable).parent / "lts"
    missing = subprocess.run(
        [lts, "slam", "import", bag, "--out", tmp_path / "slam"], capture_output=True, text=True, timeout=300
    )
    assert missing.returncode == 2
    assert "no topic /aft_mapped_to_init in the bag; it has: /cloud_registered" in missing.stderr
    result = subprocess.run(
        [lts, "slam", "import", bag, "--odometry-topic", "/odom", "--out", tmp_path / "slam", "--json"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["trajectory_from"] == f"{bag} /odom" and summary["mesh_from"] == f"{bag} /cloud_registered"
    _, imported = load_slam_dir(tmp_path / "slam")
    assert np.abs(imported.poses - trajectory.poses).max() < 1e-6
    # --bag: a bag kept elsewhere, beside an ImMesh folder that holds the mesh and the log.
    folder = tmp_path / "immesh"
    folder.mkdir()
    write_immesh_folder(folder, mesh, trajectory)
    beside = subprocess.run(
        [lts, "slam", "import", folder, "--bag", bag, "--odometry-topic", "/odom", "--out", tmp_path / "s2"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert beside.returncode == 0, beside.stderr
    assert f"trajectory from {bag} /odom (the log agrees to" in " ".join(beside.stderr.split())
