"""Keyframe matching with COLMAP gives the same matches on every run."""

import subprocess
import sys
from pathlib import Path

import numpy as np

from slam_bridge.colmap_matches import match_keyframes, read_correspondences
from slam_bridge.scene import load_scene


def test_matching_the_same_keyframes_twice_gives_the_same_matches(
    quick_room: Path, gt_slam_dir: Path, tmp_path: Path
) -> None:
    lts = Path(sys.executable).parent / "lts"
    calib = quick_room / "ground_truth" / "calib.yaml"
    scene_dir = tmp_path / "scene"
    prepare = [lts, "prepare", quick_room / "session.mcap", "--calib", calib, "--slam", gt_slam_dir]
    subprocess.run(
        [*prepare, "--out", scene_dir],
        check=True,
        capture_output=True,
        timeout=300,
    )
    scene = load_scene(scene_dir)
    names = [f"{k.name}.png" for k in scene.keyframes]
    databases = [
        match_keyframes(scene_dir / "images", tmp_path / f"run{i}", scene.camera, names) for i in range(3)
    ]
    runs = [read_correspondences(database, names) for database in databases]
    assert len(runs[0]) > 100
    for other in runs[1:]:
        for field in ("observer", "source", "uv_observer", "uv_source", "match"):
            np.testing.assert_array_equal(getattr(other, field), getattr(runs[0], field))
