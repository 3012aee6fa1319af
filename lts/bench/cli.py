"""``lts bench``: the benchmarks — rasteriser speed, training run time against error, the ablation
table, the warm-start noise curve, the calibration's accuracy, the images' own ceiling and the
stress suite."""

from __future__ import annotations

from pathlib import Path

import typer

from lts.stress.cli import bench_stability_command
from rig.cli_support import HELP_MARKUP, console, emit_json, output_folder_option

bench_app = typer.Typer(
    rich_markup_mode=HELP_MARKUP, name="bench", help="Benchmarks (timings and memory).", no_args_is_help=True
)

SCENE_OPTION = typer.Option(None, "--scene", help="Prepared scene folder (default: a new virtual-rig scene).")
GT_OPTION = typer.Option(None, "--gt", help="Virtual-rig ground-truth folder of --scene's session.")
OUT_OPTION = output_folder_option(
    Path("bench_out"), "--out", "-o", help="Where runs, the JSON table and the plot go."
)
FULL_OPTION = typer.Option(
    False, "--full", help="Simulate the full 20 s, 320x240 run instead of the quick 3 s, 160x120 one."
)


def sim_option(default: str) -> typer.models.OptionInfo:
    """``--sim PRESET``: the virtual-rig preset simulated when no --scene is given."""
    return typer.Option(
        default,
        "--sim",
        help="Virtual-rig preset simulated when no --scene is given (office: the furnished one with "
        "photographic textures, for image fidelity; room: the demo's).",
    )


JSON_OPTION = typer.Option(False, "--json", help="Print one JSON object on stdout.")


def _log(message: str) -> None:
    console.print(message, highlight=False, markup=False)


def _finish(result: dict, json_out: bool) -> None:
    console.print(f"plot: {result['plot']}", highlight=False)
    if json_out:
        emit_json(result)


@bench_app.command("train")
def bench_train_command(
    iterations: list[int] | None = typer.Option(
        None,
        "--iterations",
        "-n",
        help="Iteration budgets (by default 300, 600 and 1200; with --profile 3000).",
    ),
    triangles: list[int] = typer.Option(
        [4000, 12000], "--triangles", "-t", help="Warm-start triangle budgets."
    ),
    half_resolution: list[float] = typer.Option(
        [0.25],
        "--half-resolution",
        min=0.0,
        max=1.0,
        help="Fractions of the iterations trained at half resolution (the coarse start; 0: full "
        "resolution throughout, 1: half throughout; repeat to sweep). Views whose half size would be "
        "under 120 px on the shorter side (the quick room's) always train at full resolution.",
    ),
    profile: bool = typer.Option(
        False,
        "--profile",
        help="Instead of the sweep: one training (default preset, the first --iterations) with the "
        "milliseconds per iteration of each part of a step (render, loss, backward passes, optimiser, "
        "densification, evaluation); needs only --scene.",
    ),
    scene: Path | None = SCENE_OPTION,
    gt: Path | None = GT_OPTION,
    sim: str = sim_option("room"),
    out: Path = OUT_OPTION,
    full: bool = FULL_OPTION,
    json_out: bool = JSON_OPTION,
) -> None:
    """Run time against error: sweep iteration and triangle budgets; the Pareto front (time vs Chamfer).
    With --profile: where a training iteration's time goes."""
    from lts.bench.training import bench_profile, bench_train, profile_config, resolve_scene, sweep_configs

    if profile:
        config = profile_config((iterations or [3000])[0])
        scene_dir = (
            scene if scene is not None else resolve_scene(None, None, out, sim, not full, _log).scene_dir
        )
        result = bench_profile(scene_dir, out, config, _log)
        _print_profile(result)
        if json_out:
            emit_json(result)
        return
    configs = sweep_configs(iterations or [300, 600, 1200], triangles, half_resolution)
    result = bench_train(resolve_scene(scene, gt, out, sim, not full, _log), out, configs, _log)
    _finish(result, json_out)


def _print_profile(result: dict) -> None:
    from rich.table import Table

    table = Table(title=f"ms per iteration ({result['iterations']} iterations, {result['n_triangles_end']} "
                  "triangles at the end)")  # fmt: skip
    table.add_column("part of a step")
    table.add_column("ms", justify="right")
    table.add_column("share", justify="right")
    total = result["ms_total"]
    for section, ms in result["ms_per_iteration"].items():
        table.add_row(section, f"{ms:.2f}", f"{ms / max(total, 1e-9):.0%}")
    table.add_row("total", f"{total:.2f}", "100%")
    console.print(table)
    console.print(
        f"D-SSIM alone (forward+backward, inside the loss rows): {result['dssim_ms']:.2f} ms; "
        f"test PSNR {result['test_psnr']:.2f} dB",
        highlight=False,
    )


@bench_app.command("ablation")
def bench_ablation_command(
    preset: str = typer.Option("default", help="Training preset for every method."),
    scene: Path | None = SCENE_OPTION,
    gt: Path | None = GT_OPTION,
    sim: str = sim_option("office"),
    out: Path = OUT_OPTION,
    full: bool = FULL_OPTION,
    seeds: int = typer.Option(
        1,
        "--seeds",
        min=1,
        help="Train every method with seeds 0..N-1: each method's mean, lowest and highest, to tell "
        "the differences between methods from the run-to-run noise.",
    ),
    json_out: bool = JSON_OPTION,
) -> None:
    """Ours vs the photometric-only TS+ baseline vs the ablations on one scene (Table III analogue)."""
    from lts.bench.training import bench_ablation, resolve_scene

    bench = resolve_scene(scene, gt, out, sim, not full, _log)
    _finish(bench_ablation(bench, out, preset, seeds, _log), json_out)


@bench_app.command("noise")
def bench_noise_command(
    noise: list[float] = typer.Option(
        [0.0, 0.05, 0.1, 0.2, 0.3], "--noise", help="Vertex noise σ in metres."
    ),
    preset: str = typer.Option("default", help="Training preset."),
    scene: Path | None = SCENE_OPTION,
    gt: Path | None = GT_OPTION,
    sim: str = sim_option("room"),
    out: Path = OUT_OPTION,
    full: bool = FULL_OPTION,
    json_out: bool = JSON_OPTION,
) -> None:
    """Quality against Gaussian noise on the warm-start mesh vertices (Fig. 6 analogue)."""
    from lts.bench.training import bench_noise, resolve_scene

    bench = resolve_scene(scene, gt, out, sim, not full, _log)
    _finish(bench_noise(bench, out, noise, preset, _log), json_out)


@bench_app.command("calib")
def bench_calib_command(
    sim: list[str] = typer.Option(
        None,
        "--sim",
        help="Virtual-rig presets to simulate (repeat: --sim room --sim street); default room, none "
        "when --kitti-frames, --nuscenes-sample or --pjlab-pairs is given.",
    ),
    seeds: int = typer.Option(
        3, "--seeds", min=1, help="Sessions per preset: seeds S to S+N-1 (S: --first-seed, 0 by default)."
    ),
    first_seed: int = typer.Option(
        0,
        "--first-seed",
        min=0,
        help="The first seed: e.g. sessions held out from a choice made on seeds 0 to S-1.",
    ),
    guess: list[str] = typer.Option(
        None,
        "--guess",
        help="Initial guesses: DEG/CM (the truth turned DEG degrees about a random axis and moved CM "
        "cm in a random direction) or none (the recording alone). Repeat; default 0/0, 2/10, 10/30 "
        "and none.",
    ),
    duration: float = typer.Option(10.0, "--duration", min=2.0, help="Seconds of each simulated session."),
    kitti_frames: Path | None = typer.Option(
        None,
        "--kitti-frames",
        help="Also each frame of a folder in KITTI's object layout (calib/NAME.txt, image_2/NAME.png, "
        "velodyne/NAME.bin; reference: its target-based calibration), one frame at a time.",
    ),
    nuscenes_sample: Path | None = typer.Option(
        None,
        "--nuscenes-sample",
        help="Also each camera of a nuScenes sample (calib.json naming one LiDAR sweep .pcd.bin and "
        "the cameras' images, intrinsics and reference with the car's motion between the stamps), one "
        "camera at a time.",
    ),
    pjlab_pairs: Path | None = typer.Option(
        None,
        "--pjlab-pairs",
        help="Also each image + cloud pair in PJLab's OpenCalib layout (a folder with an image, a .pcd, "
        "CAMERA-intrinsic.json and LIDAR-to-CAMERA-extrinsic.json, the reference; or a folder of such "
        "folders), one pair at a time.",
    ),
    out: Path = OUT_OPTION,
    json_out: bool = JSON_OPTION,
) -> None:
    """Calibration from a recording: accuracy, success rate, honesty of the verdict and coverage of
    the reported spread of the targetless extrinsic (and the time offset), over seeds × guesses."""
    from calib.kitti_frames import kitti_frame_names
    from calib.nuscenes_sample import nuscenes_camera_names
    from calib.pjlab_pairs import pjlab_pair_names
    from lts.bench.calibration import DEFAULT_GUESSES, bench_calib, parse_guess
    from rig.sim.scenes import get_preset

    guesses = [parse_guess(g) for g in guess or DEFAULT_GUESSES]
    real = any(folder is not None for folder in (kitti_frames, nuscenes_sample, pjlab_pairs))
    sim = sim or ([] if real else ["room"])
    for preset in sim:
        get_preset(preset)  # an unknown preset stops here, before any session is simulated
    if kitti_frames is not None:
        kitti_frame_names(kitti_frames)  # a folder without frames stops here, before any simulation
    if nuscenes_sample is not None:
        nuscenes_camera_names(nuscenes_sample)
    if pjlab_pairs is not None:
        pjlab_pair_names(pjlab_pairs)
    result = bench_calib(
        sim,
        range(first_seed, first_seed + seeds),
        guesses,
        duration,
        out / "calib",
        _log,
        kitti_frames,
        nuscenes_sample,
        pjlab_pairs,
    )
    _print_calib(result)
    _finish(result, json_out)


def _print_calib(result: dict) -> None:
    from rich.table import Table

    bounds = result["success_bounds"]
    title = (f"extrinsic error from each guess (success: within {bounds['rotation_deg']}° and "
             f"{100 * bounds['translation_m']:g} cm; ok/wrong: ok verdicts, those beyond it)")  # fmt: skip
    table = Table(box=None, title=title)
    for column in ("source", "guess", "° med/max", "cm med/max", "success", "ok/wrong", "in 95%", "s"):
        table.add_column(column, no_wrap=True)
    for source, by_guess in result["summary"].items():
        for label, row in by_guess.items():
            rot, trans = row["rotation_error_deg"], row["translation_error_m"]
            table.add_row(
                source,
                label,
                f"{rot['median']:.2f}/{rot['max']:.2f}" if rot else "not run",
                f"{100 * trans['median']:.1f}/{100 * trans['max']:.1f}" if trans else "",
                f"{row['success_rate']:.0%}",
                f"{row['ok']}/{row['false_ok']}",
                "" if row["coverage_95"] is None else f"{row['coverage_95']:.0%}",
                "" if row["median_seconds"] is None else f"{row['median_seconds']:.1f}",
            )
    console.print(table)


@bench_app.command("images")
def bench_images_command(
    sim: str = typer.Option("office", "--sim", help="Virtual-rig preset (office: the image-fidelity one)."),
    seed: int = typer.Option(0, "--seed", min=0, help="The simulator's seed."),
    quick: bool = typer.Option(False, "--quick", help="The simulator's 3 s, 160x120 run."),
    interval: float = typer.Option(
        0.5,
        "--keyframe-interval",
        min=0.01,
        help="One keyframe per this many seconds (lts prepare's default).",
    ),
    test_every: int = typer.Option(8, "--test-every", min=2, help="Every n-th keyframe is a test view."),
    json_out: bool = JSON_OPTION,
) -> None:
    """How closely any render of a static scene can match a virtual-rig preset's test images (its
    texture's level of detail, lts prepare's undistortion): the ceiling no training passes."""
    from lts.bench.images import bench_images
    from rig.sim.config import SimConfig

    config = SimConfig(preset=sim, seed=seed)
    result = bench_images(config.quick() if quick else config, interval, test_every, _log)
    if json_out:
        emit_json(result)


@bench_app.command("raster")
def bench_raster(
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
    triangles: list[int] = typer.Option([20_000, 100_000], "--triangles", "-n", min=1, help="Scene sizes."),
    width: int = typer.Option(320, min=1, help="Image width in pixels."),
    height: int = typer.Option(240, min=1, help="Image height in pixels."),
    repeats: int = typer.Option(5, min=1, help="Timed runs per row (median; one warm-up first)."),
) -> None:
    """Forward+backward time and peak memory of every available rasteriser backend."""
    from splat.raster.bench import BenchRow, available_backends, run_bench

    backends = available_backends()
    console.print(f"backends: {', '.join(backends)}; {width}x{height}, 2-20 px triangles", highlight=False)

    def report(row: BenchRow) -> None:
        console.print(
            f"  {row.backend:<10} {row.n_triangles:>7} triangles  {row.ms_fwd_bwd:9.1f} ms  "
            f"{row.peak_mb:8.1f} MB",
            highlight=False,
        )

    result = run_bench(triangles, width, height, repeats, backends, report)
    for backend, x in result["speedup_vs_reference"].items():
        console.print(f"  {backend}: {x:.1f}x faster than the reference", highlight=False)
    if "cpu_simd" in result:
        simd = result["cpu_simd"]
        lanes = f"{simd['instruction_set']}, {simd['float_lanes']} float lanes"
        console.print(f"  cpu kernel: {lanes}", highlight=False)
    if json_out:
        emit_json(result)


bench_app.command("stability")(bench_stability_command)
