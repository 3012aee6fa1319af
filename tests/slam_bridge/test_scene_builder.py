from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
import trimesh

from rig import Calibration, CameraModel, InputError, load_calibration
from rig.deskew import deskewed_points
from rig.session import SessionReader
from rig.trajectory_io import read_tum, write_tum
from rig.transforms import invert, transform_points
from slam_bridge.depth_image import remove_occluded, zbuffer_depth
from slam_bridge.keyframe_lidar import keyframe_windows
from slam_bridge.keyframe_selection import frame_stamps
from slam_bridge.prepare_config import PrepareConfig
from slam_bridge.scene import load_scene
from slam_bridge.scene_builder import build_scene


def ground_truth_depth(mesh_path: Path, camera: CameraModel, T_world_cam: np.ndarray) -> np.ndarray:
    """Depth (z) of the true mesh along every pixel ray, by an independent open3d ray cast."""
    mesh = trimesh.load(mesh_path, process=False)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(mesh.vertices.astype(np.float32)), o3d.core.Tensor(mesh.faces.astype(np.uint32))
    )
    u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    rays = np.c_[(u.ravel() - camera.cx) / camera.fx, (v.ravel() - camera.cy) / camera.fy, np.ones(u.size)]
    dirs = rays @ T_world_cam[:3, :3].T
    norms = np.linalg.norm(dirs, axis=1, keepdims=True)
    origin = np.broadcast_to(T_world_cam[:3, 3], dirs.shape)
    hits = scene.cast_rays(o3d.core.Tensor(np.c_[origin, dirs / norms].astype(np.float32)))
    return (hits["t_hit"].numpy() / norms[:, 0]).reshape(camera.height, camera.width)


@pytest.fixture(scope="module")
def gt_scene(quick_room: Path, gt_slam_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scene")
    calibration = load_calibration(quick_room / "ground_truth" / "calib.yaml")
    build_scene(quick_room / "session.mcap", calibration, gt_slam_dir, out)
    return out


def test_keyframe_poses_follow_the_true_camera_trajectory(gt_scene: Path, quick_room: Path) -> None:
    scene = load_scene(gt_scene)
    truth = read_tum(quick_room / "ground_truth" / "trajectory.tum")
    # Frames over 0..3 s: 0.5 s would give 7 keyframes; a recording this short gets one per 0.2 s.
    assert scene.options.keyframe_interval_s == pytest.approx(0.2)
    assert len(scene.keyframes) == 16  # at 0.0, 0.2, ..., 3.0 s
    assert [k.split for k in scene.keyframes].count("test") == 2  # every eighth
    for keyframe in scene.keyframes:
        np.testing.assert_allclose(keyframe.T_world_cam, truth.interpolate(keyframe.t_ns), atol=1e-6)


def test_lidar_depth_agrees_with_ground_truth_depth(gt_scene: Path, quick_room: Path) -> None:
    scene = load_scene(gt_scene)
    sigma = 0.015  # the simulator's default range noise
    errors = []
    for keyframe in scene.keyframes:
        depth = scene.depth(keyframe)
        truth = ground_truth_depth(
            quick_room / "ground_truth" / "mesh.ply", scene.camera, keyframe.T_world_cam
        )
        valid = depth > 0
        assert valid.mean() > 0.05  # the sweeps between its neighbours 0.2 s away: ~8 % of the pixels
        errors.append(np.abs(depth[valid] - truth[valid]))
    errors = np.concatenate(errors)
    assert np.median(errors) < 1.5 * sigma
    assert np.mean(errors > 0.10) < 0.01  # occlusion leaks handled


def _static_and_moving_points(scans: list, trajectory) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each scan's de-skewed world points ``(N, 3)`` the see-through test keeps, and those it marks."""
    from rig.dynamic_points import DEFAULT_DYNAMIC, label_dynamic

    def sweeps():
        for s in scans:
            world = deskewed_points(s.points, s.point_times_ns(host=True), trajectory)
            T = trajectory.interpolate(np.array([s.t_host]), clamp=True)[0]
            yield s.t_host * 1e-9, transform_points(invert(T), world), T

    return [
        (view.points_world[~moving], view.points_world[moving])
        for _, view, moving in label_dynamic(sweeps(), DEFAULT_DYNAMIC)
    ]


def test_depth_from_the_stored_points_equals_the_depth_image_lts_prepare_stored_before(
    gt_scene: Path, quick_room: Path, gt_slam_dir: Path
) -> None:
    """Format 1 z-buffered each keyframe's window of points into a depth image; the depth made from
    the stored camera-frame points is the same, pixel for pixel (both without the points the
    see-through test calls moving, nor the static ones of the same scan beside those in the image)."""
    from slam_bridge.keyframe_lidar import in_view, off_moving_pixels

    scene = load_scene(gt_scene)
    calibration = load_calibration(quick_room / "ground_truth" / "calib.yaml")
    trajectory = read_tum(gt_slam_dir / "trajectory.tum")
    scans = list(SessionReader(quick_room / "session.mcap").scans("/lidar/points"))
    labelled = _static_and_moving_points(scans, trajectory)
    offset_ns = round(calibration.time_offset_s * 1e9)
    t = [k.t_ns for k in scene.keyframes]
    margin = int(scene.options.keyframe_interval_s * 1e9)
    for n, keyframe in enumerate(scene.keyframes):
        lo = t[n - 1] if n > 0 else t[n] - margin
        hi = t[n + 1] if n + 1 < len(t) else t[n] + margin
        T_cam_world = invert(keyframe.T_world_cam)
        kept = []
        for i, scan in enumerate(scans):
            if lo <= scan.t_host + offset_ns <= hi:
                static, moving = (
                    in_view(transform_points(T_cam_world, p), scene.camera) for p in labelled[i]
                )
                kept.append(off_moving_pixels(static, moving, scene.camera))
        static = np.concatenate(kept).astype(np.float64)
        before = remove_occluded(zbuffer_depth(static, scene.camera), 7)
        np.testing.assert_array_equal(scene.depth(keyframe), before)


def test_a_keyframes_lidar_file_is_read_once(gt_scene: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    scene = load_scene(gt_scene)
    reads = []
    load = np.load
    monkeypatch.setattr(
        np, "load", lambda path, *a, **k: reads.append(Path(path).parent.name) or load(path, *a, **k)
    )
    keyframe = scene.keyframes[0]
    first = scene.depth(keyframe)
    np.testing.assert_array_equal(scene.depth(keyframe), first)
    assert len(scene.lidar(keyframe).points) == (first > 0).sum()
    assert reads == ["lidar"]


def test_scene_records_its_format_and_options(gt_scene: Path) -> None:
    import json

    data = json.loads((gt_scene / "scene.json").read_text())
    assert data["format_version"] == 2
    options = load_scene(gt_scene).options
    assert options == PrepareConfig(keyframe_interval_s=options.keyframe_interval_s)  # the one it used
    assert options.keyframe_interval_s == pytest.approx(0.2)  # six frame periods of 30 Hz
    assert not (gt_scene / "depth").exists()


def test_keyframe_windows_reach_the_neighbouring_keyframes() -> None:
    lo, hi = keyframe_windows(np.array([10, 20, 35]) * 10**9, 0.5)
    np.testing.assert_array_equal(lo, np.array([9.5, 10, 20]) * 1e9)
    np.testing.assert_array_equal(hi, np.array([20, 35, 35.5]) * 1e9)


def test_frame_stamps_and_chosen_frames_without_decoding_the_rest(quick_room: Path) -> None:
    reader = SessionReader(quick_room / "session.mcap")
    topic = "/camera/image/compressed"
    frames = list(reader.frames(topic))
    np.testing.assert_array_equal(frame_stamps(reader, topic), [f.t_host for f in frames])
    chosen = list(reader.frames_at(topic, np.array([1, 4])))
    assert [f.t_host for f in chosen] == [frames[1].t_host, frames[4].t_host]
    np.testing.assert_array_equal(chosen[1].image, frames[4].image)


def test_normal_prior_faces_the_camera(gt_scene: Path) -> None:
    scene = load_scene(gt_scene)
    normals = scene.normals(scene.keyframes[0])
    hit = np.linalg.norm(normals, axis=-1) > 0
    assert hit.mean() > 0.95
    np.testing.assert_allclose(np.linalg.norm(normals[hit], axis=-1), 1.0, atol=1e-4)
    camera = scene.camera
    u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    rays = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones(u.shape)], axis=-1)
    assert (np.einsum("ij,ij->i", normals[hit], rays[hit]) < 0).all()  # every visible face looks back


def test_images_are_undistorted(gt_scene: Path) -> None:
    scene = load_scene(gt_scene)
    assert scene.camera.model == "pinhole" and not scene.camera.dist.any()
    image = scene.image(scene.keyframes[0])
    assert image.shape == (scene.camera.height, scene.camera.width, 3) and image.std() > 10


def test_calibration_of_another_image_size_is_refused(
    quick_room: Path, gt_slam_dir: Path, tmp_path: Path
) -> None:
    calibration = load_calibration(quick_room / "ground_truth" / "calib.yaml")
    camera = calibration.camera
    wrong = Calibration(
        CameraModel(
            camera.model, camera.width * 2, camera.height * 2, camera.K * [[2], [2], [1]], camera.dist
        ),
        calibration.T_cam_lidar,
        calibration.time_offset_s,
    )
    with pytest.raises(InputError, match="calibration's camera is"):
        build_scene(quick_room / "session.mcap", wrong, gt_slam_dir, tmp_path / "scene")


def test_trajectory_that_misses_the_camera_times_is_refused(
    quick_room: Path, gt_slam_dir: Path, tmp_path: Path
) -> None:
    truth = read_tum(gt_slam_dir / "trajectory.tum")
    shifted = type(truth).from_poses(truth.t_ns + 3_600_000_000_000, truth.poses)
    slam = tmp_path / "slam"
    slam.mkdir()
    (slam / "mesh.ply").write_bytes((gt_slam_dir / "mesh.ply").read_bytes())
    write_tum(shifted, slam / "trajectory.tum")
    calibration = load_calibration(quick_room / "ground_truth" / "calib.yaml")
    with pytest.raises(InputError, match="covers none of the camera frames"):
        build_scene(quick_room / "session.mcap", calibration, slam, tmp_path / "scene")


def test_load_scene_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not a scene folder"):
        load_scene(tmp_path)
    (tmp_path / "scene.json").write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        load_scene(tmp_path)


def test_precomputed_normal_maps_replace_the_mesh_prior(
    quick_room: Path, gt_slam_dir: Path, tmp_path: Path
) -> None:
    from rig.session import SessionReader

    calibration = load_calibration(quick_room / "ground_truth" / "calib.yaml")
    camera = calibration.camera
    folder = tmp_path / "normals"
    folder.mkdir()
    frames = list(SessionReader(quick_room / "session.mcap").frames("/camera/image/compressed"))
    up = np.zeros((camera.height, camera.width, 3), dtype=np.float32)
    up[..., 1] = -1.0  # every pixel "faces up" (camera y points down)
    for index, frame in enumerate(frames):
        if index % 2:
            np.save(folder / f"{frame.t_host}.npy", up)
        else:
            import cv2

            cv2.imwrite(
                str(folder / f"{index:06d}.png"),
                cv2.cvtColor(((up + 1) * 127.5).astype(np.uint8), cv2.COLOR_RGB2BGR),
            )
    from slam_bridge.prepare_config import PrepareConfig

    build_scene(
        quick_room / "session.mcap",
        calibration,
        gt_slam_dir,
        tmp_path / "scene",
        PrepareConfig(normals_dir=folder),
    )
    scene = load_scene(tmp_path / "scene")
    normals = scene.normals(scene.keyframes[1])
    valid = np.linalg.norm(normals, axis=-1) > 0
    assert valid.mean() > 0.8  # undistortion leaves only the border empty
    np.testing.assert_allclose(
        normals[valid], np.broadcast_to([0.0, -1.0, 0.0], normals[valid].shape), atol=0.01
    )
    (folder / f"{frames[0].t_host}.npy").unlink(missing_ok=True)
    for p in folder.glob("000000.png"):
        p.unlink()
    with pytest.raises(InputError, match="no normal map for frame 0"):
        build_scene(
            quick_room / "session.mcap",
            calibration,
            gt_slam_dir,
            tmp_path / "s2",
            PrepareConfig(normals_dir=folder),
        )


def test_sparse_points_lie_on_the_true_surface(quick_room: Path, gt_slam_dir: Path, tmp_path: Path) -> None:
    from slam_bridge.prepare_config import PrepareConfig

    calibration = load_calibration(quick_room / "ground_truth" / "calib.yaml")
    build_scene(
        quick_room / "session.mcap",
        calibration,
        gt_slam_dir,
        tmp_path / "scene",
        PrepareConfig(sparse_points=True),
    )
    points, colors = load_scene(tmp_path / "scene").sparse_points()
    assert len(points) > 30 and colors.shape == (len(points), 3)  # 7 keyframes of 160x120
    mesh = trimesh.load(quick_room / "ground_truth" / "mesh.ply", process=False)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(mesh.vertices.astype(np.float32)), o3d.core.Tensor(mesh.faces.astype(np.uint32))
    )
    distance = scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()
    assert np.median(distance) < 0.15  # 160x120 and short baselines; 2.7 cm on the 20 s room at 320x240


def test_scene_without_sparse_points_says_how_to_get_them(gt_scene: Path) -> None:
    with pytest.raises(InputError, match="--sparse-points"):
        load_scene(gt_scene).sparse_points()


def test_keyframes_by_motion(quick_room: Path, gt_slam_dir: Path, tmp_path: Path) -> None:
    import json
    import subprocess
    import sys

    lts = Path(sys.executable).parent / "lts"
    calib = quick_room / "ground_truth" / "calib.yaml"
    args = [lts, "prepare", quick_room / "session.mcap", "--calib", calib, "--slam", gt_slam_dir, "--json"]
    by_motion = subprocess.run(
        [*args, "--out", tmp_path / "m", "--keyframe-motion", "0.2", "10"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert by_motion.returncode == 0, by_motion.stderr
    scene = load_scene(tmp_path / "m")
    centres = np.array([k.T_world_cam[:3, 3] for k in scene.keyframes])
    steps = np.linalg.norm(np.diff(centres, axis=0), axis=1)
    assert json.loads(by_motion.stdout)["keyframes"] == len(scene.keyframes) >= 2
    assert (steps >= 0.2).sum() >= len(steps) - 1  # all but turn-triggered ones moved 20 cm


def test_keyframe_lidar_keeps_the_scans_in_each_window_and_the_points_in_view() -> None:
    from rig.calibration import Calibration
    from rig.messages import Scan
    from rig.trajectory import Trajectory
    from slam_bridge.keyframe_lidar import keyframe_lidar
    from slam_bridge.scene import Keyframe

    camera = CameraModel("pinhole", 32, 24, [[30, 0, 15.5], [0, 30, 11.5], [0, 0, 1]], [])
    calibration = Calibration(camera, np.eye(4), 0.1)  # LiDAR stamps + 0.1 s = camera time
    trajectory = Trajectory.from_poses(np.array([0, 5 * 10**9]), np.stack([np.eye(4), np.eye(4)]))
    keyframes = [Keyframe("a", 10**9, np.eye(4), "train"), Keyframe("b", 2 * 10**9, np.eye(4), "train")]

    def scan(t_s: float, z: float) -> Scan:  # one point ahead (in view), one behind the camera
        points = np.array([[0.0, 0.0, z], [0.0, 0.0, -z]])
        return Scan(points, np.zeros(2), np.zeros(2), round(t_s * 1e9), None)

    # Camera times 0.45 (before a's window [0.5, 2]), 1.6 (both) and 2.4 s (b's window [1, 2.5] only).
    scans = [scan(0.35, 1.0), scan(1.5, 2.0), scan(2.3, 3.0)]
    points = keyframe_lidar(scans, trajectory, calibration, keyframes, camera, 0.5).static
    assert points[0].dtype == np.float32
    np.testing.assert_array_equal(points[0], [[0, 0, 2]])
    np.testing.assert_array_equal(points[1], [[0, 0, 2], [0, 0, 3]])


def test_static_points_beside_a_moving_objects_points_are_dropped() -> None:
    """A return the see-through test missed on a vehicle lies beside the ones it found in the same
    scan: static points within the moving mask's radius (1 % of the width, 3 px here) go."""
    from slam_bridge.keyframe_lidar import off_moving_pixels

    camera = CameraModel("pinhole", 320, 240, [[300, 0, 159.5], [0, 300, 119.5], [0, 0, 1]], [])
    moving = np.array([[0.0, 0.0, 10.0]], dtype=np.float32)  # pixel (159.5, 119.5)
    # 2 px and 4 px to the right of it (at 10 m, 1 px is 3.3 cm), and one on the far side.
    static = np.array([[2 / 30, 0, 10], [4 / 30, 0, 10], [-1.0, 0.5, 10]], dtype=np.float32)
    np.testing.assert_array_equal(off_moving_pixels(static, moving, camera), static[1:])
    np.testing.assert_array_equal(off_moving_pixels(static, moving[:0], camera), static)


def test_moving_points_at_the_top_of_the_lidars_field_are_found() -> None:
    """Rings from -24 to +2 degrees (a spinning LiDAR's field) and three stray returns above them:
    the points within 1 degree below the 20th highest return are at the top (the rings at 1.3 and
    2 degrees, and the strays)."""
    from rig.dynamic_points import SweepView
    from slam_bridge.keyframe_lidar import at_field_top

    rings = np.concatenate([np.arange(-24.0, 1.0), [1.3, 2.0]])  # 27 rings
    elevations = np.repeat(rings, 40)  # 40 returns each
    elevations = np.concatenate([elevations, [9.0, 12.0, 15.0]])
    azimuths = np.tile(np.linspace(0, 2 * np.pi, 40, endpoint=False), 27)
    azimuths = np.concatenate([azimuths, [0.0, 0.0, 0.0]])
    e, a = np.radians(elevations), azimuths
    sensor = 10.0 * np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=1)
    pose = np.eye(4)
    pose[:3, 3] = [5.0, -2.0, 1.7]  # the sweep's pose in the world
    view = SweepView(0.0, pose, transform_points(pose, sensor), np.zeros((0, 0), np.float32))
    top = at_field_top(view)
    np.testing.assert_array_equal(top, elevations > 1.0)
    assert not at_field_top(SweepView(0.0, pose, transform_points(pose, sensor[:5]), view.ranges)).any()


def test_keyframe_points_are_written_where_a_keyframe_has_them(tmp_path: Path) -> None:
    from slam_bridge.keyframe_lidar import KeyframePoints, write_keyframe_lidar
    from slam_bridge.scene import LIDAR_DIR, MOVING_DIR, MOVING_TOP_DIR, Keyframe

    keyframes = [Keyframe(name, 0, np.eye(4), "train") for name in ("a", "b")]
    point, none = np.ones((1, 3), np.float32), np.zeros((0, 3), np.float32)
    points = KeyframePoints([point, point], [point, point], [point, none])
    done = []
    write_keyframe_lidar(tmp_path, keyframes, points, lambda: done.append(1))
    assert len(done) == 2
    assert sorted(p.name for p in (tmp_path / LIDAR_DIR).iterdir()) == ["a.npy", "b.npy"]
    assert sorted(p.name for p in (tmp_path / MOVING_DIR).iterdir()) == ["a.npy", "b.npy"]
    assert [p.name for p in (tmp_path / MOVING_TOP_DIR).iterdir()] == ["a.npy"]
    np.testing.assert_array_equal(np.load(tmp_path / MOVING_TOP_DIR / "a.npy"), point)


def test_a_moving_object_cut_by_the_lidars_field_is_masked_up_its_columns() -> None:
    """A lorry's returns at the top of the field at 10 m: its pixel columns are masked up to the row
    4 m higher (120 px at a 300 px focal length), and no higher."""
    from slam_bridge.depth_image import MOVING_MASK_ABOVE_M, moving_pixel_mask

    camera = CameraModel("pinhole", 320, 240, [[300, 0, 159.5], [0, 300, 119.5], [0, 0, 1]], [])
    top_row = np.array([[0.0, 0.5, 10.0]])  # pixel (159.5, 134.5)
    below = np.array([[0.0, 1.5, 10.0]])  # pixel (159.5, 164.5)
    points = np.concatenate([top_row, below])
    plain = moving_pixel_mask(points, camera)
    cut = moving_pixel_mask(points, camera, top_row)
    assert (cut >= plain).all() and not plain[100, 160]
    highest = round(134.5 - 300 * MOVING_MASK_ABOVE_M / 10.0)  # 14.5 rounds to 14
    assert cut[highest:135, 160].all() and not cut[: highest - 4, 160].any()
    assert not cut[100, 170]  # other columns keep the plain mask
    np.testing.assert_array_equal(moving_pixel_mask(points, camera, top_row[:0]), plain)


@pytest.mark.parametrize(
    ("span_s", "fps", "interval_s", "count"),
    [
        (19.97, 30, 0.5, 40),
        (7.7, 10, 0.2, 39),
        (12.0, 30, 0.3, 41),
        (2.97, 30, 0.2, 15),
        (60.0, 30, 0.5, 121),
    ],
)
def test_default_keyframe_interval_gives_short_recordings_40_keyframes(span_s, fps, interval_s, count):
    from types import SimpleNamespace

    from slam_bridge.keyframe_selection import default_interval

    t = (np.arange(0, span_s + 1e-9, 1 / fps) * 1e9).astype(np.int64)
    everywhere = SimpleNamespace(covers=lambda stamps: np.ones(len(stamps), dtype=bool))
    interval = default_interval(t, everywhere, SimpleNamespace(time_offset_s=0.0))
    assert interval == pytest.approx(interval_s, abs=1e-6)
    assert len(t[:: round(interval * fps)]) == count


def driving(speed_mps: float, fps: float, span_s: float = 4.0) -> tuple[np.ndarray, object]:
    """Frame stamps ``(N,)`` and a straight trajectory at ``speed_mps`` along x covering them."""
    from rig.trajectory import Trajectory

    t = (np.arange(0, span_s + 1e-9, 1 / fps) * 1e9).astype(np.int64)
    poses = np.repeat(np.eye(4)[None], 2, axis=0)
    poses[1, 0, 3] = speed_mps * (span_s + 1)
    return t, Trajectory.from_poses(np.array([0, int((span_s + 1) * 1e9)]), poses)


@pytest.mark.parametrize(
    ("speed_mps", "fps", "max_travel_m", "steps_m"),
    [
        (10.0, 10, 1.0, {1.0}),  # a car at speed: every 10 Hz frame, 1 m apart
        (10.0, 10, 0.0, {5.0}),  # by time alone: 0.5 s, 5 m apart
        (3.0, 30, 1.0, {1.0}),  # the virtual street: 1 m instead of 1.5 m
        (0.45, 30, 1.0, {0.225}),  # a walking robot never reaches it: one per 0.5 s
    ],
)
def test_keyframes_by_time_and_distance_travelled(speed_mps, fps, max_travel_m, steps_m) -> None:
    from slam_bridge.keyframe_selection import describe_spacing, select_keyframes

    t, trajectory = driving(speed_mps, fps)
    calibration = Calibration(
        CameraModel("pinhole", 32, 24, [[30, 0, 15.5], [0, 30, 11.5], [0, 0, 1]], []), np.eye(4), 0.0
    )
    chosen = select_keyframes(t, trajectory, calibration, 0.5, max_travel_m=max_travel_m)
    steps = np.diff(speed_mps * t[chosen] * 1e-9)
    assert set(np.round(steps, 3)) == steps_m
    spacing = describe_spacing(t[chosen], 0.5, None, max_travel_m)
    sooner = len(steps) if steps_m != {speed_mps * 0.5} else 0
    assert spacing == "one per 0.5 s" + (
        f" or 1 m travelled ({sooner} sooner by distance)" if max_travel_m else ""
    )


def test_a_scene_made_before_the_distance_rule_reads_as_keyframes_by_time(tmp_path: Path) -> None:
    data = PrepareConfig().to_json()
    del data["keyframe_max_travel_m"]
    assert PrepareConfig.from_json(data, tmp_path / "scene.json").keyframe_max_travel_m == 0.0
    with pytest.raises(InputError, match="keyframe_max_travel_m: expected metres >= 0"):
        PrepareConfig(keyframe_max_travel_m=-1.0)
