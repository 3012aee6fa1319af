"""The training profile: the same training as the trainer's, and the bench's JSON contract."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from training_scene import write_training_scene

from splat.config import make_config
from splat.model import load_model
from splat.step_profile import SECTIONS, ProfiledTrainer
from splat.trainer import train

BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    return write_training_scene(tmp_path_factory.mktemp("scene"))


def _config():
    return make_config(
        "ours", "default", iterations=40, densify_every=20, densify_until=0.5, eval_every=20,
        init_max_triangles=500, ground_fill=False, drop_redundant_keyframes=False, coarse_min_side_px=1,
    )  # fmt: skip


def test_a_profiled_training_trains_as_the_plain_one(scene_dir, tmp_path):
    plain = train(scene_dir, tmp_path / "plain", _config(), progress=False, log=lambda *_: None)
    trainer = ProfiledTrainer(scene_dir, tmp_path / "profiled", _config(), log=lambda *_: None)
    trainer.prepare(resume=False)
    profiled = trainer.run(progress=False)

    # The loss and the rasteriser's backward passes run apart: the gradients sum in another order.
    assert profiled.n_triangles == plain.n_triangles
    a, b = load_model(tmp_path / "plain" / "model.pt"), load_model(tmp_path / "profiled" / "model.pt")
    for name in a.params:
        torch.testing.assert_close(a.params[name], b.params[name], rtol=0, atol=1e-4)
    profile = trainer.profile()
    assert profile["iterations"] == 40
    assert list(profile["ms_per_iteration"]) == list(SECTIONS)
    assert all(ms >= 0 for ms in profile["ms_per_iteration"].values())
    assert profile["ms_per_iteration"]["render forward"] > 0
    assert profile["ms_total"] == pytest.approx(sum(profile["ms_per_iteration"].values()), abs=0.01)


def test_lts_bench_train_profile_prints_the_table_and_the_json(scene_dir, tmp_path):
    cmd = [BIN / "lts", "bench", "train", "--profile", "--scene", scene_dir, "-n", "20"]
    result = subprocess.run([*cmd, "--out", tmp_path, "--json"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["iterations"] == 20 and set(data["ms_per_iteration"]) == set(SECTIONS)
    assert data == json.loads((tmp_path / "train_profile.json").read_text())
    assert "render forward" in result.stderr and "total" in result.stderr
