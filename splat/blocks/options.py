"""The options of ``lts train --blocks`` (kept apart so that the command line reads their defaults
without importing torch or Ray)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class BlockOptions:
    """How ``lts train --blocks`` partitions and where it runs.

    Attributes:
        keyframe_budget: most training keyframes per block.
        face_budget: most warm-start mesh faces per block core.
        margin_m: overlap margin around each block's core (m).
        ray_address: a Ray cluster to join; None starts a local instance.
        cpus: CPUs of the local instance (None: the machine's); ignored with an address.
        threads: CPU threads per block (None: the cluster's CPUs shared by the blocks that run at once).
    """

    keyframe_budget: int = 150
    face_budget: int = 1_000_000
    margin_m: float = 2.0
    ray_address: str | None = None
    cpus: int | None = None
    threads: int | None = None
