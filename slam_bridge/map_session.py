"""The fallback mapper on a recording: its LiDAR sweeps in, a SLAM folder out (``lts slam run``
and the slam stage of ``lts reconstruct`` without ``--slam``)."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from rig.atomic_file import write_atomic
from slam_bridge.fallback_mapper import MapperConfig, run_mapper
from slam_bridge.mapping_quality import MappingQuality
from slam_bridge.slam_dir import write_slam_dir

if TYPE_CHECKING:
    from rig.session import Recording


#: The mapper's settings and its verdict on the trajectory, beside mesh.ply and trajectory.tum.
MAPPING_FILE = "mapping.json"


@dataclass(frozen=True)
class MapSummary:
    """What the mapper wrote into ``out``, the settings it chose and its verdict."""

    out: str
    scans_used: int
    poses: int
    faces: int
    path_length_m: float
    dynamic_fraction: float
    settings: dict[str, float | int | bool]
    quality: MappingQuality

    def describe(self) -> list[str]:
        """Lines for the user: what was written, the settings, the verdict and its reasons."""
        s, q = self.settings, self.quality
        lines = [
            f"wrote {self.out}/mesh.ply ({self.faces} faces) and trajectory.tum ({self.poses} poses, "
            f"{self.path_length_m:.2f} m); {100 * self.dynamic_fraction:.1f} % of the LiDAR points, judged "
            "moving (other sweeps see through them), were left out of the mesh",
            f"odometry: VGICP, sweeps downsampled to {s['voxel_m']:.2f} m, map voxels "
            f"{s['map_voxel_m']:.2f} m, ranges up to {s['max_range_m']:g} m"
            + (", the static points registered again" if s["static_reregistration"] else "")
            + f"; TSDF voxel {s['tsdf_voxel_m']:.3g} m",
            f"trajectory: {q.verdict}"
            + (
                f" (moving objects moved it by at most {q.dynamic_shift_m:.2f} m)"
                if q.verdict == "ok"
                else ""
            ),
        ]
        lines += [f"  - {reason}" for reason in q.reasons]
        if self.faces == 0:
            lines.append(
                f"the mesh is empty: its {self.scans_used} sweeps saw too little of the same surfaces for "
                "the TSDF to keep any (lts prepare needs a mesh: record longer, or import a mapper's output)"
            )
        return lines


def map_session(
    session: Recording | Path,
    out: Path,
    config: MapperConfig | None = None,
    points_topic: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> MapSummary:
    """Map the LiDAR sweeps of ``session`` (an open recording or its path; topic ``points_topic``,
    else the recording's choice) with the fallback mapper and write the cleaned mesh, the
    trajectory and :data:`MAPPING_FILE` into the SLAM folder ``out``. ``progress(done, total)``
    follows the sweeps."""
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
    summary = MapSummary(
        str(out), result.scans_used, len(result.trajectory), len(mesh.faces),
        result.trajectory.path_length_m, result.quality.dynamic_fraction, result.settings, result.quality,
    )  # fmt: skip
    write_atomic(Path(out) / MAPPING_FILE, json.dumps(asdict(summary), indent=2) + "\n")
    return summary
