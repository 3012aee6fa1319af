"""``lts train --blocks``: partition the scene, train the blocks as Ray tasks, merge them into one run.

``RUN_DIR`` ends up as any training run's (:mod:`splat.run_dir`: ``model.pt``, ``summary.json``,
meshes, renders), so ``lts eval`` and ``lts view`` read it unchanged, plus::

    partition.json         the ground frame and every block (core, margin, keyframes, faces)
    blocks/NN/scene/       block NN's scene folder (splat.blocks.block_scene)
    blocks/NN/run/         block NN's training run (checkpoints, model, train.log, worker.pid)
    blocks/NN/result.json  what its task reported: summary, wall time, peak memory, resumed at
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

from rig.atomic_file import write_atomic
from rig.cli_support import console
from rig.errors import InputError
from rig.mesh_io import load_mesh
from slam_bridge.scene import Scene, load_scene
from splat import run_dir as layout
from splat.blocks.block_scene import block_config, block_dir, write_block_scene
from splat.blocks.merge import core_triangles, merge_models
from splat.blocks.options import BlockOptions
from splat.blocks.partition import PARTITION_FILE, Block, Partition, partition_scene
from splat.blocks.ray_tasks import BlockJob, cluster_cpus, connect, import_ray, run_jobs
from splat.camera_blur import summary_width_px
from splat.config import TrainConfig
from splat.exposure import ViewExposures
from splat.held_out_views import evaluate_views, load_held_out_views, write_renders
from splat.lidar_points import lidar_points
from splat.model import load_model, save_model
from splat.trainer import TrainResult, export_run, scene_floor, train

RESULT_FILE = "result.json"


def train_in_blocks(
    scene_dir: str | Path,
    run_dir: str | Path,
    config: TrainConfig,
    options: BlockOptions,
    *,
    resume: bool = False,
    progress: bool = True,
    log: Callable = console.print,
) -> TrainResult:
    """Train ``config`` on the scene in ``scene_dir`` as spatial blocks on Ray and merge them into
    ``run_dir`` (``resume``: finished blocks are kept, the others continue from their checkpoints)."""
    import_ray()  # the missing extra is the first thing to hear about
    started = time.perf_counter()
    scene = load_scene(scene_dir)
    run_dir = Path(run_dir)
    mesh = load_mesh(scene.mesh_path)
    partition = partition_scene(
        scene, np.asarray(mesh.triangles_center), keyframe_budget=options.keyframe_budget,
        face_budget=options.face_budget, margin_m=options.margin_m,
        count=None if options.count == "auto" else int(options.count),
    )  # fmt: skip
    blocks = partition.blocks
    # Ray answers (or the error says why) before anything is written.
    ray = connect(options.ray_address, options.cpus) if len(blocks) > 1 else None
    _start_run_dir(scene, run_dir, config, partition, resume)
    if ray is None:
        log(f"the scene is one block ({blocks[0].n_train} training keyframes, {blocks[0].n_faces} warm-start "
            "faces, within the budgets): trained in this process")  # fmt: skip
        resume = resume and layout.checkpoint_path(run_dir).is_file()
        return train(scene, run_dir, config, resume=resume, progress=progress, log=log)
    n_train = len(scene.split("train"))
    sized = (f"of at most {options.keyframe_budget} training keyframes and {options.face_budget} warm-start "
             "faces" if options.count == "auto" else f"(--blocks {options.count})")  # fmt: skip
    log(f"{len(blocks)} blocks {sized}, {options.margin_m:g} m overlap: "
        + ", ".join(f"{b.n_train}" for b in blocks) + " training keyframes")  # fmt: skip
    done = {
        b.index: json.loads(f.read_text())
        for b in blocks
        if (f := block_dir(run_dir, b) / RESULT_FILE).is_file()
    }
    to_train = [b for b in blocks if b.index not in done]
    if to_train:
        cpus = cluster_cpus(ray)
        threads = options.threads or max(1, cpus // min(len(to_train), cpus))
        jobs = []
        for block in to_train:
            folder = block_dir(run_dir, block)
            block_scene = write_block_scene(scene, block, partition.frame, mesh, folder / "scene")
            settings = block_config(config, block, n_train).model_dump()
            jobs.append(BlockJob(block.index, str(block_scene), str(folder / "run"), settings, threads))
        log(f"training {len(jobs)} blocks on Ray ({cpus} CPUs, {threads} threads a block)")
        gpus = 1.0 if config.device.startswith("cuda") else 0.0

        def keep(index: int, result: dict) -> None:  # a rerun with --resume starts from the finished ones
            write_atomic(block_dir(run_dir, blocks[index]) / RESULT_FILE, json.dumps(result, indent=1))

        with _BlockProgress(jobs, progress) as display:
            done |= run_jobs(ray, jobs, gpus_per_job=gpus, on_progress=display.update, on_result=keep)
    return _merge(scene, run_dir, config, partition, done, time.perf_counter() - started)


def _start_run_dir(
    scene: Scene, run_dir: Path, config: TrainConfig, partition: Partition, resume: bool
) -> None:
    """Write the run's config, run info and partition; on ``resume`` check they are the run's."""
    run_dir.mkdir(parents=True, exist_ok=True)
    partition_file = run_dir / PARTITION_FILE
    described = partition.to_json()
    if resume:
        if not partition_file.is_file():
            raise InputError("no block run to resume (start without --resume)", path=partition_file)
        previous = json.loads(partition_file.read_text())
        if previous["blocks"] != json.loads(json.dumps(described["blocks"])):
            raise InputError("the run was partitioned otherwise (other budgets or margin); resume with the "
                             "same options or train into a new --out", path=partition_file)  # fmt: skip
    elif partition_file.is_file() or layout.checkpoint_path(run_dir).is_file():
        raise InputError("already holds a training run; pass --resume to continue it or pick a new --out",
                         path=run_dir)  # fmt: skip
    layout.config_path(run_dir).write_text(config.to_yaml())
    info = {"scene": str(scene.root.resolve()), "config": layout.CONFIG, "partition": PARTITION_FILE}
    layout.run_info_path(run_dir).write_text(json.dumps(info, indent=1))
    write_atomic(partition_file, json.dumps(described, indent=1))


def _merge(
    scene: Scene,
    run_dir: Path,
    config: TrainConfig,
    partition: Partition,
    results: dict[int, dict],
    wall_s: float,
) -> TrainResult:
    """Merge the blocks' models into ``run_dir`` as one run: model, colour maps, test metrics and
    renders, meshes, metrics line and summary."""
    blocks = partition.blocks
    runs = [block_dir(run_dir, b) / "run" for b in blocks]
    models = [load_model(layout.model_path(r), config.device) for r in runs]
    keep = [core_triangles(m, b, partition.frame) for m, b in zip(models, blocks, strict=True)]
    model = merge_models(models, keep, [float(b.n_train) for b in blocks])
    save_model(model, layout.model_path(run_dir))
    maps, rule = _merged_color_maps(scene, partition, runs, run_dir)
    summaries = [results[b.index]["summary"] for b in blocks]
    blur = _merged_camera_blur(summaries, blocks, runs)
    test_views = load_held_out_views(scene, scene.split("test"), config)
    for view in test_views:
        view.blur_px = blur["width_px"]
        if view.name in maps:
            view.color_map = torch.as_tensor(maps[view.name], dtype=torch.float32, device=config.device)
    test = evaluate_views(model, test_views, scene.camera) if test_views else {}
    write_renders(model, test_views, scene.camera, layout.renders_dir(run_dir))
    keyframes = scene.split("train")
    lidar = lidar_points(scene, keyframes)
    export = export_run(model, scene, keyframes, run_dir, scene_floor(scene, keyframes, lidar), lidar)
    iterations = sum(s["iterations"] for s in summaries)
    line = {"iteration": iterations, "elapsed_s": round(wall_s, 3), "n_triangles": model.n_triangles, **test}
    layout.metrics_path(run_dir).write_text(json.dumps(line) + "\n")
    per_block = [_block_report(b, results[b.index], int(k.sum())) for b, k in zip(blocks, keep, strict=True)]
    skips = [f"{len(blocks)} blocks trained apart and merged; what each one skipped is in its "
             f"blocks/NN/run/summary.json"]  # fmt: skip
    result = TrainResult(
        str(run_dir), config.method, config.preset, config.device, iterations, round(wall_s, 3),
        model.n_triangles, any(s["stopped_early"] for s in summaries),
        sum(s["rejected_steps"] for s in summaries), test, skips, [], export, _exposure_summary(maps, rule),
        per_block, camera_blur=blur,
    )  # fmt: skip
    layout.summary_path(run_dir).write_text(json.dumps(asdict(result), indent=1))
    return result


def _merged_camera_blur(summaries: list[dict], blocks: list[Block], runs: list[Path]) -> dict:
    """The camera's blur of the merged run: the blocks' fitted widths (one camera; their runs'
    summaries) weighted by their training keyframes."""
    widths = [summary_width_px(s, layout.summary_path(r)) for s, r in zip(summaries, runs, strict=True)]
    weights = [float(b.n_train) for b in blocks]
    width = round(sum(w * n for w, n in zip(widths, weights, strict=True)) / max(sum(weights), 1.0), 2)
    return {"width_px": width, "blocks_px": widths}


def _block_report(block: Block, result: dict, kept: int) -> dict:
    """One block's line in ``summary.json["blocks"]``."""
    summary = result["summary"]
    return {
        **block.describe(),
        "iterations": summary["iterations"],
        "train_seconds": summary["train_seconds"],
        "wall_s": result["wall_s"],
        "peak_rss_mb": result["peak_rss_mb"],
        "resumed_at": result["resumed_at"],
        "triangles": summary["n_triangles"],
        "triangles_kept": kept,
        "test": summary["test"],
    }


def _merged_color_maps(
    scene: Scene, partition: Partition, runs: list[Path], run_dir: Path
) -> tuple[dict[str, list], str | None]:
    """Every keyframe's colour map from the block its camera stands in (else the first block that
    has one for it; else the identity) and how the blocks chose the held-out ones, written to
    ``run_dir/exposure.json``; empty when no block learnt maps."""
    per_block = [layout.read_color_maps(r) for r in runs]
    if not any(maps for maps, _ in per_block):
        return {}, None
    maps: dict[str, list] = {}
    for k in scene.keyframes:
        centre = partition.frame.project(k.T_world_cam[None, :3, 3])
        owners = sorted(range(len(runs)), key=lambda i: not partition.blocks[i].in_core(centre)[0])
        found = next((per_block[i][0][k.name] for i in owners if k.name in per_block[i][0]), np.eye(3))
        maps[k.name] = np.asarray(found).tolist()
    rules = sorted({rule for m, rule in per_block if m and rule})
    record = {"test_views": "; ".join(rules), "maps": maps}
    write_atomic(layout.exposure_path(run_dir), json.dumps(record, indent=1))
    return maps, record["test_views"]


def _exposure_summary(maps: dict[str, list], rule: str | None) -> dict:
    """``summary.json["exposure"]`` of the merged colour maps (empty without any)."""
    if not maps:
        return {}
    offsets = torch.as_tensor(np.array(list(maps.values())), dtype=torch.float32) - torch.eye(3)
    return {**ViewExposures(offsets).summary(), "test_views": rule}


class _BlockProgress:
    """One Rich display of every block's training progress (a bar each)."""

    def __init__(self, jobs: list[BlockJob], enabled: bool):
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

        self.progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                 TimeRemainingColumn(), console=console, disable=not enabled)  # fmt: skip
        self.tasks = {
            j.index: self.progress.add_task(f"block {j.index:2d}", total=j.config["iterations"]) for j in jobs
        }

    def __enter__(self) -> _BlockProgress:
        self.progress.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self.progress.__exit__(*exc)

    def update(self, board: dict[int, tuple[int, int]]) -> None:
        for index, (done, total) in board.items():
            if index in self.tasks:
                self.progress.update(self.tasks[index], completed=done, total=total)
