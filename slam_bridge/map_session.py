"""The fallback mapper on a recording: its LiDAR sweeps in, a SLAM folder out (``lts slam run``
and the slam stage of ``lts reconstruct`` without ``--slam``)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from slam_bridge.fallback_mapper import MapperConfig, run_mapper
from slam_bridge.slam_dir import write_slam_dir

if TYPE_CHECKING:
    from rig.session import Recording


@dataclass(frozen=True)
class MapSummary:
    """What the mapper wrote into ``out``."""

    out: str
    scans_used: int
    poses: int
    faces: int
    path_length_m: float
    dynamic_fraction: float

    def describe(self) -> str:
        """One line for the user."""
        return (
            f"wrote {self.out}/mesh.ply ({self.faces} faces) and trajectory.tum ({self.poses} poses, "
            f"{self.path_length_m:.2f} m); {100 * self.dynamic_fraction:.1f} % of the LiDAR points, judged "
            "moving (other sweeps see through them), were left out of the mesh"
        )


def map_session(
    session: Recording | Path,
    out: Path,
    config: MapperConfig | None = None,
    points_topic: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> MapSummary:
    """Map the LiDAR sweeps of ``session`` (an open recording or its path; topic ``points_topic``,
    else the recording's choice) with the fallback mapper and write the cleaned mesh and the
    trajectory into the SLAM folder ``out``. ``progress(done, total)`` follows the sweeps."""
    from rig.session import as_recording, find_topics

    reader = as_recording(session)
    topic = find_topics(reader, points=points_topic, require_image=False).points
    total = reader.topic_types()[topic][1]
    result = run_mapper(
        reader.scans(topic),
        config or MapperConfig(),
        progress=None if progress is None else lambda i: progress(i + 1, total),
    )
    mesh, _ = write_slam_dir(out, result.mesh, result.trajectory)
    steps = np.diff(result.trajectory.translations, axis=0)
    return MapSummary(
        str(out), result.scans_used, len(result.trajectory), len(mesh.faces),
        float(np.linalg.norm(steps, axis=1).sum()), result.dynamic_fraction,
    )  # fmt: skip
