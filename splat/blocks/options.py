"""The options of ``lts train --blocks`` (kept apart so that the command line reads their defaults
without importing torch or Ray)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class BlockOptions:
    """How ``lts train --blocks`` partitions and where it runs.

    Attributes:
        count: ``auto`` (blocks sized by the budgets) or a number of blocks (the budgets are then
            ignored: the block with the most training keyframes is halved until there are that many,
            or none can be halved).
        keyframe_budget: most training keyframes per block.
        face_budget: most warm-start mesh faces per block core.
        margin_m: overlap margin around each block's core (m).
        ray_address: a Ray cluster to join; None starts a local instance.
        cpus: CPUs of the local instance (None: the machine's); ignored with an address.
        threads: CPU threads per block (None: the cluster's CPUs shared by the blocks that run at once).
    """

    count: str = "auto"
    keyframe_budget: int = 150
    face_budget: int = 1_000_000
    margin_m: float = 2.0
    ray_address: str | None = None
    cpus: int | None = None
    threads: int | None = None


def parse_block_count(value: str) -> str:
    """``--blocks``'s value, checked: ``auto`` or a whole number of blocks >= 1 (as text)."""
    from rig.errors import InputError

    if value == "auto" or (value.isdigit() and int(value) >= 1):
        return value
    raise InputError(f"expected auto or a number of blocks >= 1, got {value!r}", field="blocks")


def refuse_learnt_poses(learn_poses: bool) -> None:
    """Blocks train apart, so each would learn its own correction of the keyframes they share and
    their merged triangles would disagree at the seams: ``--learn-poses`` is refused with
    ``--blocks`` (one line, before anything runs)."""
    from rig.errors import InputError

    if learn_poses:
        raise InputError("not with --blocks (each block would correct the keyframes it shares with its "
                         "neighbours on its own); train without --blocks or without --learn-poses",
                         field="learn-poses")  # fmt: skip
