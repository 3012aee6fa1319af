"""A block's own scene folder and training settings, so that a block trains as an ordinary run.

``RUN_DIR/blocks/NN/scene`` is a scene folder (:mod:`slam_bridge.scene`) that lists the block's
keyframes, holds the warm-start faces and sparse points of its expanded region, and links the
parent scene's ``images/``, ``lidar/``, ``normals/`` and ``moving/`` folders instead of copying
them (a Ray cluster's workers therefore need the scene on a shared file system).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import trimesh

from rig.atomic_file import write_atomic
from slam_bridge.scene import (
    LIDAR_DIR,
    MOVING_DIR,
    MOVING_TOP_DIR,
    SPARSE_POINTS_FILE,
    Scene,
    write_scene_index,
)
from splat.blocks.partition import Block, GroundFrame
from splat.config import TrainConfig, validated

#: The parent scene's per-keyframe folders a block links to.
LINKED_DIRS = ("images", LIDAR_DIR, "normals", MOVING_DIR, MOVING_TOP_DIR)
#: A block trains at least this many iterations, however few keyframes it has.
MIN_BLOCK_ITERATIONS = 500


def block_dir(run_dir: Path, block: Block) -> Path:
    """``RUN_DIR/blocks/NN``: the block's scene (``scene/``) and training run (``run/``)."""
    return Path(run_dir) / "blocks" / f"{block.index:02d}"


def write_block_scene(
    scene: Scene, block: Block, frame: GroundFrame, mesh: trimesh.Trimesh, root: Path
) -> Path:
    """Write the scene folder of ``block`` into ``root`` (created) and return it.

    Args:
        scene: the whole scene.
        block: the block (its keyframes and regions).
        frame: the ground frame the block's bounds are in.
        mesh: the whole scene's warm-start mesh (its faces with a centroid in the expanded region
            are kept).
        root: the block's scene folder.
    """
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    for name in LINKED_DIRS:
        target, link = (scene.root / name).resolve(), root / name
        if target.is_dir() and not link.exists():
            os.symlink(target, link, target_is_directory=True)
    centroids = mesh.triangles_center
    faces = mesh.faces[block.in_expanded(frame.project(centroids))]
    cropped = trimesh.Trimesh(mesh.vertices, faces, process=False)
    cropped.remove_unreferenced_vertices()
    write_atomic(root / "mesh.ply", cropped.export(file_type="ply", encoding="binary"))
    sparse = None
    if scene.sparse_points_path is not None:
        points, colors = scene.sparse_points()
        inside = block.in_expanded(frame.project(points))
        cloud = trimesh.PointCloud(points[inside], colors=colors[inside] if len(colors) else None)
        write_atomic(root / SPARSE_POINTS_FILE, cloud.export(file_type="ply"))
        sparse = SPARSE_POINTS_FILE
    names = set(block.keyframes)
    keyframes = [k for k in scene.keyframes if k.name in names]
    source = {"block": block.index, "of_scene": str(scene.root.resolve())}
    write_scene_index(root, scene.camera, keyframes, scene.options, source, sparse_points=sparse)
    return root


def block_config(config: TrainConfig, block: Block, n_train_scene: int) -> TrainConfig:
    """The training settings of ``block``: ``config`` with its iterations (and the schedule steps
    counted in iterations: densification, evaluation, checkpoints) scaled by the block's share of
    the scene's training keyframes, so that each of its views is visited as often as in one run of
    the whole scene (at least :data:`MIN_BLOCK_ITERATIONS`, at most the whole scene's)."""
    share = block.n_train / max(n_train_scene, 1)
    iterations = min(config.iterations, max(MIN_BLOCK_ITERATIONS, math.ceil(config.iterations * share)))
    scale = iterations / config.iterations

    def scaled(steps: int) -> int:
        return max(1, round(steps * scale))

    return validated(
        config.model_dump()
        | {
            "iterations": iterations,
            "densify_every": scaled(config.densify_every),
            "eval_every": scaled(config.eval_every),
            "final_eval_every": scaled(config.final_eval_every),
            "checkpoint_every": scaled(config.checkpoint_every),
        }
    )
