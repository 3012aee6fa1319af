"""splat.blocks: long trajectories trained as spatial blocks on Ray and merged into one run.

``lts train SCENE --blocks`` partitions the scene on the ground plane (:mod:`.partition`), writes
each block a scene folder of its own (:mod:`.block_scene`), trains the blocks as Ray tasks that
are retried from their checkpoints (:mod:`.ray_tasks`) and merges their triangles into one run
folder (:mod:`.merge`, :mod:`.block_run`) that ``lts eval`` and ``lts view`` read like any other.
"""

from __future__ import annotations

from rig.lazy import lazy_exports

_EXPORTS = {
    "Block": "splat.blocks.partition",
    "GroundFrame": "splat.blocks.partition",
    "Partition": "splat.blocks.partition",
    "ground_frame": "splat.blocks.partition",
    "partition_scene": "splat.blocks.partition",
    "block_config": "splat.blocks.block_scene",
    "write_block_scene": "splat.blocks.block_scene",
    "merge_models": "splat.blocks.merge",
    "core_triangles": "splat.blocks.merge",
    "BlockOptions": "splat.blocks.options",
    "train_in_blocks": "splat.blocks.block_run",
}
__all__, __getattr__ = lazy_exports(__name__, _EXPORTS)
