"""``lts demo``: a virtual-rig scene recorded through the mock devices and reconstructed.

1. ``lts sim DIR/sim --preset room`` (``--quick``: the simulator's 3 s, 160×120 run);
2. ``rig record --sim DIR/sim --once --out DIR/session.mcap`` — the same drivers, recorder and clock
   estimation a robot uses, fed by fake devices that speak the real wire protocols;
3. the ground truth moved onto the recording's clock (``DIR/ground_truth``): the recorder stamps
   with its own host clock, so the true trajectory is shifted by the difference of the first
   camera frame's stamps in the two sessions, and the true camera–LiDAR time offset changes by
   how much more the LiDAR's stamps moved than the camera's (the drivers' clock estimation);
4. ``lts reconstruct`` with the rig's nominal calibration as the starting guess (``--init``), the
   fallback mapper, training and evaluation against the ground truth (``--quick``: the fast preset,
   :data:`QUICK_ITERATIONS` iterations).

Simulating and recording are stages of the same :class:`~lts.stages.StageRunner` as the
reconstruction's, so a rerun reuses them.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import os
import shutil
import subprocess
import sys
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np

from lts.pipeline import ReconstructOptions, ReconstructResult, reconstruct
from lts.stages import StageRecord, StageRunner
from rig.native_build import NativeBuildError
from rig.trajectory_io import read_tum, write_tum

#: The quick room's training: its 15 keyframes at 160×120 gain little after 800 iterations (PSNR
#: 34.34 against 34.65 dB at 1150 of the fast preset's 1200, F 0.965 against 0.962, no probe
#: through either way) and its whole run stays under a minute (docs/benchmarks.md).
QUICK_ITERATIONS = 800

#: What the reconstruction imports, loaded while the recorder replays the scene in real time in its
#: own process and leaves this one idle (about 2.5 s of imports off the demo's path). ``torch._dynamo`` is
#: what the first ``torch.optim`` optimizer imports.
RECONSTRUCTION_MODULES = (
    "torch", "torch._dynamo", "pycolmap", "calib.session_calib", "slam_bridge.scene_builder",
    "splat.trainer", "eval.run_eval", "eval.report",
)  # fmt: skip
#: The compiled extensions the reconstruction loads (``module:function``), in the order its stages
#: need them: a first demo compiles them (~40 s) while the recorder runs, not after it.
EXTENSION_LOADERS = ("calib.photo_kernel:photo_extension", "splat.raster.extension:optional_cpu_extension")
#: The nice value of the compile: the real-time recorder keeps the CPU it needs.
BUILD_NICENESS = 19


def import_while_recording() -> threading.Thread:
    """A started thread that imports :data:`RECONSTRUCTION_MODULES`, then loads (building where
    not built yet) the :data:`EXTENSION_LOADERS` at :data:`BUILD_NICENESS` (Linux; join it before
    the next stage). A module or an extension that fails is left for its stage to report."""

    def load() -> None:
        for name in RECONSTRUCTION_MODULES:
            with contextlib.suppress(ImportError):
                importlib.import_module(name)
        if sys.platform.startswith("linux"):  # a thread's own nice value, which the compiler inherits
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), BUILD_NICENESS)
        for loader in EXTENSION_LOADERS:
            module, function = loader.split(":")
            with contextlib.suppress(ImportError, NativeBuildError):
                getattr(importlib.import_module(module), function)()

    thread = threading.Thread(target=load, name="import-while-recording", daemon=True)
    thread.start()
    return thread


def first_frame_ns(session: Path) -> int:
    """Host stamp (ns) of the first camera frame of ``session``."""
    from rig.session import SessionReader, find_topics

    reader = SessionReader(session)
    topic = find_topics(reader).image
    return int(next(iter(reader.frames(topic))).t_host)


def _scan_stamps_by_first_point(session: Path) -> dict[tuple[float, ...], int]:
    """Host stamp (ns) of every LiDAR scan, keyed by its first point (mm): the mock LiDAR replays
    the simulated scans point for point, so the key finds the same scan in both sessions."""
    from rig.session import SessionReader, find_topics

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


def simulate_preset(out: Path, preset: str, quick: bool, seed: int = 0) -> None:
    """The virtual rig's ``preset`` into ``out`` (``session.mcap``, ``ground_truth/``); ``quick``:
    its 3 s, 160×120 run."""
    from rig.sim.config import SimConfig
    from rig.sim.simulate import simulate

    config = SimConfig(preset=preset, seed=seed)
    simulate(config.quick() if quick else config, out)


def record_through_mock_devices(sim_dir: Path, out: Path, log: Callable[[str], None] = print) -> None:
    """``rig record --sim``: the robot-side recorder (its own process, in real time) fed by mock
    devices replaying ``sim_dir``; one pass of the scene, written to ``out`` when complete (its
    warnings on stderr as they come, then what ``out`` holds)."""
    from rig.record import written_line

    partial = out.with_suffix(".partial.mcap")
    # One pass (--once), not the jump back to the scene's start that the looping devices make.
    command = [str(Path(sys.executable).with_name("rig")), "record", "--sim", str(sim_dir), "--once"]
    recorded = subprocess.run([*command, "--out", str(partial), "--json"], stdout=subprocess.PIPE, text=True)
    if recorded.returncode != 0:
        raise RuntimeError(f"rig record failed: {' '.join(command[1:])}")
    partial.replace(out)
    log(f"  {written_line(out, json.loads(recorded.stdout)['written'])}")


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
    sim_dir, session, gt = out / "sim", out / "session.mcap", out / "ground_truth"
    stages = StageRunner(out, ("simulate", "record", "ground truth"), log)
    key = ["lts sim", str(sim_dir), "--preset", "room", *(["--quick"] if quick else [])]
    stages.run("simulate", key, [], sim_dir / "session.mcap", lambda: simulate_preset(sim_dir, "room", quick))
    key = ["rig record", "--sim", str(sim_dir), "--once", "--out", str(session)]
    importing = import_while_recording()
    stages.run("record", key, [sim_dir], session, lambda: record_through_mock_devices(sim_dir, session, log))
    importing.join()

    def move_ground_truth() -> None:
        shift = shifted_ground_truth(sim_dir, session, gt)
        log(f"  trajectory shifted by {shift / 1e9:.3f} s onto the recording's clock")

    key = ["the simulation's ground truth on the recording's clock"]
    inputs = [sim_dir / "ground_truth", session]
    stages.run("ground truth", key, inputs, gt / "calib.yaml", move_ground_truth)
    options = ReconstructOptions(
        session, out / "run", init=sim_dir / "ground_truth" / "calib.yaml", gt=gt,
        preset="fast" if quick else "default",  # the quick 3 s get a keyframe per 0.2 s, the 20 s per 0.5 s
        iterations=QUICK_ITERATIONS if quick else None,
    )  # fmt: skip
    return reconstruct(options, log), stages.records
