"""``lts view``: the viewer of a tiny training run, screenshotted by a headless Chromium, and its
one-line errors."""

from __future__ import annotations

import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from console_script import run_console_script
from headless_browser import CHROMIUM, screenshot_when
from test_run_eval import make_tiny_run

from eval.run_inputs import resolve_run_dir
from eval.viewer_data import load_truth
from eval.viewer_layers import error_colors, nearest_keyframe
from lts.cli import main as lts_main
from slam_bridge.scene import load_scene
from splat.run_dir import scene_of

LTS = Path(sys.executable).parent / "lts"


@pytest.fixture(scope="module")
def reconstruct_dir(tmp_path_factory) -> tuple[Path, Path]:
    """An ``lts reconstruct``-style folder (``OUT/train`` is a tiny run) and its ground truth."""
    root = tmp_path_factory.mktemp("viewer")
    run_dir, gt_dir = make_tiny_run(root)
    out = root / "out"
    out.mkdir()
    run_dir.rename(out / "train")
    return out, gt_dir


def _drawn_share(image: np.ndarray) -> float:
    """The share of the 3D canvas (left of the control panel, below Chromium's software-WebGL
    notice) that is not the empty canvas's white."""
    canvas = image[200:, :900].reshape(-1, 3)
    return float(np.any(canvas < 235, axis=1).mean())


def _canvas_is_drawn(image: np.ndarray) -> bool:
    canvas = image[200:, :900].reshape(-1, 3)
    return _drawn_share(image) > 0.2 and len(np.unique(canvas, axis=0)) > 200


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _wait_for_port(port: int, server: subprocess.Popen, timeout_s: float = 120.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if server.poll() is not None:
            pytest.fail(f"lts view exited with {server.returncode}")
        try:  # an HTTP request: a bare connection would make the server log a failed handshake
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=2.0):
                return
        except OSError:
            time.sleep(0.5)
    pytest.fail(f"lts view did not listen on port {port} within {timeout_s:g} s")


def test_run_folder_and_reconstruct_folder_resolve_to_the_training_run(reconstruct_dir, tmp_path) -> None:
    out, _ = reconstruct_dir
    assert resolve_run_dir(out) == out / "train"
    assert resolve_run_dir(out / "train") == out / "train"
    with pytest.raises(ValueError, match="not a training run folder"):
        resolve_run_dir(tmp_path)


def test_ground_truth_folder_its_mesh_and_a_plain_mesh_file(reconstruct_dir, tmp_path) -> None:
    out, gt_dir = reconstruct_dir
    scene = load_scene(scene_of(out / "train"))
    for gt in (gt_dir, gt_dir.parent, gt_dir / "mesh.ply"):
        mesh, aligned, up = load_truth(scene, gt)
        assert aligned and len(mesh.faces) > 0
        np.testing.assert_allclose(up, [0, 0, 1], atol=1e-6)  # the truth's poses are the scene's
    plain = tmp_path / "other.ply"
    shutil.copy(gt_dir / "mesh.ply", plain)
    mesh, aligned, up = load_truth(scene, plain)
    assert not aligned and up is None and len(mesh.faces) > 0


def test_error_colours_span_the_scale_and_nearest_keyframe_faces_the_view() -> None:
    colors = error_colors(np.array([0.0, 0.1, 0.2, 5.0]), threshold_m=0.1)
    assert colors.shape == (4, 3) and colors.dtype == np.uint8
    assert not np.array_equal(colors[0], colors[2]) and np.array_equal(colors[2], colors[3])
    ahead, behind = np.eye(4), np.diag([-1.0, 1.0, -1.0, 1.0])  # behind: turned half round
    ahead[:3, 3], behind[:3, 3] = [0, 0, 1.0], [0, 0, 0.1]
    assert nearest_keyframe(np.stack([ahead, behind]), np.eye(4)) == 0


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on PATH to screenshot the viewer with")
def test_lts_view_serves_a_page_whose_3d_canvas_shows_the_run(reconstruct_dir, tmp_path) -> None:
    out, gt_dir = reconstruct_dir
    port = _free_port()
    log = tmp_path / "view.log"  # a file, not a pipe nobody reads while the page loads
    with log.open("w") as log_file:
        command = [LTS, "view", out, "--gt", gt_dir, "--port", str(port)]
        server = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=log_file)
    try:
        _wait_for_port(port, server)
        image = screenshot_when(f"http://127.0.0.1:{port}", _canvas_is_drawn)
        assert image.shape[:2] == (800, 1280)
        assert _canvas_is_drawn(image), f"only {_drawn_share(image):.1%} of the canvas is drawn on"
        server.send_signal(signal.SIGTERM)  # as Ctrl-C; SIGINT is ignored where pytest runs in the background
        server.wait(timeout=60)
        stderr = log.read_text()
        assert server.returncode == 0, stderr
        assert f"http://127.0.0.1:{port}" in stderr and str(out / "train") in stderr
        assert "Traceback" not in stderr
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()


@pytest.mark.parametrize("case", ["missing run", "not a run", "missing gt"])
def test_bad_input_is_one_line_naming_the_path(case, reconstruct_dir, tmp_path, monkeypatch, capsys) -> None:
    out, _ = reconstruct_dir
    run, gt = {
        "missing run": (tmp_path / "nowhere", None),
        "not a run": (tmp_path, None),
        "missing gt": (out, tmp_path / "no_gt.ply"),
    }[case]
    args = ["view", run, *(["--gt", gt] if gt else [])]
    code, stdout, stderr = run_console_script(lts_main, args, monkeypatch, capsys)
    assert code == 2 and stdout == ""
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), stderr
    assert str(gt or run) in lines[0]
