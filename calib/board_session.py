"""Target-based extrinsic from a recorded session: the frames that show the chessboard, each
with the LiDAR points measured around it, into :func:`calib.target_based.calibrate_with_board`.

The robot (or the person holding the board) provides the poses; frames are searched for the
board at a stride, and every frame where it was found is a pose (spread evenly over them beyond
``MAX_BOARD_POSES``). At 30 fps the stride is 100 ms, a sweep of a 10 Hz LiDAR, so the poses'
point windows take each sweep that sees the board once. A board plane from one sweep's ~100–700
points is good to only ~0.3°: on the virtual rig's boards preset (5 runs, true time offset),
the ~135 poses found instead of 24 spread over them took the extrinsic from 0.07–0.14° /
1.4–5.9 mm to 0.03–0.05° / 0.9–1.5 mm. The camera's velocity relative to the (static) board,
from the board poses of the searched frames before and after, removes the motion within the
LiDAR window from the points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.boards import ChessboardTarget, parse_grid
from calib.session_data import SessionData, frame_clouds, frame_times
from calib.target_based import BoardObservation, calibrate_with_board, detect_board_pose
from calib.targetless import ExtrinsicResult
from rig.camera import CameraModel
from rig.errors import InputError

#: Every DETECT_STRIDE-th frame is searched for the board.
DETECT_STRIDE = 3
#: Board poses used at most, spread evenly over the frames where the board was found (bounds the
#: fit's time on long sessions; a 20 s pass of four boards finds ~140).
MAX_BOARD_POSES = 300


@dataclass(frozen=True)
class BoardGeometry:
    """A chessboard ``target`` and the half width and height (m) of its outline about the
    corners' centre."""

    target: ChessboardTarget
    half_size: tuple[float, float]


def board_geometry(board: str, square_m: float, outline_mm: str | None = None) -> BoardGeometry:
    """Board from the CLI's ``--board COLSxROWS``, ``--square M`` and ``--outline WxH`` (mm; default:
    one square beyond the outer corners on every side)."""
    if not square_m > 0:
        raise InputError(f"must be positive, got {square_m}", field="--square")
    target = ChessboardTarget(*parse_grid(board, "--board"), square_m)
    if outline_mm is None:
        return BoardGeometry(target, ((target.cols + 1) * square_m / 2, (target.rows + 1) * square_m / 2))
    width_mm, height_mm = parse_grid(outline_mm, "--outline")
    return BoardGeometry(target, (width_mm / 2000, height_mm / 2000))


def camera_velocity(found: dict[int, np.ndarray], times: np.ndarray, index: int) -> np.ndarray | None:
    """The camera's linear velocity ``(3,)`` (m/s, camera frame) at frame ``index``, from the
    static board's poses ``found`` (``T_cam_board`` ``(4, 4)`` by frame index) in the searched
    frames ``DETECT_STRIDE`` before and after (one side when the other misses the board); None
    when neither shows it. ``times`` ``(F,)`` are the frames' times (s)."""
    T_cam_board = found[index]
    near = [j for j in (index - DETECT_STRIDE, index, index + DETECT_STRIDE) if j in found]
    if len(near) < 2:
        return None
    first, last = near[0], near[-1]

    def centre(T: np.ndarray) -> np.ndarray:
        """Camera centre in the board frame; a board numbered the other way round (180° about
        its normal, the same centre) is turned back to agree with this frame's numbering."""
        R = T[:3, :3]
        if np.trace(T_cam_board[:3, :3].T @ R) < 1.0:  # turned by more than 90°
            R = R @ np.diag([-1.0, -1.0, 1.0])
        return -R.T @ T[:3, 3]

    velocity_board = (centre(found[last]) - centre(found[first])) / (times[last] - times[first])
    return T_cam_board[:3, :3] @ velocity_board


def board_frames(data: SessionData, camera: CameraModel, target: ChessboardTarget) -> dict[int, np.ndarray]:
    """``T_cam_board`` ``(4, 4)`` by frame index of every ``DETECT_STRIDE``-th frame that shows
    the board."""
    found = {}
    for index in range(0, len(data.frames), DETECT_STRIDE):
        pose = detect_board_pose(data.frames[index].image, camera, target, f"frame {index}")
        if pose is not None:
            found[index] = pose
    return found


def calibrate_board_session(
    data: SessionData,
    camera: CameraModel,
    board: BoardGeometry,
    time_offset_s: float,
    T_init: np.ndarray,
) -> ExtrinsicResult:
    """``T_cam_lidar`` from the board poses of a session; ``T_init`` (a rough guess, a few degrees
    and centimetres) says where to look for the board in each LiDAR cloud."""
    if not data.scans:
        raise InputError(
            f"no LiDAR scans on {data.topics.points or 'any topic'}", path=data.path, field="topics"
        )
    found = board_frames(data, camera, board.target)
    indices = sorted(found)
    if len(indices) > MAX_BOARD_POSES:
        indices = [indices[k] for k in np.linspace(0, len(indices) - 1, MAX_BOARD_POSES).round().astype(int)]
    times = frame_times(data)
    poses, velocities = [], []
    for index in indices:
        velocity = camera_velocity(found, times, index)
        if velocity is not None:
            poses.append((index, found[index]))
            # The LiDAR's velocity in its own frame (its lever arm's share, ω × ~0.1 m, is left).
            velocities.append(T_init[:3, :3].T @ velocity)
    clouds = frame_clouds(data, [index for index, _ in poses], time_offset_s, velocities)
    observations = [
        BoardObservation(T_cam_board, cloud, f"frame {index}")
        for (index, T_cam_board), cloud in zip(poses, clouds, strict=True)
        if cloud is not None
    ]
    result = calibrate_with_board(observations, board.half_size, T_init)
    result.extra["frames_with_board"] = len(poses)
    return result
