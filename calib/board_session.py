"""Target-based extrinsic from a recorded session: the frames that show the chessboard, each
with the LiDAR points measured around it, into :func:`calib.target_based.calibrate_with_board`.

The robot (or the person holding the board) provides the poses; frames are searched for the
board at a stride and the poses used are spread evenly over the frames where it was found. The
camera's velocity relative to the (static) board, from the board poses of nearby frames, removes
the motion within the LiDAR window from the points.
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
#: Board poses used at most, spread evenly over the frames where the board was found.
MAX_BOARD_POSES = 24
#: The board poses this many frames before and after a board frame give the camera's velocity.
VELOCITY_FRAMES = 2


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


def _pose_at(
    data: SessionData, camera: CameraModel, target: ChessboardTarget, index: int
) -> np.ndarray | None:
    """``T_cam_board`` ``(4, 4)`` in frame ``index``, or None when the board is not found there."""
    return detect_board_pose(data.frames[index].image, camera, target, f"frame {index}")


def camera_velocity(
    data: SessionData, camera: CameraModel, target: ChessboardTarget, index: int, T_cam_board: np.ndarray
) -> np.ndarray | None:
    """The camera's linear velocity ``(3,)`` (m/s, camera frame) at frame ``index``, from the
    static board's poses ``VELOCITY_FRAMES`` frames before and after (one side when the other
    misses the board); None when neither shows it."""
    times = frame_times(data)
    found = {index: T_cam_board}
    for j in (index - VELOCITY_FRAMES, index + VELOCITY_FRAMES):
        pose = _pose_at(data, camera, target, j) if 0 <= j < len(data.frames) else None
        if pose is not None:
            found[j] = pose
    if len(found) < 2:
        return None
    first, last = min(found), max(found)

    def centre(T: np.ndarray) -> np.ndarray:
        """Camera centre in the board frame; a board numbered the other way round (180° about
        its normal, the same centre) is turned back to agree with this frame's numbering."""
        R = T[:3, :3]
        if np.trace(T_cam_board[:3, :3].T @ R) < 1.0:  # turned by more than 90°
            R = R @ np.diag([-1.0, -1.0, 1.0])
        return -R.T @ T[:3, 3]

    velocity_board = (centre(found[last]) - centre(found[first])) / (times[last] - times[first])
    return T_cam_board[:3, :3] @ velocity_board


def board_frames(
    data: SessionData, camera: CameraModel, target: ChessboardTarget
) -> list[tuple[int, np.ndarray]]:
    """``(frame index, T_cam_board (4, 4))`` of up to ``MAX_BOARD_POSES`` frames showing the board,
    spread evenly over those where it was found."""
    found = []
    for index in range(0, len(data.frames), DETECT_STRIDE):
        pose = _pose_at(data, camera, target, index)
        if pose is not None:
            found.append((index, pose))
    if len(found) > MAX_BOARD_POSES:
        keep = np.linspace(0, len(found) - 1, MAX_BOARD_POSES).round().astype(int)
        found = [found[k] for k in keep]
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
        raise InputError(f"no LiDAR scans on {data.topics['points']}", path=data.path, field="topics")
    poses, velocities = [], []
    for index, T_cam_board in board_frames(data, camera, board.target):
        velocity = camera_velocity(data, camera, board.target, index, T_cam_board)
        if velocity is not None:
            poses.append((index, T_cam_board))
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
