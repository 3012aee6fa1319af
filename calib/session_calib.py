"""Calibrate from a recorded session: time offset from motion, then the extrinsic — from a
chessboard seen in the session (target-based) or refined from a rough guess (targetless: the
photo-consistency of the recording's LiDAR map over many frames, :mod:`calib.photo_consistency`).

The camera model comes from the session's CameraInfo (or the initial calibration). The LiDAR
motion signal is the gyro of the IMU on the LiDAR's clock when the session has one (Livox,
Ouster and the virtual rig carry it in the LiDAR), otherwise KISS-ICP odometry.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from calib.board_session import BoardGeometry, calibrate_board_session
from calib.lidar_map import LidarMap, build_lidar_map
from calib.motion import (
    LONG_PAIR_SPAN_S,
    PAIR_SPAN_S,
    camera_angular_velocity,
    imu_angular_velocity,
    lidar_angular_velocity,
)
from calib.photo_consistency import (
    MAX_ROT_STD_DEG,
    MAX_TRANS_STD_M,
    ConsistencyFrame,
    photo_consistency_extrinsic,
)
from calib.session_data import SessionData, frame_clouds, frame_times, load_session
from calib.targetless import ExtrinsicPair, ExtrinsicResult, refine_extrinsic
from calib.time_offset import MAX_OFFSET_S, TimeOffsetResult, estimate_time_offset
from rig.calibration import Calibration
from rig.camera import CameraModel
from rig.errors import InputError
from rig.session import DEFAULT_TOPICS, Recording, as_recording
from rig.session.tf_static import tf_extrinsic
from rig.trajectory import Trajectory

#: Image + LiDAR pairs of the one-pair-at-a-time targetless extrinsic (a recording too short for a
#: LiDAR map), and the frames of the photo-consistency one.
EXTRINSIC_PAIRS = 6
CONSISTENCY_FRAMES = 20
LIDAR_MOTION = ("auto", "imu", "odometry")
#: Half-width of the interval (seconds) over which the LiDAR's speed at a frame is measured.
SPEED_WINDOW_S = 0.05
#: The photo-consistency searches the time offset too where the motion leaves it at most this
#: far off (s; :func:`offset_error`): 29 ms on the hand-held office whose motion refused the
#: offset (the search then used 0 s, the truth 15 ms). Past it (no estimate at all: the whole
#: ±0.5 s) the offset is taken as used and its doubt stays.
RETIME_REACH_S = 0.05
#: ... and only where that doubt could move the fastest frame by more than this (degrees,
#: metres: the accuracy aimed at). On the virtual room (turning at most about 20°/s, its doubt
#: 0.03-0.08°) searching it anyway doubled a trial's time and moved the medians by at most
#: 0.02° and 0.5 cm, some up and some down.
RETIME_ABOVE = (0.1, 0.01)


def calibrate_time(
    data: SessionData, camera: CameraModel, lidar_motion: str = "auto"
) -> tuple[TimeOffsetResult, tuple[np.ndarray, np.ndarray]]:
    """Camera–LiDAR time offset of a session (see :mod:`calib.time_offset`), and the camera's
    angular speed signal (times ``(K,)`` s, speeds ``(K,)`` rad/s) it came from."""
    if lidar_motion not in LIDAR_MOTION:
        raise InputError(f"unknown {lidar_motion!r}; expected one of {LIDAR_MOTION}", field="lidar_motion")
    use_imu = lidar_motion == "imu" or (lidar_motion == "auto" and len(data.imu) > 0)
    if use_imu and not data.imu:
        raise InputError(
            f"no IMU samples on {data.topics.imu or DEFAULT_TOPICS['imu']}", path=data.path, field="topics"
        )
    if not use_imu and not data.scans:
        raise InputError(
            f"no LiDAR scans on {data.topics.points or 'any topic'}", path=data.path, field="topics"
        )
    t_lid, w_lid = imu_angular_velocity(data.imu) if use_imu else lidar_angular_velocity(data.scans)
    # Two baselines for the camera's motion (frames ~1/15 s and ~1/6 s apart); the fit whose
    # offset varies least between blocks of the recording is kept. On the hand-held virtual office
    # (10 s, seeds 0-2, true 15 ms) the short one gave -1.2 to 8.3 ms (+-8.7-17.9 ms, refused), the
    # long one 9.3-14.8 ms (+-3.2-4.6, ok); on the boards preset the long one tracks chessboard
    # corners across the wrong squares and gave 183 ms (+-2.7, correlation 0.53), the short one
    # 14.6 ms (+-1.9).
    spans = (PAIR_SPAN_S, LONG_PAIR_SPAN_S)
    signals = camera_angular_velocity(data.frames, camera, spans)
    fits = [
        (estimate_time_offset(t_cam, w_cam, t_lid, w_lid), t_cam, w_cam, span_s)
        for span_s, (t_cam, w_cam) in zip(spans, signals, strict=True)
    ]
    result, t_cam, w_cam, span_s = min(fits, key=lambda fit: (fit[0].std_s, fit[3]))
    result.extra["lidar_motion"] = "imu gyro" if use_imu else "KISS-ICP odometry"
    result.extra["camera_pair_span_s"] = span_s
    return result, (t_cam, np.linalg.norm(w_cam, axis=1))


def calm_frames(
    data: SessionData, motion: tuple[np.ndarray, np.ndarray] | None = None, count: int = EXTRINSIC_PAIRS
) -> list[int]:
    """Indices of ``count`` frames spread over the session: the middle of each stretch, or with the
    camera's angular speed ``motion`` (times, speeds) the calmest frame of its middle half. (The
    calmest of a whole stretch bunched up at the stretches' ends, 2 and 4 frames apart, and cost
    the virtual room's photo-consistency extrinsic 0.31° against 0.15° median.)"""
    frame_t = frame_times(data)
    chosen = []
    for stretch in np.array_split(np.arange(len(frame_t)), count + 2)[1:-1]:
        if not len(stretch):
            continue
        index = int(stretch[len(stretch) // 2])
        if motion is not None and len(motion[0]):
            quarter = len(stretch) // 4
            middle = stretch[quarter : len(stretch) - quarter]
            speed = np.interp(frame_t[middle], motion[0], motion[1])
            index = int(middle[np.argmin(speed)])
        chosen.append(index)
    return chosen


def extrinsic_pairs(
    data: SessionData, time_offset_s: float, motion: tuple[np.ndarray, np.ndarray] | None = None
) -> list[ExtrinsicPair]:
    """Image + LiDAR pairs at :func:`calm_frames` (clouds from :func:`frame_clouds`)."""
    indices = calm_frames(data, motion)
    clouds = frame_clouds(data, indices, time_offset_s)
    return [
        ExtrinsicPair(data.frames[i].image, cloud)
        for i, cloud in zip(indices, clouds, strict=True)
        if cloud is not None
    ]


#: Where a rough extrinsic found from the recording alone comes from (``extrinsic_init``).
MOTION_GUESS = (
    "the motion (no guess given: the rotation between the camera's and the LiDAR's angular "
    "velocities, translation 0)"
)


def motion_guess(time_result: TimeOffsetResult) -> np.ndarray | None:
    """A rough ``T_cam_lidar`` ``(4, 4)`` from the recording alone: the rotation that maps the
    LiDAR's angular velocity onto the camera's (fitted with the time offset, hand-eye on rates)
    and a zero translation (one rig's sensors sit within decimetres of each other). None when the
    rates do not fit (too little rotation, a weak correlation: the rotation then means nothing),
    or the offset is too unsure for the extrinsic's search to pin it (:data:`RETIME_REACH_S`).
    """
    rotation = time_result.extra.get("R_cam_lidar_from_motion")
    if rotation is None or offset_error(time_result, time_result.time_offset_s) > RETIME_REACH_S:
        return None
    T = np.eye(4)
    T[:3, :3] = np.asarray(rotation, dtype=np.float64)
    return T


def session_lidar_map(data: SessionData) -> LidarMap | None:
    """The recording's LiDAR map (:func:`calib.lidar_map.build_lidar_map`), or None when it has
    fewer than two usable sweeps."""
    try:
        return build_lidar_map(data.scans)
    except InputError:
        return None


def consistency_frames(
    data: SessionData, lidar_map: LidarMap, time_offset_s: float, indices: Sequence[int]
) -> list[ConsistencyFrame]:
    """The frames ``indices`` (:func:`calm_frames`) within the map's trajectory, each with the
    LiDAR's pose when it was taken (camera stamps moved onto the LiDAR clock by the offset) and
    the moving things measured then (:meth:`~calib.lidar_map.LidarMap.moving_near`)."""
    t_ns = np.round((frame_times(data)[indices] - time_offset_s) * 1e9).astype(np.int64)
    covered = lidar_map.trajectory.covers(t_ns)
    poses = lidar_map.trajectory.interpolate(t_ns[covered]) if covered.any() else np.zeros((0, 4, 4))
    return [
        ConsistencyFrame(data.frames[i].image, pose, lidar_map.moving_near(int(t)), int(t))
        for i, t, pose in zip(np.asarray(indices)[covered], t_ns[covered], poses, strict=True)
    ]


def offset_error(time_result: TimeOffsetResult, time_offset_s: float) -> float:
    """How far (s) the time offset ``time_offset_s`` a step uses may lie from the truth: its
    distance from the estimate plus the estimate's 95 % interval (``interval_95`` σ); the whole search range
    (:data:`~calib.time_offset.MAX_OFFSET_S`) when the motion gave no estimate."""
    if not (np.isfinite(time_result.time_offset_s) and np.isfinite(time_result.std_s)):
        return MAX_OFFSET_S
    reach = time_result.interval_95 * time_result.std_s
    return min(abs(time_result.time_offset_s - time_offset_s) + reach, MAX_OFFSET_S)


def timing_drift(
    frame_t: np.ndarray,
    trajectory: Trajectory,
    motion: tuple[np.ndarray, np.ndarray] | None,
    time_offset_s: float,
    error_s: float,
) -> tuple[float, float, float, float]:
    """How far the frames taken at ``frame_t`` ``(K,)`` (camera clock, s) may be from where the
    time offset ``time_offset_s`` places them when it is ``error_s`` off: the fastest frame's turn
    (degrees: its angular speed from ``motion``, camera times and rad/s, × ``error_s``) and move
    (metres: its speed along the LiDAR's ``trajectory`` × ``error_s``); then that angular speed
    (degrees/s) and speed (m/s)."""
    turn = np.interp(frame_t, motion[0], motion[1]) if motion is not None and len(motion[0]) else np.zeros(1)
    t_ns = np.round((frame_t - time_offset_s) * 1e9).astype(np.int64)
    step = round(SPEED_WINDOW_S * 1e9)
    ends = [trajectory.interpolate(t_ns + side, clamp=True)[:, :3, 3] for side in (-step, step)]
    speed = float((np.linalg.norm(ends[1] - ends[0], axis=1) / (2 * SPEED_WINDOW_S)).max())
    turn_deg = float(np.degrees(turn.max()))
    return turn_deg * error_s, speed * error_s, turn_deg, speed


def timing_reasons(
    frame_t: np.ndarray,
    trajectory: Trajectory,
    motion: tuple[np.ndarray, np.ndarray] | None,
    time_offset_s: float,
    error_s: float,
) -> list[str]:
    """Why an extrinsic over frames taken at ``frame_t`` ``(K,)`` (camera clock, s) cannot vouch
    for itself when the time offset it used may be ``error_s`` off (:func:`timing_drift`): past
    the extrinsic's own limits the frames' LiDAR poses are wrong by more than the result may be,
    in a way its jackknife over frames cannot see (they all share the offset)."""
    drift = timing_drift(frame_t, trajectory, motion, time_offset_s, error_s)
    rotation_deg, translation_m, turn, speed = drift
    if rotation_deg <= MAX_ROT_STD_DEG and translation_m <= MAX_TRANS_STD_M:
        return []
    return [
        f"the time offset used ({time_offset_s * 1e3:.1f} ms) may be {error_s * 1e3:.0f} ms off: the "
        f"fastest frame (turning {turn:.0f}°/s, moving {speed:.2f} m/s) would "
        f"then be {rotation_deg:.2f}° and {translation_m * 100:.1f} cm from where it was taken (limits "
        f"{MAX_ROT_STD_DEG}° / {MAX_TRANS_STD_M * 100:.1f} cm); record turns that speed up and slow "
        "down to pin the offset, or give it with --init"
    ]


def session_extrinsic(
    data: SessionData,
    camera: CameraModel,
    time_offset_s: float,
    motion: tuple[np.ndarray, np.ndarray] | None,
    T_init: np.ndarray,
    board: BoardGeometry | None = None,
    lidar_map: LidarMap | None = None,
    offset_error_s: float = 0.0,
    search_straight: bool = True,
    threads: int = 1,
) -> ExtrinsicResult:
    """The extrinsic step of :func:`calibrate_session`: from the chessboard ``board`` when given,
    else targetless from the rough ``T_init`` ``(4, 4)``: photo-consistency of the recording's
    LiDAR map over many frames (``lidar_map``, built here when not given), or one image + LiDAR
    pair at a time (:func:`extrinsic_pairs`) when the recording has no map. ``offset_error_s``
    (:func:`offset_error`) bounds how far ``time_offset_s`` may be off; a photo-consistency result
    whose frames it would move too far is ``poorly constrained`` (:func:`timing_reasons`).
    ``search_straight``, ``threads``: as in
    :func:`~calib.photo_consistency.photo_consistency_extrinsic`."""
    if board is not None:
        return calibrate_board_session(data, camera, board, time_offset_s, T_init)
    lidar_map = lidar_map or session_lidar_map(data)
    if lidar_map is None:
        return refine_extrinsic(extrinsic_pairs(data, time_offset_s, motion), camera, T_init)
    indices = calm_frames(data, motion, CONSISTENCY_FRAMES)
    frames = consistency_frames(data, lidar_map, time_offset_s, indices)
    frame_t = frame_times(data)[indices]
    drift = timing_drift(frame_t, lidar_map.trajectory, motion, time_offset_s, offset_error_s)
    matters = drift[0] > RETIME_ABOVE[0] or drift[1] > RETIME_ABOVE[1]
    reach = offset_error_s if matters and offset_error_s <= RETIME_REACH_S else 0.0
    result = photo_consistency_extrinsic(frames, camera, lidar_map, T_init, search_straight, reach, threads)
    if (shift := result.extra.get("time_offset_shift")) is not None:
        shift["time_offset_s"] = time_offset_s + shift["shift_s"]
        if not shift["at_reach"]:  # else the offset may lie past the window: its doubt stays
            time_offset_s, offset_error_s = shift["time_offset_s"], shift["interval_95_s"]
    if doubts := timing_reasons(frame_t, lidar_map.trajectory, motion, time_offset_s, offset_error_s):
        result.reasons += doubts
        result.verdict = "poorly constrained"
    return result


def calibrate_session(
    path: Recording | str | Path,
    init: Calibration | None = None,
    lidar_motion: str = "auto",
    topics: dict[str, str] | None = None,
    board: BoardGeometry | None = None,
    progress: Callable[[str], None] | None = None,
    search_straight: bool = True,
    threads: int = 1,
) -> tuple[Calibration, dict[str, Any]]:
    """Everything a recording supports: camera model, time offset and the extrinsic — from the
    chessboard ``board`` when given, else targetless — starting at a rough ``T_cam_lidar``:
    ``init``'s (unless it holds the camera alone), else the recording's ``/tf_static`` one, else
    :func:`motion_guess`. A time offset or extrinsic whose verdict is not ``ok`` is reported but
    not applied (the calibration keeps the rough one). ``progress`` is told each step as it
    starts. ``search_straight`` False skips the targetless search of a straight drive, whose
    result is never applied (what a reconstruction needs; the search's four axes are a diagnosis
    for ``lts calibrate``). ``threads``: the targetless search's (the same result with any number;
    one where another process keeps the cores busy). Returns the calibration and a report
    (``extrinsic_init`` says where the rough extrinsic came from, ``init_holds`` what ``init``
    gave when not the extrinsic)."""
    recording = as_recording(path)
    data = load_session(recording, topics)
    camera = data.camera or (init.camera if init is not None else None)
    if camera is None:
        raise InputError(
            "the session has no CameraInfo and no --init calibration was given",
            path=data.path,
            field="camera_info",
        )
    report: dict[str, Any] = {"camera_source": "session CameraInfo" if data.camera else "initial calibration"}
    # The rough extrinsic: init's, unless it holds the camera alone (lts calibrate intrinsics).
    guess = init if init is not None and init.has_extrinsic else None
    if init is not None and guess is None:
        report["init_holds"] = "the camera alone (no T_cam_lidar)"
    if guess is None and (tf := tf_extrinsic(recording, data.topics)) is not None:
        guess = Calibration(camera, tf.T_cam_lidar)
        report["extrinsic_init"] = tf.describe()
    elif guess is not None:
        report["extrinsic_init"] = "--init"
    if board is not None and guess is None:
        raise InputError(
            "the board method needs a rough T_cam_lidar (--init) to find the board in the LiDAR clouds",
            path=data.path,
            field="--init",
        )
    calibration = Calibration(
        camera, guess.T_cam_lidar.copy() if guess else np.eye(4), init.time_offset_s if init else 0.0,
        has_extrinsic=guess is not None,
    )  # fmt: skip

    tell = progress or (lambda step: None)
    tell("time offset from the motion")
    time_result, motion = calibrate_time(data, camera, lidar_motion)
    report["time"] = time_result.to_json()
    report["time"]["applied"] = time_result.verdict == "ok"
    if time_result.verdict == "ok":
        calibration.time_offset_s = time_result.time_offset_s

    T_init = guess.T_cam_lidar if guess is not None else motion_guess(time_result)
    if T_init is None:
        report["extrinsic"] = {
            "verdict": "not run",
            "reasons": [
                "no rough T_cam_lidar: give --init (or a bag with /tf_static), or record with "
                "enough rotation for the motion to give one (the camera's and the LiDAR's angular "
                "velocities above did not fit, or left the time offset too unsure)"
            ],
        }
    else:
        if guess is None:
            report["extrinsic_init"] = MOTION_GUESS
            calibration.T_cam_lidar, calibration.has_extrinsic = T_init.copy(), True
        tell(
            "extrinsic from the board"
            if board is not None
            else f"extrinsic: LiDAR map, then photo-consistency over {CONSISTENCY_FRAMES} frames (~1 min)"
        )
        # An offset given with --init is taken as given; one estimated here is as good as its interval.
        trusted = (init is not None or guess is not None) and time_result.verdict != "ok"
        offset_doubt = 0.0 if trusted else offset_error(time_result, calibration.time_offset_s)
        result = session_extrinsic(
            data, camera, calibration.time_offset_s, motion, T_init, board,
            offset_error_s=offset_doubt, search_straight=search_straight, threads=threads,
        )  # fmt: skip
        report["extrinsic"] = result.to_json()
        # As with the time offset: a result that cannot vouch for itself does not replace the
        # guess (a refinement drifting away from a good start is what users of other tools meet).
        report["extrinsic"]["applied"] = result.verdict == "ok"
        if result.verdict == "ok":
            calibration.T_cam_lidar = result.T_cam_lidar
        if (searched := result.extra.get("time_offset_shift")) is not None:
            # An ok extrinsic vouches for the offset its frames were placed with.
            applied = result.verdict == "ok" and not searched["at_reach"]
            report["time"]["with_the_extrinsic"] = {
                "time_offset_s": searched["time_offset_s"],
                "interval_95_s": searched["interval_95_s"],
                "at_reach": searched["at_reach"],
                "applied": applied,
            }
            if applied:
                calibration.time_offset_s = searched["time_offset_s"]
    calibration.quality = {"time": report["time"], "extrinsic": report["extrinsic"]}
    return calibration, report


def _interval_text(block: dict[str, Any]) -> str:
    """`` ±… (95 %)`` for a report step's estimate where it gives a finite interval: the time
    offset's in milliseconds, the extrinsic's in degrees and centimetres."""

    def finite(key: str) -> bool:
        return isinstance(block.get(key), float | int) and math.isfinite(block[key])

    if finite("interval_95_s"):
        return f" ±{block['interval_95_s'] * 1e3:.1f} ms (95 %)"
    if finite("rotation_interval_95_deg") and finite("translation_interval_95_m"):
        rotation, translation = block["rotation_interval_95_deg"], block["translation_interval_95_m"]
        return f" ±{rotation:.2f}° ±{translation * 100:.1f} cm (95 %)"
    return ""


def report_lines(report: dict[str, Any]) -> list[str]:
    """One line per step of a :func:`calibrate_session` report: its verdict, the reasons, and
    whether the result was applied; after them, where the rough extrinsic came from."""
    lines = []
    given = report.get("extrinsic_init")  # "--init", a /tf_static description, the motion, or absent
    for step in ("time", "extrinsic"):
        block = report[step]
        searched = block.get("with_the_extrinsic", {})
        if step == "extrinsic":
            kept = f"the value from {given} is kept"
        elif searched.get("applied"):
            kept = "the offset searched with the extrinsic is used"
        else:
            kept = ("the value from --init" if given == "--init" else "0 s") + " is kept"
        lines.append(
            f"{step}: {block['verdict']}"
            + _interval_text(block)
            + ("" if not block["reasons"] else " (" + "; ".join(block["reasons"]) + ")")
            + (f" — not applied, {kept}" if block.get("applied") is False else "")
        )
        if searched:
            lines.append(
                f"time offset searched with the extrinsic: {searched['time_offset_s'] * 1e3:.1f} ms"
                + _interval_text(searched)
                + (
                    " — applied"
                    if searched["applied"]
                    else " — not applied (at the edge of the window searched: it may lie past it)"
                    if searched["at_reach"]
                    else " — not applied (the extrinsic is not ok)"
                )
            )
    if "init_holds" in report:
        lines.append(f"--init: {report['init_holds']}")
    if given is not None:
        lines.append(f"rough extrinsic: {given}")
    return lines
