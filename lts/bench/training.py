"""Benchmarks of training: run time against error, the ablation table, the warm-start noise curve.

Each trains on one virtual-rig scene (simulated, mapped and prepared here through the pipeline's
stages, or given), scores every run against the ground truth with the culled-mesh
protocol (:mod:`eval.ground_truth`), writes a JSON table and a PNG plot, and returns the table.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from eval.ground_truth import compare_culled, culled_samples, load_ground_truth
from lts.bench.figures import pyplot, save_figure
from rig.errors import InputError
from rig.mesh_io import load_mesh
from slam_bridge.scene import load_scene

if TYPE_CHECKING:
    from splat.config import TrainConfig

#: What each finished run reports in the log.
SUMMARY_KEYS = ("train_seconds", "psnr", "fscore", "chamfer_m")


@dataclass(frozen=True)
class BenchScene:
    """A prepared scene and the virtual-rig ground truth of its session."""

    scene_dir: Path
    gt_dir: Path


def virtual_scene(
    out: Path, preset: str = "room", quick: bool = True, seed: int = 0, log: Callable = print
) -> BenchScene:
    """Simulate a session of the virtual rig's ``preset``, map it with the fallback mapper and
    prepare its scene (with SfM points for the TS+ baseline) under ``out``, each stage reused when
    up to date. ``quick``: the simulator's 3 s, 160×120 run."""
    from lts.demo import simulate_preset
    from lts.pipeline import build_scene, map_session, prepare_key
    from lts.stages import StageRunner
    from slam_bridge.prepare_config import PrepareConfig

    sim, slam, scene = out / "sim", out / "slam", out / "scene"
    session, calib = sim / "session.mcap", sim / "ground_truth" / "calib.yaml"
    # The quick run lasts 3 s: one keyframe per 0.5 s would leave none to test on.
    keyframes = PrepareConfig(keyframe_interval_s=0.2 if quick else 0.5, sparse_points=True)
    stages = StageRunner(out, ("simulate", "slam", "prepare"), log)
    key = ["lts sim", str(sim), "--preset", preset, "--seed", str(seed), *(["--quick"] if quick else [])]
    stages.run("simulate", key, [], session, lambda: simulate_preset(sim, preset, quick, seed))
    stages.run("slam", ["lts slam run", str(session)], [session], slam / "mesh.ply",
               lambda: map_session(session, slam, log))  # fmt: skip
    key = ["lts prepare", str(session), *prepare_key(keyframes)]
    stages.run("prepare", key, [session, slam], scene / "scene.json",
               lambda: build_scene(session, calib, slam, scene, keyframes, log))  # fmt: skip
    return BenchScene(scene, sim / "ground_truth")


def train_and_score(bench: BenchScene, config, run_dir: Path, threshold_m: float = 0.1) -> dict[str, Any]:
    """Train ``config`` into ``run_dir`` and score it: wall time, test PSNR/SSIM, geometry."""
    from splat.trainer import train

    started = time.perf_counter()
    result = train(bench.scene_dir, run_dir, config, progress=False, log=lambda *_: None)
    wall = time.perf_counter() - started
    scene = load_scene(bench.scene_dir)
    truth = load_ground_truth(scene, bench.gt_dir)
    mesh = load_mesh(run_dir / "mesh.ply")
    geometry = compare_culled(culled_samples(mesh, scene, truth), threshold_m)
    return {
        "method": config.method,
        "preset": config.preset,
        "seed": config.seed,
        "iterations": result.iterations,
        "init_max_triangles": config.init_max_triangles,
        "max_triangles": config.max_triangles,
        "init_noise_m": config.init_noise_m,
        "coarse_until": config.coarse_until,
        "train_seconds": result.train_seconds,
        "wall_seconds": round(wall, 2),
        "n_triangles": result.n_triangles,
        "psnr": result.test.get("test_psnr"),
        "ssim": result.test.get("test_ssim"),
        "depth_l1_m": result.test.get("test_depth_l1_m"),
        **geometry,
        "threshold_m": threshold_m,
    }


def _run_name(config) -> str:
    return f"it{config.iterations}_tri{config.init_max_triangles}_half{config.coarse_until:g}"


def pareto_front(rows: list[dict], cost: str = "train_seconds", error: str = "chamfer_m") -> list[int]:
    """Indices of the rows no other row beats on both ``cost`` and ``error`` (lower is better),
    in increasing cost."""
    order = sorted(range(len(rows)), key=lambda i: (rows[i][cost], rows[i][error]))
    front, best = [], np.inf
    for i in order:
        if rows[i][error] < best:
            front.append(i)
            best = rows[i][error]
    return front


def _run_all(
    bench: BenchScene, configs: Iterable, out: Path, name: Callable, log: Callable
) -> list[dict[str, Any]]:
    rows = []
    for config in configs:
        run_dir = out / "runs" / name(config)
        if run_dir.exists():
            shutil.rmtree(run_dir)
        log(f"training {name(config)} ...")
        rows.append(train_and_score(bench, config, run_dir))
        log(
            "  "
            + ", ".join(f"{key} {rows[-1][key]:.3f}" for key in SUMMARY_KEYS if rows[-1][key] is not None)
        )
    return rows


def _write(out: Path, name: str, result: dict) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(result, indent=1))


def sweep_configs(
    iterations: list[int], init_triangles: list[int], half_resolution: list[float]
) -> list[TrainConfig]:
    """The trainings of :func:`bench_train`: iteration budgets × warm-start triangle budgets × the
    fraction of iterations trained at half resolution (``coarse_until``: 0 full resolution
    throughout, 1 half throughout) of ``ours``. Raises InputError on a budget a training refuses,
    before any scene is simulated."""
    from splat.config import make_config

    try:
        return [
            make_config(
                "ours",
                "default",
                iterations=n,
                init_max_triangles=t,
                max_triangles=max(3 * t, 1000),
                eval_every=max(n // 4, 1),
                densify_every=max(n // 6, 1),
                coarse_until=h,
            )
            for n in iterations
            for t in init_triangles
            for h in half_resolution
        ]
    except InputError as exc:
        flags = {"iterations": "--iterations", "init_max_triangles": "--triangles"}
        raise InputError(exc.reason, field=flags.get(exc.field or "", exc.field)) from None


def bench_train(
    bench: BenchScene, out: Path, configs: list[TrainConfig], log: Callable = print
) -> dict[str, Any]:
    """Train each of ``configs`` (:func:`sweep_configs`) on the bench scene; the Pareto front of
    training time against Chamfer error (and a plot ``train_pareto.png``)."""
    rows = _run_all(bench, configs, out, _run_name, log)
    front = pareto_front(rows)
    result = {
        "scene": str(bench.scene_dir),
        "rows": rows,
        "pareto": front,
        "plot": str(out / "train_pareto.png"),
    }
    _plot_pareto(rows, front, out / "train_pareto.png")
    _write(out, "bench_train", result)
    return result


def profile_config(iterations: int) -> TrainConfig:
    """The training :func:`bench_profile` times: ``ours``, default preset, ``iterations`` (raises
    InputError on a budget a training refuses, before any scene is simulated)."""
    from splat.config import make_config

    return make_config("ours", "default", iterations=iterations)


def bench_profile(scene_dir: Path, out: Path, config: TrainConfig, log: Callable = print) -> dict[str, Any]:
    """One training of ``config`` (:func:`profile_config`) on ``scene_dir`` with every step timed
    by section (:class:`splat.step_profile.ProfiledTrainer`); writes ``train_profile.json``."""
    from splat.step_profile import ProfiledTrainer

    iterations = config.iterations
    run_dir = out / "runs" / f"profile_it{iterations}"
    if run_dir.exists():
        shutil.rmtree(run_dir)
    scene = load_scene(scene_dir)
    trainer = ProfiledTrainer(scene, run_dir, config, log=lambda *_: None)
    started = time.perf_counter()
    trainer.prepare(resume=False)
    prepare_s = time.perf_counter() - started
    log(f"profiling {iterations} iterations on {scene_dir} ({scene.camera.width}x{scene.camera.height}) ...")
    result = trainer.run(progress=False)
    result_json = {
        "scene": str(scene_dir),
        "image_size": [scene.camera.width, scene.camera.height],
        "set_up_seconds": round(prepare_s, 2),
        "train_seconds": result.train_seconds,
        "test_psnr": result.test.get("test_psnr"),
        **trainer.profile(),
    }
    _write(out, "train_profile", result_json)
    return result_json


#: The metrics the ablation summarises over seeds.
ABLATION_KEYS = ("psnr", "ssim", "fscore", "precision", "recall", "chamfer_m", "n_triangles", "train_seconds")


def bench_ablation(
    bench: BenchScene, out: Path, preset: str = "default", seeds: int = 1, log: Callable = print
) -> dict[str, Any]:
    """Every method on one scene: ours, the TS+ baseline and the ablations (Table III analogue),
    each trained with seeds ``0 … seeds-1``; with more than one, ``summary`` gives each method's
    mean, lowest and highest of :data:`ABLATION_KEYS` (the run-to-run noise beside the
    differences between methods)."""
    from splat.config import METHODS, make_config

    configs = [make_config(m, preset, seed=seed) for seed in range(seeds) for m in METHODS]
    name = (lambda c: c.method) if seeds == 1 else (lambda c: f"{c.method}_seed{c.seed}")
    rows = _run_all(bench, configs, out, name, log)
    summary = {method: seed_spread([r for r in rows if r["method"] == method]) for method in METHODS}
    result = {
        "scene": str(bench.scene_dir),
        "preset": preset,
        "seeds": seeds,
        "rows": rows,
        "summary": summary,
        "plot": str(out / "ablation.png"),
    }
    _plot_bars(summary, out / "ablation.png")
    _write(out, "bench_ablation", result)
    return result


def seed_spread(rows: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Mean, lowest and highest of each of :data:`ABLATION_KEYS` over ``rows`` (one method's runs
    with different seeds); a metric some run lacks is left out."""
    spread = {}
    for key in ABLATION_KEYS:
        values = [r[key] for r in rows if r.get(key) is not None]
        if values and len(values) == len(rows):
            spread[key] = {
                "mean": float(np.mean(values)),
                "min": float(min(values)),
                "max": float(max(values)),
            }
    return spread


def bench_noise(
    bench: BenchScene, out: Path, noise_m: list[float], preset: str = "default", log: Callable = print
) -> dict[str, Any]:
    """``ours`` with Gaussian noise on the warm-start vertices (the Fig. 6 analogue)."""
    from splat.config import make_config

    configs = [make_config("ours", preset, init_noise_m=n) for n in noise_m]
    rows = _run_all(bench, configs, out, lambda c: f"noise_{c.init_noise_m:g}", log)
    result = {"scene": str(bench.scene_dir), "preset": preset, "rows": rows, "plot": str(out / "noise.png")}
    _plot_noise(rows, out / "noise.png")
    _write(out, "bench_noise", result)
    return result


def _plot_pareto(rows: list[dict], front: list[int], path: Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    ax.scatter([r["train_seconds"] for r in rows], [r["chamfer_m"] for r in rows], c="#888", label="runs")
    best = [rows[i] for i in front]
    ax.plot(
        [r["train_seconds"] for r in best],
        [r["chamfer_m"] for r in best],
        "o-",
        c="#c0392b",
        label="Pareto front",
    )
    for r in rows:
        label = f"{r['iterations']} it / {r['init_max_triangles'] // 1000}k / half {r['coarse_until']:g}"
        ax.annotate(
            label, (r["train_seconds"], r["chamfer_m"]), fontsize=7, textcoords="offset points", xytext=(4, 4)
        )
    ax.set(xlabel="training time (s)", ylabel="Chamfer-L1 (m)", title="Run time against error")
    ax.legend()
    save_figure(plt, fig, path)


def _plot_bars(summary: dict[str, dict[str, dict[str, float]]], path: Path) -> None:
    """Each method's mean as a bar, its lowest and highest over the seeds as an error bar."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.5), dpi=120)
    names = list(summary)
    panels = (("psnr", "PSNR (dB)"), ("fscore", "F-score @10 cm"), ("chamfer_m", "Chamfer (m)"))
    for ax, (key, label) in zip(axes, panels, strict=True):
        mean = np.array([summary[n][key]["mean"] for n in names])
        low = mean - [summary[n][key]["min"] for n in names]
        high = np.array([summary[n][key]["max"] for n in names]) - mean
        colours = ["#c0392b" if n == "ours" else "#7f8c8d" for n in names]
        ax.bar(names, mean, yerr=np.stack([low, high]), capsize=3, color=colours)
        ax.set_title(label)
        ax.tick_params(axis="x", rotation=45)
    save_figure(plt, fig, path)


def _plot_noise(rows: list[dict], path: Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    noise = [100 * r["init_noise_m"] for r in rows]
    ax.plot(noise, [r["fscore"] for r in rows], "o-", c="#c0392b", label="F-score @10 cm")
    ax.set(xlabel="warm-start vertex noise σ (cm)", ylabel="F-score", ylim=(0, 1.02))
    twin = ax.twinx()
    twin.plot(noise, [r["psnr"] for r in rows], "s--", c="#2c3e50", label="PSNR")
    twin.set_ylabel("test PSNR (dB)")
    fig.legend(loc="lower left")
    save_figure(plt, fig, path)


def resolve_scene(
    scene: Path | None, gt: Path | None, out: Path, preset: str, quick: bool, log: Callable
) -> BenchScene:
    """The given scene and ground truth, or a fresh virtual-rig scene of ``preset`` under
    ``out/scene``."""
    if scene is None and gt is None:
        from rig.sim.scenes import get_preset

        get_preset(preset)  # an unknown name is an error before anything runs
        return virtual_scene(out / "scene", preset, quick=quick, log=log)
    if scene is None or gt is None:
        raise InputError(
            "give both --scene and --gt, or neither (a virtual-rig scene is made)", field="scene"
        )
    return BenchScene(scene, gt)
