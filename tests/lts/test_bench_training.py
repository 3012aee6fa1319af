"""Training benchmarks: the Pareto front and the plots (the benches themselves run in lts bench)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from lts.bench.training import _plot_bars, _plot_noise, _plot_pareto, pareto_front, seed_spread


def _row(seconds: float, chamfer: float, **extra) -> dict:
    return {"train_seconds": seconds, "chamfer_m": chamfer, "iterations": 100, "init_max_triangles": 4000,
            "method": "ours", "psnr": 30.0, "fscore": 0.9, "init_noise_m": 0.0, "coarse_until": 0.25,
            **extra}  # fmt: skip


def test_pareto_front_keeps_the_runs_nothing_beats_on_both_time_and_error():
    rows = [_row(10, 0.05), _row(5, 0.08), _row(20, 0.05), _row(30, 0.03), _row(6, 0.09)]
    assert pareto_front(rows) == [1, 0, 3]  # 20 s / 0.05 is beaten by 10 s / 0.05; 6 s / 0.09 by 5 s / 0.08


def test_seed_spread_gives_each_metric_its_mean_lowest_and_highest():
    runs = [_row(10, 0.04, psnr=30.0), _row(14, 0.05, psnr=31.0), _row(12, 0.03, psnr=30.5)]
    spread = seed_spread(runs)
    assert spread["psnr"] == {"mean": 30.5, "min": 30.0, "max": 31.0}
    assert spread["train_seconds"] == {"mean": 12.0, "min": 10.0, "max": 14.0}
    assert spread["chamfer_m"]["min"] == 0.03 and spread["chamfer_m"]["max"] == 0.05
    assert "ssim" not in spread  # no run reports it


def test_plots_are_written(tmp_path):
    rows = [_row(1, 0.1), _row(2, 0.05, method="tsplus", init_noise_m=0.1)]
    _plot_pareto(rows, pareto_front(rows), tmp_path / "sub" / "pareto.png")
    _plot_bars({r["method"]: seed_spread([r]) for r in rows}, tmp_path / "sub" / "bars.png")
    _plot_noise(rows, tmp_path / "sub" / "noise.png")
    for name in ("pareto.png", "bars.png", "noise.png"):
        assert (tmp_path / "sub" / name).stat().st_size > 1000


def test_an_unknown_virtual_rig_preset_is_refused_before_anything_runs(tmp_path: Path) -> None:
    lts = Path(sys.executable).parent / "lts"
    for command in ("ablation", "noise", "train"):
        out = tmp_path / command
        result = subprocess.run(
            [lts, "bench", command, "--sim", "offce", "--out", out],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert result.returncode == 2, result.stderr
        assert "unknown preset 'offce'" in result.stderr and "office" in result.stderr
        assert "Traceback" not in result.stderr and not out.exists()
