"""RUN_DIR/report.html: every section, embedded images only, and a headless-Chromium screenshot."""

from __future__ import annotations

import base64
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "splat"))
from training_scene import corner_mesh, write_training_scene

from eval.report import SECTIONS, write_report
from eval.run_eval import evaluate_run
from rig.trajectory import Trajectory
from rig.trajectory_io import write_tum
from slam_bridge.scene import load_scene

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
DATA_PNG = re.compile(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"')


@pytest.fixture(scope="module")
def run_and_truth(tmp_path_factory) -> tuple[Path, Path]:
    """A 40-iteration run on the corner scene and its ground-truth folder (identity alignment)."""
    from splat.config import make_config
    from splat.trainer import train

    root = tmp_path_factory.mktemp("report")
    scene_dir = write_training_scene(root / "scene")
    config = make_config(
        "ours", "default", iterations=40, densify_every=20, eval_every=20, checkpoint_every=20,
        init_max_triangles=500, ground_fill=False,
    )  # fmt: skip
    train(scene_dir, root / "run", config, progress=False, log=lambda *_: None)
    gt_dir = root / "ground_truth"
    gt_dir.mkdir()
    corner_mesh(24).export(gt_dir / "mesh.ply")
    keyframes = load_scene(scene_dir).keyframes
    trajectory = Trajectory.from_poses(
        np.array([k.t_ns for k in keyframes]), np.stack([k.T_world_cam for k in keyframes])
    )
    write_tum(trajectory, gt_dir / "trajectory.tum")
    return root / "run", gt_dir


@pytest.fixture(scope="module")
def report(run_and_truth) -> Path:
    run_dir, gt_dir = run_and_truth
    return write_report(evaluate_run(run_dir, gt_dir, samples=30_000))


def test_report_has_every_section_with_embedded_images(report: Path, run_and_truth) -> None:
    assert report == run_and_truth[0] / "report.html"
    page = report.read_text(encoding="utf-8")
    for sid, heading in SECTIONS.items():
        assert f'<section id="{sid}"><h2>{heading}</h2>' in page
    for text in ("fscore", "hole_fraction_leaned", "fall-through", "config.yaml", "Skipped work"):
        assert text in page
    images = DATA_PNG.findall(page)
    # colour bar + 3 per test view, 4 leaned views, point cloud, curves, physics
    assert len(images) >= 1 + 3 + 4 + 3
    for data in images:
        assert base64.b64decode(data).startswith(b"\x89PNG\r\n\x1a\n")
    assert "Not computed" not in page  # everything had what it needs


def test_report_has_no_external_resources(report: Path) -> None:
    page = report.read_text(encoding="utf-8")
    assert "http://" not in page and "https://" not in page and "url(" not in page
    for attribute in re.findall(r'(?:src|href)="([^"]*)"', page):
        assert attribute.startswith(("data:image/png;base64,", "#")), attribute
    assert "<link" not in page and "<script" not in page and "@import" not in page


def test_report_without_ground_truth_says_what_is_missing(run_and_truth, tmp_path) -> None:
    path = write_report(evaluate_run(run_and_truth[0], None, physics=False), tmp_path / "report.html")
    page = path.read_text(encoding="utf-8")
    for sid, heading in SECTIONS.items():
        assert f'<section id="{sid}"><h2>{heading}</h2>' in page
    assert page.count("Not computed: needs --gt") == 2  # geometry and physics
    assert "the scene&#x27;s SLAM mesh" in page  # leaned holes measured against it


def _chromium() -> str | None:
    return next((p for p in map(shutil.which, CHROMIUM_NAMES) if p), None)


def test_report_screenshot_in_headless_chromium(report: Path, tmp_path) -> None:
    """The page renders in a browser: a full-width screenshot that is neither blank nor uniform.

    By hand: chromium --headless --no-sandbox --hide-scrollbars --window-size=1280,6000
    --screenshot=shot.png file://$PWD/RUN_DIR/report.html
    """
    chromium = _chromium()
    if chromium is None:
        pytest.skip(f"no headless browser found ({', '.join(CHROMIUM_NAMES)}; apt-get install chromium)")
    shot = tmp_path / "report.png"
    result = subprocess.run(
        [
            chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
            f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1280,4000",
            f"--screenshot={shot}", report.resolve().as_uri(),
        ],
        capture_output=True, text=True, timeout=180,
    )  # fmt: skip
    assert result.returncode == 0 and shot.is_file(), result.stderr[-2000:]
    image = cv2.imread(str(shot))
    assert image is not None and image.shape[:2] == (4000, 1280)
    assert shot.stat().st_size > 100_000  # photos and plots, not an empty page
    colours = np.unique(image[::4, ::4].reshape(-1, 3), axis=0)
    assert len(colours) > 2000
    header = image[:60, :, :].mean(axis=(0, 1))
    assert header.max() < 80  # the dark title bar is drawn: the stylesheet applied
