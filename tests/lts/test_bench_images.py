"""``lts bench images``: the ceiling of image fidelity a virtual-rig preset's test images allow."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from lts.bench.images import BLUR_SIGMAS_PX, bench_images, keyframe_split
from rig.sim.config import SimConfig
from rig.sim.simulate import prepare

BIN = Path(sys.executable).parent


def test_the_split_holds_out_every_nth_keyframe() -> None:
    run = prepare(SimConfig(preset="room").quick(duration_s=4.0))
    train, test = keyframe_split(run, 0.5, 4)
    np.testing.assert_array_equal([k.t_ns for k in test], [1_750_000_000, 3_750_000_000])
    assert len(train) == 6 and not {k.t_ns for k in train} & {k.t_ns for k in test}
    np.testing.assert_allclose(test[0].T_world_cam, run.motion.poses(np.array([1.75]))[0])


def test_the_quick_room_has_a_ceiling_below_perfect_and_each_part_above_it() -> None:
    result = bench_images(SimConfig(preset="room").quick(), 0.2, 4, log=lambda line: None)
    assert result["test_views"] == 3 and result["train_views"] == 12
    by_blur = result["undistortion_psnr_by_blur_px"]
    assert set(by_blur) == {str(sigma) for sigma in BLUR_SIGMAS_PX}
    # The distorted camera's images resampled bilinearly are smoother than a sharp render: some
    # blur of the render fits them better than none.
    assert result["undistortion_psnr"] == max(by_blur.values()) > by_blur["0.0"]
    # Views from other distances give some points other texture levels; both sources together
    # stand below either alone.
    assert 25 < result["ceiling_psnr"] < min(result["static_colour_psnr"], result["undistortion_psnr"])
    assert result["static_colour_psnr"] < 60


def test_too_few_keyframes_is_a_one_line_usage_error() -> None:
    done = subprocess.run(
        [BIN / "lts", "bench", "images", "--sim", "room", "--quick", "--keyframe-interval", "2"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    assert "need both" in done.stderr and "--keyframe-interval" in done.stderr


def test_the_json_is_one_object_on_stdout() -> None:
    done = subprocess.run(
        [BIN / "lts", "bench", "images", "--sim", "room", "--quick", "--keyframe-interval", "0.2",
         "--test-every", "4", "--json"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["preset"] == "room" and result["image_size"] == [160, 120]
