"""Virtual-rig sessions: time offset from motion, the whole session command, straight driving."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rig.calibration import Calibration, load_calibration, save_calibration
from rig.transforms import distance_and_angle, make_transform

from .test_targetless import perturb

LTS = Path(sys.executable).parent / "lts"
pytestmark = pytest.mark.slow


def _simulate(out: Path, **options) -> Path:
    sim_config = pytest.importorskip("rig.sim.config")
    sim = pytest.importorskip("rig.sim.simulate")
    sim.simulate(sim_config.SimConfig(**options), out)
    return out


@pytest.fixture(scope="module")
def room_session(tmp_path_factory) -> Path:
    """The default 20 s room run (default noise), with its ground truth."""
    return _simulate(tmp_path_factory.mktemp("room"), preset="room", seed=0)


def _lts(*args) -> subprocess.CompletedProcess:
    return subprocess.run([LTS, *map(str, args)], capture_output=True, text=True, timeout=600)


def test_time_offset_within_2_ms(room_session: Path) -> None:
    truth = load_calibration(room_session / "ground_truth" / "calib.yaml").time_offset_s
    result = _lts("calibrate", "time", room_session / "session.mcap", "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["verdict"] == "ok", summary["reasons"]
    assert abs(summary["time_offset_s"] - truth) < 0.002


def test_session_command_writes_calibration(room_session: Path, tmp_path: Path) -> None:
    truth = load_calibration(room_session / "ground_truth" / "calib.yaml")
    init = tmp_path / "init.yaml"
    save_calibration(
        Calibration(truth.camera, perturb(truth.T_cam_lidar, np.random.default_rng(0)), 0.0), init
    )
    out = tmp_path / "calib.yaml"
    start = time.monotonic()
    result = _lts("calibrate", room_session / "session.mcap", "--out", out, "--init", init, "--json")
    elapsed = time.monotonic() - start
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    written = load_calibration(out)
    assert abs(written.time_offset_s - truth.time_offset_s) < 0.002
    np.testing.assert_allclose(written.camera.K, truth.camera.K)
    extrinsic = summary["extrinsic"]
    assert extrinsic["method"].startswith("targetless (photo-consistency")
    estimate = np.asarray(extrinsic["T_cam_lidar"])
    translation_m, angle = distance_and_angle(estimate, truth.T_cam_lidar)
    # From 2° / 10 cm off to within the benchmark's success bounds (0.1-0.2° / 0.5-4 cm on the
    # 10 s room sessions of lts bench calib), but for the height: the robot turns about the
    # vertical only, and on this 20 s room the cost along the camera's y has a second valley
    # 10-12 cm above the truth, 2 % dearer at the true rotation. Where the result ends along it
    # (3 or 11 cm, with time offsets 0.5 ms apart) it must say the frames hardly tell it.
    assert np.degrees(angle) < 0.5
    flat = [r for r in extrinsic["reasons"] if "hardly tell the translation" in r]
    error_cm = 100 * (estimate[:3, 3] - truth.T_cam_lidar[:3, 3])
    if flat:
        assert extrinsic["verdict"] != "ok" and "[0.0, 1.0, 0.0]" in flat[0], flat
        assert np.hypot(error_cm[0], error_cm[2]) < 5.0, error_cm
    else:
        assert translation_m < 0.05
    if extrinsic["verdict"] == "ok":
        np.testing.assert_allclose(written.T_cam_lidar, extrinsic["T_cam_lidar"])
    assert written.quality["time"]["verdict"] == "ok"
    print(
        f"session calibration took {elapsed:.1f} s; extrinsic: {extrinsic['verdict']}, "
        f"{np.degrees(angle):.3f}° {100 * translation_m:.2f} cm off"
    )


@pytest.fixture(scope="module")
def room_map(room_session: Path):
    from calib.session_calib import session_lidar_map
    from calib.session_data import load_session

    data = load_session(room_session / "session.mcap")
    return data, session_lidar_map(data)


def test_lidar_map_follows_the_truth(room_session: Path, room_map) -> None:
    """The map's trajectory is the LiDAR's (ATE after alignment) and its points lie on the room."""
    from eval.trajectory_metrics import absolute_trajectory_error
    from rig.trajectory_io import read_tum

    data, lidar_map = room_map
    assert len(lidar_map.trajectory) == len(data.scans)
    truth = read_tum(room_session / "ground_truth" / "trajectory_lidar.tum")
    assert absolute_trajectory_error(lidar_map.trajectory, truth).rmse_m < 0.03
    open3d = pytest.importorskip("open3d")
    import trimesh

    mesh = trimesh.load(room_session / "ground_truth" / "mesh.ply")
    scene = open3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        open3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
        open3d.core.Tensor(np.asarray(mesh.faces, np.uint32)),
    )
    # The map's world is the first sweep's frame: put it into the truth's world.
    first = truth.interpolate(lidar_map.trajectory.t_ns[:1], clamp=True)[0]
    world = lidar_map.points[::20] @ first[:3, :3].T + first[:3, 3]
    distance = scene.compute_distance(open3d.core.Tensor(world.astype(np.float32))).numpy()
    assert np.median(distance) < 0.03


def test_too_few_frames_are_poorly_constrained(room_map) -> None:
    from calib.photo_consistency import MIN_FRAMES, photo_consistency_extrinsic
    from calib.session_calib import CONSISTENCY_FRAMES, calm_frames, consistency_frames

    data, lidar_map = room_map
    frames = consistency_frames(data, lidar_map, 0.0, calm_frames(data, count=CONSISTENCY_FRAMES))[
        : MIN_FRAMES - 1
    ]
    T = np.eye(4)
    result = photo_consistency_extrinsic(frames, data.camera, lidar_map, T)
    assert result.verdict == "poorly constrained"
    assert f"only {MIN_FRAMES - 1} frames" in result.reasons[0]
    np.testing.assert_array_equal(result.T_cam_lidar, T)


def test_a_straight_drive_can_skip_the_search_it_could_not_apply(room_session: Path, room_map) -> None:
    """lts reconstruct applies only an ok extrinsic, which a straight drive never gets: its
    search is skipped, the guess kept whole and the verdict says why."""
    from calib.photo_consistency import photo_consistency_extrinsic
    from calib.session_calib import CONSISTENCY_FRAMES, calm_frames, consistency_frames

    data, lidar_map = room_map
    truth = load_calibration(room_session / "ground_truth" / "calib.yaml")
    frames = consistency_frames(data, lidar_map, 0.0, calm_frames(data, count=CONSISTENCY_FRAMES))[:8]
    for k, frame in enumerate(frames):  # 8 cm apart along the first frame's LiDAR x, not turning
        frame.T_world_lidar = frames[0].T_world_lidar @ make_transform(np.eye(3), (0.08 * k, 0.0, 0.0))
    result = photo_consistency_extrinsic(
        frames, data.camera, lidar_map, truth.T_cam_lidar, search_straight=False
    )
    assert result.verdict == "poorly constrained"
    (reason,) = result.reasons
    assert "turned at most 0.0°" in reason and "the guess was kept whole" in reason
    np.testing.assert_array_equal(result.T_cam_lidar, truth.T_cam_lidar)
    assert result.extra["kept_from_guess"]["travel_direction_cam"]


def test_a_wrong_time_offset_is_searched_with_the_extrinsic(room_session: Path, room_map) -> None:
    """Frames placed with an offset 10 ms short of the truth, the search allowed 20 ms either way
    (from the true extrinsic): it finds the offset within 3 ms (on the office's seeds 0-19 its
    median error was 0.9 ms) and says how sure it is."""
    from calib.photo_consistency import photo_consistency_extrinsic
    from calib.session_calib import CONSISTENCY_FRAMES, calm_frames, consistency_frames

    data, lidar_map = room_map
    truth = load_calibration(room_session / "ground_truth" / "calib.yaml")
    used = truth.time_offset_s - 0.010
    frames = consistency_frames(data, lidar_map, used, calm_frames(data, count=CONSISTENCY_FRAMES))
    result = photo_consistency_extrinsic(
        frames, data.camera, lidar_map, truth.T_cam_lidar, offset_reach_s=0.02
    )
    shift = result.extra["time_offset_shift"]
    assert abs(used + shift["shift_s"] - truth.time_offset_s) < 0.003, shift
    assert 0 < shift["interval_95_s"] < 0.01 and not shift["at_reach"] and shift["reach_s"] == 0.02
    # Not the translation: along the camera's y this room's cost is lowest 12 cm above the truth
    # (the truth costs 6 % more), with the true offset as well (docs/calibration.md).
    _, angle = distance_and_angle(result.T_cam_lidar, truth.T_cam_lidar)
    assert np.degrees(angle) < 0.3


def test_lidar_map_needs_two_sweeps() -> None:
    from calib.lidar_map import build_lidar_map
    from rig.errors import InputError

    with pytest.raises(InputError, match="only 0 usable LiDAR sweeps"):
        build_lidar_map([])


def test_session_without_a_guess_starts_from_the_motion(room_session: Path, tmp_path: Path) -> None:
    """--init with the camera alone (as lts calibrate intrinsics writes it) and no /tf_static: the
    rough extrinsic is the rotation between the sensors' angular velocities with a zero
    translation, and the report says where each part came from."""
    from calib.session_calib import MOTION_GUESS

    truth = load_calibration(room_session / "ground_truth" / "calib.yaml")
    camera_only = tmp_path / "cam.yaml"
    save_calibration(Calibration(truth.camera, has_extrinsic=False), camera_only)
    out = tmp_path / "calib.yaml"
    result = _lts("calibrate", room_session / "session.mcap", "--init", camera_only, "--out", out, "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["extrinsic_init"] == MOTION_GUESS
    assert summary["init_holds"] == "the camera alone (no T_cam_lidar)"
    extrinsic = summary["extrinsic"]
    translation_m, angle = distance_and_angle(np.asarray(extrinsic["T_cam_lidar"]), truth.T_cam_lidar)
    rotation_deg = np.degrees(angle)
    # Honest whichever way it ends: ok only when right.
    if extrinsic["verdict"] == "ok":
        assert rotation_deg < 0.5 and translation_m < 0.05
        assert extrinsic["applied"]
    else:
        assert not extrinsic["applied"] and extrinsic["reasons"]
    written = load_calibration(out)
    # The motion's rotation (1.8° off on this run), or better where the refinement vouched for itself.
    assert np.degrees(distance_and_angle(written.T_cam_lidar, truth.T_cam_lidar)[1]) < 3.0
    print(f"no guess: {extrinsic['verdict']}, estimate {rotation_deg:.2f}° {100 * translation_m:.1f} cm")


def test_straight_drive_refuses_time_offset(room_session: Path, tmp_path: Path) -> None:
    # Drive 1.8 m straight ahead from the room run's first pose, without turning.
    first = np.loadtxt(room_session / "ground_truth" / "trajectory.tum")[0]
    times = np.arange(0.0, 6.0, 1 / 30)
    heading = np.array([0.996, 0.087, 0.0])
    rows = [[t, *(first[1:4] + 0.3 * t * heading), *first[4:8]] for t in times]
    trajectory = tmp_path / "straight.tum"
    np.savetxt(trajectory, rows, fmt="%.9f")
    run = _simulate(
        tmp_path / "straight",
        mesh=str(room_session / "ground_truth" / "mesh.ply"),
        trajectory=str(trajectory),
        seed=1,
    )
    result = _lts("calibrate", "time", run / "session.mcap", "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["verdict"] == "poorly constrained"
    assert summary["reasons"]
    # Nor can the motion give a rough extrinsic: without --init the extrinsic is not run, and says why.
    result = _lts("calibrate", run / "session.mcap", "--out", tmp_path / "calib.yaml", "--json")
    assert result.returncode == 0, result.stderr
    extrinsic = json.loads(result.stdout)["extrinsic"]
    assert extrinsic["verdict"] == "not run"
    assert "--init" in extrinsic["reasons"][0]
    assert not load_calibration(tmp_path / "calib.yaml").has_extrinsic  # no identity written as if known
    # Started from the camera alone, a reconstruction stops at its calibrate stage, saying why,
    # instead of going on with an identity extrinsic.
    camera_only = tmp_path / "cam.yaml"
    save_calibration(
        Calibration(load_calibration(tmp_path / "calib.yaml").camera, has_extrinsic=False), camera_only
    )
    result = _lts("reconstruct", run / "session.mcap", "--init", camera_only, "--out", tmp_path / "run")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "no LiDAR-to-camera extrinsic: no rough T_cam_lidar" in result.stderr
    assert not (tmp_path / "run" / "calib.yaml").exists()


def test_odometry_offset_within_2_ms(room_session: Path) -> None:
    """Without the gyro the LiDAR motion comes from KISS-ICP odometry (see
    calib.motion.lidar_angular_velocity), timed to within 2 ms too."""
    truth = load_calibration(room_session / "ground_truth" / "calib.yaml").time_offset_s
    result = _lts("calibrate", "time", room_session / "session.mcap", "--lidar-motion", "odometry", "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["lidar_motion"] == "KISS-ICP odometry"
    assert summary["verdict"] == "ok", summary["reasons"]
    assert abs(summary["time_offset_s"] - truth) < 0.002
    offset_ms, std_ms = summary["time_offset_s"] * 1e3, summary["std_s"] * 1e3
    print(f"odometry time offset: {offset_ms:.1f} ± {std_ms:.1f} ms (true {truth * 1e3:.1f} ms)")
