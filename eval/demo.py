"""``lts demo``: a virtual-rig scene recorded through the mock devices and reconstructed.

1. ``lts sim DIR/sim --preset room`` (``--quick``: the simulator's 3 s, 160×120 run);
2. ``rig record --sim DIR/sim --out DIR/session.mcap`` — the same drivers, recorder and clock
   estimation a robot uses, fed by fake devices that speak the real wire protocols;
3. the ground truth moved onto the recording's clock (``DIR/ground_truth``): the recorder stamps
   with its own host clock, so the true trajectory is shifted by the difference of the first
   camera frame's stamps in the two sessions, and the true camera–LiDAR time offset changes by
   how much more the LiDAR's stamps moved than the camera's (the drivers' clock estimation);
4. ``lts reconstruct`` with the rig's nominal calibration as the starting guess (``--init``), the
   fallback mapper, training and evaluation against the ground truth.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from eval.reconstruct import ReconstructOptions, ReconstructResult, StageRecord, reconstruct
from rig.trajectory_io import read_tum, write_tum


def first_frame_ns(session: Path) -> int:
    """Host stamp (ns) of the first camera frame of ``session``."""
    from rig.session import SessionReader
    from slam_bridge.session_streams import find_topics

    reader = SessionReader(session)
    topic = find_topics(reader).image
    return int(next(iter(reader.frames(topic))).t_host)


def _scan_stamps_by_first_point(session: Path) -> dict[tuple[float, ...], int]:
    """Host stamp (ns) of every LiDAR scan, keyed by its first point (mm): the mock LiDAR replays
    the simulated scans point for point, so the key finds the same scan in both sessions."""
    from rig.session import SessionReader
    from slam_bridge.session_streams import find_topics

    reader = SessionReader(session)
    scans = reader.scans(find_topics(reader).points)
    return {tuple(np.round(s.points[0], 3)): int(s.t_host) for s in scans if len(s.points)}


def lidar_shift_ns(simulation: Path, recording: Path) -> int:
    """Median shift (ns) of the recording's LiDAR stamps from the simulation's, same scans."""
    simulated = _scan_stamps_by_first_point(simulation)
    recorded = _scan_stamps_by_first_point(recording)
    shifts = [t - simulated[key] for key, t in recorded.items() if key in simulated]
    if not shifts:
        raise RuntimeError(f"no LiDAR scan of {recording} matches one of {simulation}")
    return int(np.median(shifts))


def _run(command: list[str], what: str) -> None:
    if subprocess.run(command).returncode != 0:
        raise RuntimeError(f"{what} failed: {' '.join(command)}")


def shifted_ground_truth(sim_dir: Path, recording: Path, out: Path) -> int:
    """Write ``out/{mesh.ply, trajectory.tum, calib.yaml}``: the simulation's ground truth with the
    trajectory and the time offset on the recording's host clock; returns the trajectory's shift
    in ns."""
    from rig.calibration import load_calibration, save_calibration

    truth = sim_dir / "ground_truth"
    shift = first_frame_ns(recording) - first_frame_ns(sim_dir / "session.mcap")
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(truth / "mesh.ply", out / "mesh.ply")
    calibration = load_calibration(truth / "calib.yaml")
    # time_offset_s is added to LiDAR stamps to put them on the camera's timeline.
    calibration.time_offset_s += (shift - lidar_shift_ns(sim_dir / "session.mcap", recording)) / 1e9
    save_calibration(calibration, out / "calib.yaml")
    trajectory = read_tum(truth / "trajectory.tum")
    write_tum(type(trajectory).from_poses(trajectory.t_ns + shift, trajectory.poses), out / "trajectory.tum")
    return shift


def run_demo(
    out: Path, quick: bool, log: Callable[[str], None] = print
) -> tuple[ReconstructResult, list[StageRecord]]:
    """Simulate, record and reconstruct; returns the reconstruction and the demo's own stages."""
    bin_dir = Path(sys.executable).parent
    sim_dir, session, gt = out / "sim", out / "session.mcap", out / "ground_truth"
    stages = []
    if not (sim_dir / "session.mcap").is_file():
        started = time.perf_counter()
        log("[simulate] lts sim (room)")
        _run(
            [str(bin_dir / "lts"), "sim", str(sim_dir), "--preset", "room", *(["--quick"] if quick else [])],
            "lts sim",
        )
        stages.append(StageRecord("simulate", "ran", round(time.perf_counter() - started, 2)))
    if not session.is_file():
        from rig.session import SessionReader

        summary = SessionReader(sim_dir / "session.mcap").topics()
        duration_s = (
            max(t.last_t for t in summary.values()) - min(t.first_t for t in summary.values())
        ) / 1e9
        started = time.perf_counter()
        log(f"[record] rig record --sim ({duration_s:.0f} s through the mock devices)")
        partial = out / "session.partial.mcap"
        # The mock devices replay the scene in a loop: record one pass, not the jump back to its start.
        _run([str(bin_dir / "rig"), "record", "--sim", str(sim_dir), "--out", str(partial),
              "--duration", f"{duration_s:.2f}"], "rig record")  # fmt: skip
        partial.replace(session)
        stages.append(StageRecord("record", "ran", round(time.perf_counter() - started, 2)))
    shift = shifted_ground_truth(sim_dir, session, gt)
    log(f"[ground truth] trajectory shifted by {shift / 1e9:.3f} s onto the recording's clock")
    options = ReconstructOptions(
        session, out / "run", init=sim_dir / "ground_truth" / "calib.yaml", gt=gt,
        # 3 s at one keyframe per 0.5 s would leave no keyframe to test on.
        preset="fast" if quick else "default", keyframe_interval_s=0.2 if quick else None,
    )  # fmt: skip
    return reconstruct(options, log), stages
