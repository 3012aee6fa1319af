"""Calibration boards: chessboard and ChArUco targets, and their detection in images.

Detection runs on a downscaled copy of the image (fast even with the exhaustive search) and the
corners are then refined with ``cv2.cornerSubPix`` at full resolution.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from rig.errors import InputError
from rig.image_io import read_image

#: Longest image side the chessboard detector works on before refining at full resolution.
DETECT_MAX_SIDE = 960
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
_SB_FLAGS = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY


@dataclass(frozen=True)
class ChessboardTarget:
    """A chessboard with ``cols`` × ``rows`` inner corners and squares of ``square_m`` metres."""

    cols: int
    rows: int
    square_m: float

    def object_points(self) -> np.ndarray:
        """Board-frame corners ``(rows * cols, 3)`` in OpenCV's row-major order, z = 0."""
        grid = np.mgrid[0 : self.cols, 0 : self.rows].T.reshape(-1, 2)
        return np.hstack([grid * self.square_m, np.zeros((len(grid), 1))]).astype(np.float32)


@dataclass(frozen=True)
class CharucoTarget:
    """A ChArUco board of ``squares_x`` × ``squares_y`` squares (OpenCV objdetect definition)."""

    squares_x: int
    squares_y: int
    square_m: float
    marker_m: float
    dictionary: str = "DICT_5X5_100"

    def board(self) -> cv2.aruco.CharucoBoard:
        """The OpenCV board object."""
        try:
            dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        except AttributeError:
            raise InputError(f"unknown ArUco dictionary {self.dictionary!r}", field="dictionary") from None
        return cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y), self.square_m, self.marker_m, dictionary
        )


@dataclass(eq=False)
class BoardView:
    """Board corners seen in one image.

    Attributes:
        name: where the view came from (an image path or a frame stamp).
        image_points: ``(N, 2)`` float32 pixel coordinates.
        object_points: ``(N, 3)`` float32 board-frame coordinates (metres, z = 0).
    """

    name: str
    image_points: np.ndarray
    object_points: np.ndarray


def to_gray(image: np.ndarray) -> np.ndarray:
    """A ``(H, W)`` uint8 grey image from a grey or BGR ``(H, W[, 3])`` image."""
    return image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


def _downscale(gray: np.ndarray) -> tuple[np.ndarray, float]:
    scale = min(1.0, DETECT_MAX_SIDE / max(gray.shape))
    if scale == 1.0:
        return gray, 1.0
    return cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA), scale


def _refine(gray: np.ndarray, corners_small: np.ndarray, scale: float, grid: tuple[int, int]) -> np.ndarray:
    """Map corners ``(N, 2)`` from the downscaled image to full resolution and refine them there."""
    corners = (corners_small.reshape(-1, 2) + 0.5) / scale - 0.5
    cols, rows = grid
    lattice = corners.reshape(rows, cols, 2)
    spacing = min(
        np.linalg.norm(np.diff(lattice, axis=1), axis=2).min(),
        np.linalg.norm(np.diff(lattice, axis=0), axis=2).min(),
    )
    half = int(np.clip(spacing * 0.3, 2, 15))
    refined = cv2.cornerSubPix(
        gray, corners.astype(np.float32).reshape(-1, 1, 2), (half, half), (-1, -1), _SUBPIX_CRITERIA
    )
    return refined.reshape(-1, 2)


def detect_chessboard(gray: np.ndarray, cols: int, rows: int) -> np.ndarray | None:
    """Inner corners ``(rows * cols, 2)`` float32 of a ``cols`` × ``rows`` chessboard, or None."""
    small, scale = _downscale(gray)
    found, corners = cv2.findChessboardCornersSB(small, (cols, rows), _SB_FLAGS)
    if not found:
        return None
    return _refine(gray, corners, scale, (cols, rows))


def find_chessboard_size(grays: Sequence[np.ndarray], min_side: int = 3) -> tuple[int, int]:
    """The ``(cols, rows)`` inner-corner count (``cols >= rows``) seen most often in the images.

    Uses the detector's "larger board" mode, which returns the whole board it finds around a
    small seed pattern. Raises :class:`InputError` if no image shows a board.
    """
    sizes: Counter[tuple[int, int]] = Counter()
    for gray in grays:
        small, _ = _downscale(gray)
        found, _, meta = cv2.findChessboardCornersSBWithMeta(
            small, (min_side, min_side), _SB_FLAGS | cv2.CALIB_CB_LARGER
        )
        if found and meta is not None:
            # The detector may return the grid either way round; a board fits both orders.
            rows, cols = sorted(int(v) for v in meta.shape)
            sizes[(cols, rows)] += 1
    if not sizes:
        raise InputError("no chessboard found in any image", field="images")
    return sizes.most_common(1)[0][0]


def detect_charuco(gray: np.ndarray, target: CharucoTarget, min_corners: int = 6) -> BoardView | None:
    """ChArUco corners in ``gray`` matched to the board (``name`` left empty), or None."""
    board = target.board()
    detector = cv2.aruco.CharucoDetector(board)
    corners, ids, _, _ = detector.detectBoard(gray)
    if corners is None or ids is None or len(ids) < min_corners:
        return None
    corners = cv2.cornerSubPix(gray, corners.astype(np.float32), (5, 5), (-1, -1), _SUBPIX_CRITERIA)
    obj, img = board.matchImagePoints(corners, ids)
    return BoardView("", img.reshape(-1, 2).astype(np.float32), obj.reshape(-1, 3).astype(np.float32))


def parse_grid(text: str, field: str) -> tuple[int, int]:
    """Parse ``"COLSxROWS"`` (e.g. ``"15x17"``) into two positive integers."""
    try:
        cols, rows = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"expected COLSxROWS like 9x6, got {text!r}", field=field) from None
    if cols < 2 or rows < 2:
        raise InputError(f"need at least 2x2, got {text!r}", field=field)
    return cols, rows


def read_gray(path: str | Path) -> np.ndarray:
    """Read an image file as ``(H, W)`` uint8 grey; raises :class:`InputError` naming the file."""
    return read_image(path, cv2.IMREAD_GRAYSCALE)


def detect_views(
    images: Sequence[tuple[str, np.ndarray]],
    target: ChessboardTarget | CharucoTarget | None = None,
    square_m: float = 1.0,
) -> tuple[list[BoardView], ChessboardTarget | CharucoTarget]:
    """Board views in named grey images ``[(name, (H, W))]``; images without a board are left out.

    With ``target=None`` the images show a chessboard whose size is searched
    (:func:`find_chessboard_size`) with squares of ``square_m``. Returns the views and the target.
    """
    if target is None:
        target = ChessboardTarget(*find_chessboard_size([g for _, g in images]), square_m)
    views = []
    for name, gray in images:
        if isinstance(target, ChessboardTarget):
            corners = detect_chessboard(gray, target.cols, target.rows)
            if corners is not None:
                views.append(BoardView(name, corners.astype(np.float32), target.object_points()))
        else:
            view = detect_charuco(gray, target)
            if view is not None:
                view.name = name
                views.append(view)
    return views, target
