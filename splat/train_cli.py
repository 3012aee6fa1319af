"""``lts train SCENE_DIR --out RUN_DIR``: the fine stage (mounted by eval/cli.py)."""

from __future__ import annotations

from pathlib import Path

import typer

from rig.cli_support import console, emit_json, output_folder_option
from rig.errors import InputError
from splat.blocks.options import BlockOptions, parse_block_count, refuse_learnt_poses
from splat.config import METHODS, PRESET_HELP, TrainConfig


def _block_option(flag: str, minimum: float, what: str, default: float):
    """A ``--block-*`` option: None unless given (it applies only with --blocks), its default shown."""
    return typer.Option(None, flag, min=minimum, help=f"With --blocks: {what} (default {default:g}).",
                        show_default=False)  # fmt: skip


def train_command(
    scene: Path = typer.Argument(..., help="Scene folder written by lts prepare."),
    out: Path = output_folder_option(
        ..., "--out", "-o", help="Run folder (config, metrics, checkpoints, model, mesh)."
    ),
    method: str = typer.Option(
        "ours",
        help=f"One of {', '.join(METHODS)}: ours (mesh warm start, LiDAR depth + normal losses, variance "
        "densification), tsplus (photometric-only TS+ baseline from SfM points), or an ablation.",
    ),
    preset: str = typer.Option("default", help=f"One of {PRESET_HELP}."),
    iterations: int | None = typer.Option(None, min=1, help="Override the preset's iteration count."),
    max_triangles: int | None = typer.Option(None, min=1, help="Override the triangle budget."),
    init_noise: float = typer.Option(
        0.0, "--init-noise", min=0, help="Gaussian noise (m) on warm-start vertices."
    ),
    half_resolution: float | None = typer.Option(
        None,
        "--half-resolution",
        min=0.0,
        max=1.0,
        help="Fraction of the iterations that render the training views at half resolution (a faster "
        "start; 0: full resolution throughout); "
        f"by default {TrainConfig.model_fields['coarse_until'].default}.",
    ),
    exposure: str = typer.Option(
        "auto",
        "--exposure",
        help="auto, on or off: learn a colour matrix per training image (auto-exposure, white balance); "
        "auto learns them when the images' gains, measured on the LiDAR points neighbouring images "
        "share, spread by more than 5 %.",
    ),
    learn_poses: bool = typer.Option(
        False,
        "--learn-poses",
        help="Learn a rigid correction of each training keyframe's pose with the triangles, held near "
        "the LiDAR pose by a prior; writes RUN_DIR/keyframe_poses.tum (the corrected poses). For poses "
        "rougher than the images (another mapper's, an imported trajectory); on good ones it gains "
        "little (docs/training.md).",
    ),
    seed: int = typer.Option(0, min=0, help="Seed of view order, sampling and noise."),
    device: str = typer.Option("cpu", help="cpu or cuda (the matching rasteriser kernel is used)."),
    resume: bool = typer.Option(
        False, "--resume", help="Continue the run in --out from its last checkpoint."
    ),
    blocks: str | None = typer.Option(
        None,
        "--blocks",
        metavar="auto|N",
        help="Train long trajectories as spatial blocks on Ray and merge them into one run (needs the "
        "blocks extra): auto sizes the blocks by --block-keyframes and --block-faces (a scene within "
        "them is one block); N makes N blocks.",
    ),
    block_keyframes: int | None = _block_option(
        "--block-keyframes", 1, "most training keyframes per block", BlockOptions.keyframe_budget
    ),
    block_faces: int | None = _block_option(
        "--block-faces", 1, "most warm-start mesh faces in a block's core", BlockOptions.face_budget
    ),
    block_margin: float | None = _block_option(
        "--block-margin", 0.0, "overlap margin around each block (m)", BlockOptions.margin_m
    ),
    ray_address: str | None = typer.Option(
        None,
        "--ray-address",
        help="A Ray cluster to run the blocks on: HOST:PORT (ray start --head prints it) or auto (the one "
        "ray start runs on this machine); without it a new local Ray instance uses this machine's CPUs. "
        "The scene and --out must be on a file system every node sees.",
    ),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show the progress bar."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object (the run summary) on stdout."),
) -> None:
    """Optimise triangles against the images and LiDAR depth, densify, export the mesh.

    Writes RUN_DIR/config.yaml, metrics.jsonl (one line per evaluation), checkpoints/last.pt
    (every N iterations and on Ctrl-C), model.pt, summary.json, renders/ and mesh.ply/obj/glb +
    collision.ply. Ctrl-C saves a checkpoint; rerun with --resume to continue bit for bit.
    """
    from splat.config import config_from_options
    from splat.trainer import TrainingDivergedError, TrainingInterruptedError, train

    block_settings = {"--block-keyframes": block_keyframes, "--block-faces": block_faces,
                      "--block-margin": block_margin, "--ray-address": ray_address}  # fmt: skip
    if blocks is None and (given := [name for name, value in block_settings.items() if value is not None]):
        raise InputError(f"only with --blocks, which was not given: {', '.join(given)}", field="blocks")
    count = None if blocks is None else parse_block_count(blocks)
    if count is not None:
        refuse_learnt_poses(learn_poses)

    config = config_from_options(
        method, preset, seed=seed, device=device, init_noise_m=init_noise, iterations=iterations,
        max_triangles=max_triangles, coarse_until=half_resolution, exposure=exposure, learn_poses=learn_poses,
    )  # fmt: skip
    try:
        if count is not None:
            from splat.blocks.block_run import train_in_blocks

            defaults = BlockOptions()
            options = BlockOptions(
                count,
                block_keyframes or defaults.keyframe_budget,
                block_faces or defaults.face_budget,
                defaults.margin_m if block_margin is None else block_margin,
                ray_address,
            )
            result = train_in_blocks(scene, out, config, options, resume=resume, progress=progress)
        else:
            result = train(scene, out, config, resume=resume, progress=progress)
    except TrainingInterruptedError as exc:
        console.print(str(exc), highlight=False)
        raise typer.Exit(130) from None
    except TrainingDivergedError as exc:
        console.print(f"error: training diverged: {exc}", highlight=False)
        raise typer.Exit(1) from None
    test = result.test
    console.print(
        f"{result.method}: {result.iterations} iterations in {result.train_seconds:.0f} s, "
        f"{result.n_triangles} triangles; test PSNR {test.get('test_psnr', float('nan')):.2f} dB, "
        f"SSIM {test.get('test_ssim', float('nan')):.3f}; rejected steps {result.rejected_steps}",
        highlight=False,
    )
    if result.exposure:
        e = result.exposure
        console.print(f"  colour maps per training image: gain {e['gain_min']:.2f}-{e['gain_max']:.2f}, "
                      f"channel mixing up to {e['mixing_max']:.3f}", highlight=False)  # fmt: skip
    if result.poses:
        p = result.poses
        console.print(f"  pose corrections: rotation median {p['rotation_median_deg']:.3f}° (largest "
                      f"{p['rotation_max_deg']:.3f}°), translation median {p['translation_median_cm']:.2f} "
                      f"cm (largest {p['translation_max_cm']:.2f} cm)", highlight=False)  # fmt: skip
    for line in result.skips:
        console.print(f"  skipped: {line}", highlight=False)
    for b in result.blocks:
        resumed = "" if b["resumed_at"] is None else f", resumed at iteration {b['resumed_at']}"
        console.print(
            f"  block {b['index']}: {b['train_keyframes']} training keyframes, {b['iterations']} "
            f"iterations in {b['wall_s']:.0f} s, peak {b['peak_rss_mb']:.0f} MB, {b['triangles_kept']} of "
            f"{b['triangles']} triangles kept{resumed}",
            highlight=False,
        )
    console.print(f"  mesh: {out / 'mesh.ply'}  collision: {out / 'collision.ply'}", highlight=False)
    if json_out:
        from dataclasses import asdict

        emit_json(asdict(result))
