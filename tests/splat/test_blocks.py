"""Training in spatial blocks: partition, block scenes and settings, merge, and Ray runs end to end
(as the installed command, in subprocesses: Ray starts its own worker processes)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from training_scene import write_training_scene

from rig.errors import InputError
from rig.transforms import make_transform
from slam_bridge.prepare_config import PrepareConfig
from slam_bridge.scene import Keyframe, Scene, load_scene
from splat.blocks.block_scene import block_config, write_block_scene
from splat.blocks.merge import core_triangles, merge_models
from splat.blocks.partition import (
    Block,
    GroundFrame,
    Partition,
    ground_frame,
    partition_scene,
    read_partition,
)
from splat.config import make_config
from splat.model import TriangleModel
from splat.raster.scenes import pinhole

LTS = [sys.executable, "-c", "import sys; from lts.cli import main; sys.argv[0] = 'lts'; sys.exit(main())"]


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    return write_training_scene(tmp_path_factory.mktemp("scene"), n_views=8, spread_m=3.0, pitch_deg=60.0)


def _keyframes(centres: np.ndarray, yaw_deg: float = 0.0) -> list[Keyframe]:
    """Level cameras (OpenCV axes, y down = world −z) at ``centres`` ``(N, 3)`` facing ``yaw_deg``."""
    yaw = np.radians(yaw_deg)
    forward = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    R = np.column_stack([right, [0.0, 0.0, -1.0], forward])
    return [Keyframe(f"{i:03d}", i, make_transform(R, c), "train") for i, c in enumerate(centres)]


def test_the_ground_frame_follows_the_cameras_up_and_the_path_modulo_right_angles():
    along = np.radians(30)
    direction = np.array([np.cos(along), np.sin(along), 0.0])
    left = np.array([-np.sin(along), np.cos(along), 0.0])
    # An L-shaped path: 10 m along the direction, then 4 m at a right angle to it.
    path = [direction * s for s in np.linspace(0, 10, 21)] + [
        direction * 10 + left * s for s in np.linspace(0, 4, 9)
    ]
    frame = ground_frame(_keyframes(np.array(path) + np.array([0, 0, 1.2]), yaw_deg=30))
    assert np.allclose(frame.up, [0, 0, 1], atol=1e-9)
    assert abs(abs(frame.axes[0] @ direction) - 1) < 1e-6 and abs(abs(frame.axes[1] @ left) - 1) < 1e-6
    xy = frame.project(np.array(path))
    assert np.ptp(xy[:21, 1]) < 1e-6  # the first leg runs along one axis


class _Lidar:
    """A stand-in for a keyframe's LiDAR: ``points`` ``(N, 3)`` in the camera frame."""

    def __init__(self, points: np.ndarray):
        self.points = points.astype(np.float32)


def _corridor_scene(tmp_path: Path, n: int = 40) -> Scene:
    """Cameras every 0.5 m along x (20 m), each seeing the floor from 1 to 3 m ahead of it."""
    keyframes = _keyframes(np.column_stack([np.arange(n) * 0.5, np.zeros(n), np.full(n, 1.0)]))
    keyframes[-1] = Keyframe(keyframes[-1].name, keyframes[-1].t_ns, keyframes[-1].T_world_cam, "test")
    ahead = np.linspace(1.0, 3.0, 50)
    points = np.column_stack([np.zeros(50), np.full(50, 1.0), ahead])  # camera frame: 1 m below, ahead
    scene = Scene(tmp_path, pinhole(64, 48, 80.0), keyframes, tmp_path / "mesh.ply", PrepareConfig())
    for k in keyframes:
        scene._lidar[k.name] = _Lidar(points)
    return scene


def test_blocks_tile_the_plane_and_hold_their_budgets(tmp_path):
    scene = _corridor_scene(tmp_path)
    faces = np.column_stack([np.linspace(-1, 22, 1000), np.zeros(1000), np.zeros(1000)])
    whole = partition_scene(scene, faces, keyframe_budget=100, face_budget=10_000, margin_m=1.0)
    assert len(whole.blocks) == 1 and whole.blocks[0].n_train == 39  # within the budgets: one block
    parts = partition_scene(scene, faces, keyframe_budget=12, face_budget=10_000, margin_m=1.0)
    blocks = parts.blocks
    assert len(blocks) >= 4 and all(b.n_train <= 12 for b in blocks)
    assert [b.index for b in blocks] == list(range(len(blocks)))
    xy = parts.frame.project(faces)
    owners = np.stack([b.in_core(xy) for b in blocks])
    assert (owners.sum(axis=0) == 1).all()  # every point of the plane lies in exactly one core
    centres = parts.frame.project(np.stack([k.T_world_cam[:3, 3] for k in scene.keyframes]))
    for b in blocks:  # a block keeps every keyframe standing in its core, numbered along the path
        standing = {k.name for k, inside in zip(scene.keyframes, b.in_core(centres), strict=True) if inside}
        assert standing <= set(b.keyframes)
    firsts = [min(int(name) for name in b.keyframes) for b in blocks]
    assert firsts == sorted(firsts)
    three = partition_scene(scene, faces, keyframe_budget=1, face_budget=1, margin_m=1.0, count=3)
    assert len(three.blocks) == 3  # a count instead of the budgets
    by_faces = partition_scene(scene, faces, keyframe_budget=100, face_budget=300, margin_m=1.0)
    assert len(by_faces.blocks) > 1 and all(int(b.in_core(xy).sum()) <= 300 for b in by_faces.blocks)


def test_bad_budgets_are_refused_naming_them(tmp_path):
    scene = _corridor_scene(tmp_path)
    with pytest.raises(Exception, match="budgets >= 1"):
        partition_scene(scene, np.zeros((1, 3)), keyframe_budget=0, face_budget=1, margin_m=1.0)
    with pytest.raises(Exception, match="margin"):
        partition_scene(scene, np.zeros((1, 3)), keyframe_budget=1, face_budget=1, margin_m=-1.0)


def test_a_block_visits_its_views_as_often_as_the_whole_run():
    config = make_config("ours", "default")  # 3000 iterations, densify every 500
    block = Block(0, np.zeros((2, 2)), 1.0, (), 100, 0)
    scaled = block_config(config, block, 300)
    assert scaled.iterations == 1000 and scaled.densify_every == 167 and scaled.eval_every == 83
    assert scaled.densify_until == config.densify_until  # fractions of the iterations stay
    assert block_config(config, Block(0, np.zeros((2, 2)), 1.0, (), 3, 0), 300).iterations == 500
    assert block_config(config.model_copy(update={"iterations": 200}), block, 300).iterations == 200


def test_a_block_scene_lists_its_keyframes_and_crops_the_warm_start(scene_dir, tmp_path):
    scene = load_scene(scene_dir)
    mesh = trimesh.load(scene.mesh_path, process=False)
    frame = GroundFrame(np.array([[1.0, 0, 0], [0, 1.0, 0]]), np.array([0, 0, 1.0]))
    core = np.array([[-np.inf, -np.inf], [0.0, np.inf]])
    names = tuple(k.name for k in scene.keyframes[:3])
    root = write_block_scene(scene, Block(0, core, 0.5, names, 3, 0), frame, mesh, tmp_path / "b")
    block_scene = load_scene(root)
    assert [k.name for k in block_scene.keyframes] == list(names)
    assert (root / "images").is_symlink() and block_scene.image(block_scene.keyframes[0]).shape == (48, 64, 3)
    cropped = trimesh.load(root / "mesh.ply", process=False)
    assert 0 < len(cropped.faces) < len(mesh.faces)
    assert (cropped.triangles_center[:, 0] < 0.5).all()


def _model_at(x: np.ndarray, background: float | None) -> TriangleModel:
    """Small triangles (10 cm) centred at ground-plane x positions ``x`` ``(N,)``."""
    corners = np.array([[0.0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]]) - [0.05 / 1.5, 0.05 / 1.5, 0]
    triangles = torch.as_tensor(
        corners[None] + np.column_stack([x, 0 * x, 0 * x])[:, None], dtype=torch.float32
    )
    model = TriangleModel.from_triangles(triangles, torch.full((len(x), 3, 3), 0.5), 0.9)
    if background is not None:
        model.background = torch.full((9, 3), background, requires_grad=True)
        model.background_sphere = torch.tensor([background, 0.0, 0.0, 100.0 * (1 + background)])
    return model


def test_merge_keeps_each_blocks_core_and_a_seam_overlap_and_averages_the_sky_and_its_sphere():
    frame = GroundFrame(np.array([[1.0, 0, 0], [0, 1.0, 0]]), np.array([0, 0, 1.0]))
    left = Block(0, np.array([[-np.inf, -np.inf], [0.0, np.inf]]), 1.0, (), 30, 0)
    right = Block(1, np.array([[0.0, -np.inf], [np.inf, np.inf]]), 1.0, (), 10, 0)
    xs = np.array([-0.9, -0.3, -0.02, 0.03, 0.2, 0.8])  # each block trained both sides of the seam
    a, b = _model_at(xs, 1.0), _model_at(xs, 0.0)
    keep_a, keep_b = core_triangles(a, left, frame), core_triangles(b, right, frame)
    # Half the median longest edge (14 cm / 2): the triangles within 7 cm past the seam stay.
    assert keep_a.tolist() == [True, True, True, True, False, False]
    assert keep_b.tolist() == [False, False, True, True, True, True]
    merged = merge_models([a, b], [keep_a, keep_b], [30.0, 10.0])
    assert merged.n_triangles == 8
    assert torch.allclose(merged.background, torch.full((9, 3), 0.75)) and merged.background.requires_grad
    assert torch.allclose(merged.background_sphere, torch.tensor([0.75, 0.0, 0.0, 175.0]))


def _run(args: list, **kwargs) -> subprocess.CompletedProcess:
    env = {**os.environ, "COLUMNS": "400"}
    return subprocess.run([*LTS, *map(str, args)], capture_output=True, text=True, env=env, **kwargs)


def test_blocks_without_ray_installed_is_one_line_naming_the_extra(scene_dir, tmp_path):
    hide_ray = "import sys; sys.modules['ray'] = None; " + LTS[2]
    env = {**os.environ, "COLUMNS": "400"}
    args = ["train", scene_dir, "--out", tmp_path / "run", "--blocks", "auto"]
    done = subprocess.run(
        [sys.executable, "-c", hide_ray, *map(str, args)], capture_output=True, text=True, env=env
    )
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "lidar-ts[blocks]" in lines[0] and "Traceback" not in done.stderr
    assert not (tmp_path / "run").exists()


def test_block_options_without_blocks_are_refused(scene_dir, tmp_path, lts_cli):
    code, _, err = lts_cli(
        "train", scene_dir, "--out", tmp_path / "run", "--block-margin", 1, "--ray-address", "auto"
    )
    assert code == 2 and "only with --blocks" in err and "--block-margin, --ray-address" in err
    assert not (tmp_path / "run").exists()
    code, _, err = lts_cli(
        "reconstruct", tmp_path / "none.mcap", "--out", tmp_path / "r", "--ray-address", "auto"
    )
    assert code == 2 and "only with --blocks" in err


@pytest.mark.slow
def test_blocks_on_ray_merge_into_a_run_that_lts_eval_reads(scene_dir, tmp_path):
    run = tmp_path / "run"
    blocks = ["--blocks", "auto", "--block-keyframes", 4, "--block-margin", 0.1]
    args = [
        "train",
        scene_dir,
        "--out",
        run,
        *blocks,
        "--preset",
        "fast",
        "--iterations",
        60,
        "--no-progress",
        "--json",
    ]
    done = _run(args, timeout=600)
    assert done.returncode == 0, done.stderr + done.stdout
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(summary["blocks"]) >= 2 and summary["n_triangles"] > 0
    assert summary["n_triangles"] == sum(b["triangles_kept"] for b in summary["blocks"])
    assert all(b["peak_rss_mb"] > 0 and b["resumed_at"] is None for b in summary["blocks"])
    partition = json.loads((run / "partition.json").read_text())
    assert len(partition["blocks"]) == len(summary["blocks"])
    blur = summary["camera_blur"]  # the blocks' widths, weighted by their training keyframes
    widths, weights = blur["blocks_px"], [b["train_keyframes"] for b in summary["blocks"]]
    assert len(widths) == len(weights) and min(widths) <= blur["width_px"] <= max(widths)
    for name in ("model.pt", "mesh.ply", "collision.obj", "metrics.jsonl", "run.json"):
        assert (run / name).is_file(), name
    evaluated = _run(["eval", run], timeout=600)
    assert evaluated.returncode == 0, evaluated.stderr
    assert json.loads((run / "eval.json").read_text())["psnr"] > 10
    again = _run(args, timeout=600)  # a finished run is not overwritten
    assert again.returncode == 2 and "--resume" in again.stderr


_KILLABLE = """
import sys
from splat.blocks.block_run import train_in_blocks
from splat.blocks.options import BlockOptions
from splat.config import make_config
config = make_config(
    "ours", "fast", iterations=400, checkpoint_every=20, eval_every=50, init_max_triangles=500
)
options = BlockOptions(keyframe_budget=4, margin_m=0.1, cpus=2)
result = train_in_blocks(sys.argv[1], sys.argv[2], config, options, progress=False, log=lambda *_: None)
print([b["resumed_at"] for b in result.blocks])
"""


@pytest.mark.slow
def test_a_worker_killed_mid_training_is_retried_from_its_checkpoint(scene_dir, tmp_path):
    run = tmp_path / "run"
    process = subprocess.Popen([sys.executable, "-c", _KILLABLE, str(scene_dir), str(run)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    checkpoint, pid_file = run / "blocks/00/run/checkpoints/last.pt", run / "blocks/00/run/worker.pid"
    deadline = time.monotonic() + 300
    while not (checkpoint.is_file() and pid_file.is_file()) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert checkpoint.is_file(), process.communicate()[1]
    os.kill(int(pid_file.read_text()), signal.SIGKILL)
    out, err = process.communicate(timeout=600)
    assert process.returncode == 0, err
    resumed = json.loads(out.strip().splitlines()[-1].replace("None", "null"))
    assert resumed[0] is not None and resumed[0] > 0  # block 0 started again from its checkpoint
    assert (run / "model.pt").is_file()


def test_seam_distance_and_the_partition_file_round_trip(tmp_path):
    frame = GroundFrame(np.array([[1.0, 0, 0], [0, 1.0, 0]]), np.array([0, 0, 1.0]))
    blocks = [
        Block(0, np.array([[-np.inf, -np.inf], [0.0, np.inf]]), 1.0, ("a",), 3, 10),
        Block(1, np.array([[0.0, -np.inf], [5.0, np.inf]]), 1.0, ("b",), 4, 20),
    ]
    partition = Partition(frame, blocks)
    xy = np.array([[-3.0, 7.0], [0.4, -2.0], [4.0, 0.0], [9.0, 0.0]])
    assert partition.seam_distance(xy).tolist() == [3.0, 0.4, 1.0, np.inf]  # beyond every core: none
    path = tmp_path / "partition.json"
    path.write_text(json.dumps(partition.to_json()))
    again = read_partition(path)
    assert np.array_equal(again.frame.axes, frame.axes)
    assert [b.core.tolist() for b in again.blocks] == [b.core.tolist() for b in blocks]
    path.write_text('{"axes": [[1, 0, 0]], "up": [0, 0, 1], "blocks": []}')
    with pytest.raises(InputError, match=r"partition\.json"):
        read_partition(path)
