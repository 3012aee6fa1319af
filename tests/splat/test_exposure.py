"""Per-view colour maps (exposure, white balance): the map, its training, its checkpoint, and the
evaluation's colour-aligned PSNR."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
import torch
from training_scene import write_training_scene

from eval.photometric import color_aligned, psnr
from rig.errors import InputError
from splat.config import make_config
from splat.exposure import IDENTITY, INTERPOLATED, MEASURED, ViewExposures, held_out_maps
from splat.run_dir import read_color_maps
from splat.trainer import Trainer, train

#: The gains the training images are recorded with (the test view, the last, keeps gain 1).
GAINS = (0.75, 1.2, 0.9, 1.1, 0.8)


def _config(**overrides):
    values = dict(
        iterations=300, densify_every=100, densify_until=0.5, eval_every=100, checkpoint_every=100,
        init_max_triangles=500, ground_fill=False, drop_redundant_keyframes=False, coarse_min_side_px=1,
    )  # fmt: skip
    values.update(overrides)
    return make_config("ours", "default", **values)


@pytest.fixture(scope="module")
def exposed_scene(tmp_path_factory):
    """The training corner with each training image recorded at one of :data:`GAINS`."""
    root = write_training_scene(tmp_path_factory.mktemp("exposed"))
    for i, gain in enumerate(GAINS):
        path = root / "images" / f"{i:06d}.png"
        image = cv2.imread(str(path)).astype(np.float64)
        cv2.imwrite(str(path), np.clip(image * gain + 0.5, 0, 255).astype(np.uint8))
    return root


def test_the_identity_map_changes_nothing_and_an_offset_is_an_affine_map():
    rgb = torch.rand(4, 5, 3)
    exposures = ViewExposures.identity(2)
    assert torch.equal(exposures.apply(rgb, 1), rgb)
    assert float(exposures.prior(0).detach()) == 0.0
    offsets = torch.zeros(2, 3, 3)
    offsets[1] = torch.tensor([[0.2, 0.0, 0.0], [0.0, -0.1, 0.05], [0.0, 0.0, 0.0]])
    mapped = ViewExposures(offsets).apply(rgb, 1)
    assert torch.allclose(mapped, rgb @ (torch.eye(3) + offsets[1]).T, atol=1e-6)
    assert torch.equal(ViewExposures(offsets).apply(rgb, 0), rgb)
    assert torch.equal(
        ViewExposures(offsets).apply(torch.zeros(2, 2, 3), 1), torch.zeros(2, 2, 3)
    )  # holes stay black
    with pytest.raises(ValueError, match=r"\(V, 3, 3\)"):
        ViewExposures(torch.zeros(2, 3, 4))


def test_training_learns_each_views_gain_and_keeps_the_common_appearance(exposed_scene, tmp_path):
    quiet = lambda *_: None  # noqa: E731
    with_maps = Trainer(exposed_scene, tmp_path / "maps", _config(), quiet)  # auto: the gains differ
    with_maps.prepare(resume=False)
    learnt = with_maps.run(progress=False)
    without = train(exposed_scene, tmp_path / "plain", _config(exposure="off"), progress=False, log=quiet)
    gains = with_maps.exposures.gains()
    relative, truth = (gains / gains.mean()).numpy(), np.array(GAINS) / np.mean(GAINS)
    assert np.abs(relative - truth).max() < 0.06, relative
    assert learnt.exposure["gain_min"] < 0.85 and learnt.exposure["gain_max"] > 1.1
    assert without.exposure == {}
    assert read_color_maps(tmp_path / "plain") == ({}, None)
    maps, rule = read_color_maps(tmp_path / "maps")
    assert sorted(maps) == [f"{i:06d}" for i in range(6)]
    # The gains jump from image to image, so the test view's (recorded at gain 1) is measured
    # against its nearest training image's, not interpolated.
    assert rule == MEASURED.format(1, 1)
    test_gain = np.mean(np.diag(maps["000005"]))
    assert test_gain / float(gains.mean()) == pytest.approx(1 / np.mean(GAINS), abs=0.06)
    # With a map per view the triangles fit every differently exposed image, not their average.
    last_l1 = [json.loads((tmp_path / run / "metrics.jsonl").read_text().splitlines()[-1])["loss"]["l1"]
               for run in ("maps", "plain")]  # fmt: skip
    assert last_l1[0] < 0.8 * last_l1[1]


def test_resuming_a_run_without_colour_maps_names_the_file(exposed_scene, tmp_path):
    quiet = lambda *_: None  # noqa: E731
    run = tmp_path / "run"
    trainer = Trainer(exposed_scene, run, _config(iterations=20, exposure="off"), quiet)
    trainer.prepare(resume=False)
    trainer.save_checkpoint()
    state = torch.load(run / "checkpoints" / "last.pt", weights_only=False)
    assert state["exposure"] is None
    (run / "config.yaml").write_text(_config(iterations=20, exposure="on").to_yaml())  # as if it had been on
    with pytest.raises(InputError, match="colour maps of 5 training views") as error:
        Trainer(exposed_scene, run, _config(iterations=20, exposure="on"), quiet).prepare(resume=True)
    assert "last.pt" in str(error.value)


def test_colour_alignment_undoes_a_colour_matrix_and_leaves_a_match_alone():
    rng = np.random.default_rng(0)
    target = rng.uniform(0.1, 0.8, (30, 40, 3)).astype(np.float32)
    A = np.array([[1.1, 0.05, 0.0], [0.0, 0.9, 0.02], [0.03, 0.0, 1.05]])
    rendered = (target @ np.linalg.inv(A).T).astype(np.float32)
    assert psnr(rendered, target) < 30
    assert psnr(color_aligned(rendered, target), target) > 60
    assert np.allclose(color_aligned(target, target), target, atol=1e-5)
    # Holes (black) stay black and leave the fit alone.
    holes = rendered.copy()
    holes[:10] = 0.0
    aligned = color_aligned(holes, target)
    assert np.all(aligned[:10] == 0) and psnr(aligned[10:], target[10:]) > 60


def test_held_out_views_get_the_interpolated_map_when_it_predicts_the_training_views():
    times = np.arange(6, dtype=float)
    drift = torch.zeros(6, 3, 3)
    drift[:, 0, 0] = torch.linspace(-0.1, 0.1, 6)  # a smooth drift of the red gain
    maps, rule = held_out_maps(ViewExposures(drift), times, np.array([2.5, -1.0, 9.0]))
    assert rule == INTERPOLATED
    assert maps[0, 0, 0] == pytest.approx(1.0 + (drift[2, 0, 0] + drift[3, 0, 0]) / 2)
    assert maps[1, 0, 0] == pytest.approx(0.9) and maps[2, 0, 0] == pytest.approx(1.1)  # the ends held
    # Gains that jump from image to image: the neighbours do not predict them, the identity is kept.
    jumps = torch.zeros(6, 3, 3)
    jumps[:, 1, 1] = torch.tensor([0.2, -0.2, 0.2, -0.2, 0.2, -0.2])
    maps, rule = held_out_maps(ViewExposures(jumps), times, np.array([2.5]))
    assert rule == IDENTITY and torch.equal(maps[0], torch.eye(3))
    # With each held-out image's gain measured against its nearest training image: that image's
    # map scaled by it; the identity where it could not be measured.
    measured = (np.array([2, 3]), np.array([np.log(1.5), np.nan]))
    maps, rule = held_out_maps(ViewExposures(jumps), times, np.array([2.4, 2.6]), measured)
    assert rule == MEASURED.format(1, 2)
    assert torch.allclose(maps[0], 1.5 * (torch.eye(3) + jumps[2])) and torch.equal(maps[1], torch.eye(3))


def test_a_malformed_exposure_file_names_itself(tmp_path):
    (tmp_path / "exposure.json").write_text('{"maps": {"kf_0000": [1, 2]}}')
    with pytest.raises(InputError, match=r"exposure\.json"):
        read_color_maps(tmp_path)


def test_the_gains_between_neighbouring_images_are_measured_on_shared_lidar_points(exposed_scene, tmp_path):
    from slam_bridge.scene import load_scene
    from splat.exposure import GAIN_SPREAD_LIMIT, gain_spread, neighbour_gains

    def ratios(root):
        scene = load_scene(root)
        keyframes = scene.split("train")
        return neighbour_gains(
            [scene.image(k) / 255.0 for k in keyframes],
            [scene.lidar(k).points.astype(np.float64) for k in keyframes],
            np.stack([k.T_world_cam for k in keyframes]),
            scene.camera,
        )

    measured = ratios(exposed_scene)
    assert np.allclose(measured, np.diff(np.log(GAINS)), atol=0.03), measured
    plain_root = write_training_scene(tmp_path / "plain")
    plain = ratios(plain_root)
    assert gain_spread(plain) < GAIN_SPREAD_LIMIT < gain_spread(measured)
    # Something in front of the wall in one image only (an occluder, a passer-by): the points
    # behind it scatter instead of moving by one gain, and that pair says nothing.
    image_path = plain_root / "images" / "000002.png"
    image = cv2.imread(str(image_path))
    image[:, : image.shape[1] * 2 // 3] = (20, 200, 90)
    cv2.imwrite(str(image_path), image)
    occluded = ratios(plain_root)
    assert occluded[1] == 0.0 and occluded[2] == 0.0 and gain_spread(occluded) < GAIN_SPREAD_LIMIT


def test_auto_learns_no_maps_where_the_images_share_one_exposure(tmp_path):
    plain = write_training_scene(tmp_path / "plain")
    result = train(plain, tmp_path / "run", _config(iterations=20), progress=False, log=lambda *_: None)
    assert result.exposure == {} and not (tmp_path / "run" / "exposure.json").exists()
    assert any("no colour maps learnt" in line for line in result.skips)
