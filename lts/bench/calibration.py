"""Benchmark of the calibration from a recording: the targetless extrinsic and the time offset on
virtual-rig sessions over seeds × initial guesses, and the extrinsic on single real frames (KITTI's
object layout, a nuScenes sample's cameras, PJLab's OpenCalib pairs) against each dataset's
reference.

Each session is simulated once (reused while up to date), its time offset estimated once, then the
extrinsic refined from every guess: the truth turned by a given angle about a random axis and moved
by a given distance in a random direction (both drawn from the session's seed), or no guess at all
(:func:`calib.session_calib.motion_guess`). Per trial it records the error against the truth, the
verdict, the reported spread and the seconds; per source (preset or KITTI) and guess: the median
and largest error, the share of successes, ``ok`` verdicts given while wrong, and how often the
truth lies inside the reported 95 % interval (over the trials that report one: axes kept from the
guess leave a trial without). Writes ``bench_calib.json`` and ``bench_calib.png``.
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from calib.targetless import ExtrinsicPair, ExtrinsicResult
from rig.camera import CameraModel
from rig.errors import InputError
from rig.transforms import distance_and_angle, make_transform

#: A trial succeeds within these bounds (rotation degrees, translation metres); they are also the
#: bounds beyond which an ``ok`` verdict counts as given while wrong.
SUCCESS_DEG = 0.5
SUCCESS_M = 0.05
NO_GUESS = "none"
DEFAULT_GUESSES = ("0/0", "2/10", "10/30", NO_GUESS)
#: The source names of the KITTI object-layout frames, the nuScenes sample's cameras and the
#: OpenCalib pairs in the table.
KITTI_SOURCE = "kitti"
NUSCENES_SOURCE = "nuscenes"
PJLAB_SOURCE = "pjlab"


@dataclass(frozen=True)
class Guess:
    """An initial-guess size: the truth turned by ``degrees`` and moved by ``centimetres``, or,
    with ``degrees`` None, no guess (the recording alone)."""

    degrees: float | None
    centimetres: float = 0.0

    @property
    def label(self) -> str:
        """How the table names it: ``10°/30 cm`` or ``none``."""
        return NO_GUESS if self.degrees is None else f"{self.degrees:g}°/{self.centimetres:g} cm"


def parse_guess(text: str) -> Guess:
    """``DEG/CM`` (e.g. ``10/30``: 10° and 30 cm from the truth) or ``none``."""
    if text.strip().lower() == NO_GUESS:
        return Guess(None)
    match = re.fullmatch(r"\s*([0-9.]+)\s*/\s*([0-9.]+)\s*", text)
    try:
        degrees, centimetres = float(match[1]), float(match[2])  # type: ignore[index]
    except (TypeError, ValueError):
        raise InputError(
            f"{text!r} is not DEG/CM (e.g. 10/30: the truth turned 10 degrees and moved 30 cm) or none",
            field="--guess",
        ) from None
    return Guess(degrees, centimetres)


def perturbed(T: np.ndarray, guess: Guess, rng: np.random.Generator) -> np.ndarray:
    """``T`` ``(4, 4)`` turned by exactly ``guess.degrees`` about a random axis (camera frame) and
    moved by exactly ``guess.centimetres`` in a random direction."""
    axis, direction = rng.normal(size=3), rng.normal(size=3)
    rotation = Rotation.from_rotvec(np.radians(guess.degrees or 0.0) * axis / np.linalg.norm(axis))
    move = guess.centimetres / 100.0 * direction / np.linalg.norm(direction)
    return make_transform(rotation.as_matrix() @ T[:3, :3], T[:3, 3] + move)


def _errors(T: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Rotation (degrees) and translation (metres) between two ``T_cam_lidar``."""
    distance, angle = distance_and_angle(T, truth)
    return float(np.degrees(angle)), float(distance)


def _session(out: Path, preset: str, seed: int, duration_s: float, log: Callable[[str], None]) -> Path:
    """The virtual-rig session of ``preset`` and ``seed`` under ``out`` (simulated unless up to
    date); returns its folder (``session.mcap``, ``ground_truth/``)."""
    from lts.stages import StageRunner
    from rig.sim.config import SimConfig
    from rig.sim.simulate import simulate

    folder = out / f"{preset}-seed{seed}"
    stages = StageRunner(folder, ("simulate",), log)
    key = ["lts sim", preset, str(seed), f"{duration_s:g}"]
    config = SimConfig(preset=preset, seed=seed, duration_s=duration_s)
    stages.run("simulate", key, [], folder / "session.mcap", lambda: simulate(config, folder))
    return folder


def _trial(
    refine: Callable[[np.ndarray], ExtrinsicResult],
    truth: np.ndarray,
    T_init: np.ndarray | None,
    truth_offset_s: float | None = None,
) -> dict[str, Any]:
    """One extrinsic refinement ``refine(T_init)`` scored against ``truth`` ``(4, 4)``; ``T_init``
    None: no guess could be made, not run. Where the refinement searched the time offset too, that
    offset is scored against ``truth_offset_s`` (s)."""
    if T_init is None:
        return {"verdict": "not run", "success": False, "false_ok": False, "covered": False}
    start = time.perf_counter()
    result = refine(T_init)
    seconds = time.perf_counter() - start
    rotation_deg, translation_m = _errors(result.T_cam_lidar, truth)
    init_deg, init_m = _errors(T_init, truth)
    within = rotation_deg <= SUCCESS_DEG and translation_m <= SUCCESS_M
    row = {
        "init_rotation_error_deg": init_deg,
        "init_translation_error_m": init_m,
        "rotation_error_deg": rotation_deg,
        "translation_error_m": translation_m,
        "verdict": result.verdict,
        "reasons": result.reasons,
        "rotation_std_deg": result.rotation_std_deg,
        "translation_std_m": result.translation_std_m,
        "interval_95": result.interval_95,
        # What the spread is made of, where the method says (the photo-consistency's jackknife and cost
        # tolerance): a coverage can be told for each.
        "std_parts": result.extra.get("std_parts"),
        "success": within,
        "false_ok": result.verdict == "ok" and not within,
        # A trial without an interval (axes kept from the guess: infinite spread) covers nothing.
        "covered": bool(
            rotation_deg <= result.interval_95 * result.rotation_std_deg
            and translation_m <= result.interval_95 * result.translation_std_m
        )
        if np.isfinite(result.rotation_std_deg) and np.isfinite(result.translation_std_m)
        else None,
        "seconds": seconds,
    }
    if (shift := result.extra.get("time_offset_shift")) is not None and truth_offset_s is not None:
        error_s = abs(shift["time_offset_s"] - truth_offset_s)
        row["time_offset_searched_error_ms"] = error_s * 1e3
        row["time_offset_searched_covered"] = bool(error_s <= shift["interval_95_s"])
    return row


def _guess_for(
    guess: Guess, truth: np.ndarray, seed: int, motion_start: np.ndarray | None
) -> np.ndarray | None:
    """The initial ``T_cam_lidar`` of one trial: the truth perturbed by ``guess`` (drawn from
    ``seed`` and the guess's size), or for no guess ``motion_start`` (None where there is none)."""
    if guess.degrees is None:
        return motion_start
    return perturbed(
        truth, guess, np.random.default_rng([seed, round(10 * guess.degrees), round(guess.centimetres)])
    )


def _session_rows(
    out: Path, preset: str, seed: int, duration_s: float, guesses: Sequence[Guess], log: Callable[[str], None]
) -> list[dict[str, Any]]:
    """The trials of one simulated session: its time offset once, then the extrinsic per guess."""
    from calib.session_calib import (
        calibrate_time,
        motion_guess,
        offset_error,
        session_extrinsic,
        session_lidar_map,
    )
    from calib.session_data import load_session
    from rig.calibration import load_calibration

    folder = _session(out, preset, seed, duration_s, log)
    truth = load_calibration(folder / "ground_truth" / "calib.yaml")
    data = load_session(folder / "session.mcap")
    start = time.perf_counter()
    time_result, motion = calibrate_time(data, data.camera)
    time_seconds = time.perf_counter() - start
    # What lts calibrate does: an offset that cannot vouch for itself is not applied.
    offset = time_result.time_offset_s if time_result.verdict == "ok" else 0.0
    session = {
        "source": preset,
        "seed": seed,
        "time_verdict": time_result.verdict,
        "time_reasons": time_result.reasons,
        "time_offset_error_ms": abs(time_result.time_offset_s - truth.time_offset_s) * 1e3
        if time_result.verdict == "ok"
        else None,
        "time_seconds": time_seconds,
    }
    start = time.perf_counter()
    lidar_map = session_lidar_map(data)  # once for all guesses
    session["map_seconds"] = time.perf_counter() - start

    def refine(T_init: np.ndarray) -> ExtrinsicResult:
        return session_extrinsic(
            data,
            data.camera,
            offset,
            motion,
            T_init,
            lidar_map=lidar_map,
            offset_error_s=offset_error(time_result, offset),
        )

    motion_start = motion_guess(time_result)
    rows = []
    for guess in guesses:
        T_init = _guess_for(guess, truth.T_cam_lidar, seed, motion_start)
        trial = _trial(refine, truth.T_cam_lidar, T_init, truth.time_offset_s)
        rows.append({**session, "guess": guess.label, **trial})
        log(_trial_line(rows[-1]))
    return rows


def _frame_rows(
    source: str,
    frames: Sequence[str],
    read: Callable[[str], tuple[ExtrinsicPair, CameraModel, np.ndarray]],
    guesses: Sequence[Guess],
    log: Callable[[str], None],
) -> list[dict[str, Any]]:
    """The trials of single real frames, each alone (no motion, so no trial without a guess):
    ``read(frame)`` gives a frame's image + cloud, its camera and the dataset's reference."""
    from calib.targetless import refine_extrinsic

    rows = []
    for index, name in enumerate(frames):
        pair, camera, truth = read(name)

        def refine(T_init: np.ndarray, pair=pair, camera=camera) -> ExtrinsicResult:
            return refine_extrinsic([pair], camera, T_init)

        for guess in guesses:
            trial = _trial(refine, truth, _guess_for(guess, truth, index, None))
            rows.append({"source": source, "seed": index, "frame": name, "guess": guess.label, **trial})
            log(_trial_line(rows[-1]))
    return rows


def _summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Medians, maxima and shares over the trials of one preset and guess."""
    ran = [r for r in rows if r["verdict"] != "not run"]
    bounded = [r for r in ran if r["covered"] is not None]

    def spread(key: str) -> dict[str, float | None]:
        values = [r[key] for r in ran]
        return {"median": float(np.median(values)), "max": float(np.max(values))} if ran else {}

    return {
        "trials": len(rows),
        "ran": len(ran),
        "rotation_error_deg": spread("rotation_error_deg"),
        "translation_error_m": spread("translation_error_m"),
        "success_rate": sum(r["success"] for r in rows) / len(rows),
        "ok": sum(r["verdict"] == "ok" for r in rows),
        "false_ok": sum(r["false_ok"] for r in rows),
        "coverage_95": sum(r["covered"] for r in bounded) / len(bounded) if bounded else None,
        "with_interval": len(bounded),
        "median_seconds": float(np.median([r["seconds"] for r in ran])) if ran else None,
    }


def bench_calib(
    presets: Sequence[str],
    seeds: Sequence[int],
    guesses: Sequence[Guess],
    duration_s: float,
    out: Path,
    log: Callable[[str], None],
    kitti_frames: Path | None = None,
    nuscenes_sample: Path | None = None,
    pjlab_pairs: Path | None = None,
) -> dict[str, Any]:
    """Run every preset × seed × guess, and every frame of ``kitti_frames``, camera of
    ``nuscenes_sample`` and pair of ``pjlab_pairs`` × guess (see the module docstring); returns the
    JSON table."""
    from calib.kitti_frames import kitti_frame_names, read_kitti_frame
    from calib.nuscenes_sample import nuscenes_camera_names, read_nuscenes_camera
    from calib.pjlab_pairs import pjlab_pair_names, read_pjlab_pair

    rows: list[dict[str, Any]] = []
    for preset in presets:
        for seed in seeds:
            rows += _session_rows(out, preset, seed, duration_s, guesses, log)
    sources = list(presets)
    if kitti_frames is not None:
        names = kitti_frame_names(kitti_frames)
        rows += _frame_rows(KITTI_SOURCE, names, lambda n: read_kitti_frame(kitti_frames, n), guesses, log)
        sources.append(KITTI_SOURCE)
    if nuscenes_sample is not None:
        names = nuscenes_camera_names(nuscenes_sample)
        rows += _frame_rows(
            NUSCENES_SOURCE, names, lambda n: read_nuscenes_camera(nuscenes_sample, n), guesses, log
        )
        sources.append(NUSCENES_SOURCE)
    if pjlab_pairs is not None:
        names = pjlab_pair_names(pjlab_pairs)
        rows += _frame_rows(PJLAB_SOURCE, names, lambda n: read_pjlab_pair(pjlab_pairs, n), guesses, log)
        sources.append(PJLAB_SOURCE)
    summary = {
        source: {
            g.label: _summary([r for r in rows if r["source"] == source and r["guess"] == g.label])
            for g in guesses
        }
        for source in sources
    }
    result = {
        "sources": sources,
        "seeds": list(seeds),
        "duration_s": duration_s,
        "success_bounds": {"rotation_deg": SUCCESS_DEG, "translation_m": SUCCESS_M},
        "summary": summary,
        "rows": rows,
        "plot": str(out / "bench_calib.png"),
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_calib.json").write_text(json.dumps(result, indent=2))
    _plot(rows, sources, guesses, out / "bench_calib.png")
    return result


def _trial_line(row: dict[str, Any]) -> str:
    where = f"frame {row['frame']}" if "frame" in row else f"seed {row['seed']}"
    head = f"  {row['source']} {where} guess {row['guess']}:"
    if row["verdict"] == "not run":
        why = (
            f"time offset {row['time_verdict']}" if "time_verdict" in row else "a single frame has no motion"
        )
        return f"{head} not run (no rough extrinsic from the motion: {why})"
    return (
        f"{head} {row['init_rotation_error_deg']:.2f}° {100 * row['init_translation_error_m']:.1f} cm → "
        f"{row['rotation_error_deg']:.2f}° {100 * row['translation_error_m']:.1f} cm, {row['verdict']}, "
        f"{row['seconds']:.1f} s"
    )


def _plot(rows: list[dict[str, Any]], sources: Sequence[str], guesses: Sequence[Guess], path: Path) -> None:
    """One panel per source (preset or KITTI frames): each trial's rotation against translation
    error (log axes), a colour per guess, filled where the verdict was ``ok``; dashed lines at the
    success bounds."""
    from lts.bench.figures import pyplot, save_figure

    plt = pyplot()
    fig, axes = plt.subplots(1, len(sources), figsize=(5 * len(sources), 4), dpi=120, squeeze=False)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, source in zip(axes[0], sources, strict=True):
        for colour, guess in zip(colours, guesses, strict=False):
            ran = [r for r in rows if r["source"] == source and r["guess"] == guess.label and "seconds" in r]
            for ok in (True, False):
                picked = [r for r in ran if (r["verdict"] == "ok") == ok]
                ax.scatter(
                    [max(r["rotation_error_deg"], 1e-3) for r in picked],
                    [max(100 * r["translation_error_m"], 1e-2) for r in picked],
                    facecolors=colour if ok else "none",
                    edgecolors=colour,
                    label=f"{guess.label} ({'ok' if ok else 'not ok'})" if picked else None,
                )
        ax.axvline(SUCCESS_DEG, color="#888", linestyle="--")
        ax.axhline(100 * SUCCESS_M, color="#888", linestyle="--")
        ax.set(
            xscale="log",
            yscale="log",
            xlabel="rotation error (°)",
            ylabel="translation error (cm)",
            title=source,
        )
        ax.legend(fontsize=7)
    save_figure(plt, fig, path)
