"""Camera intrinsics from board views: pinhole or fisheye, with outlier views rejected.

The result carries the residuals that justify it (overall and per-view RMS, rejected views, how
much of the image the corners cover) and a verdict, so a weak calibration says so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from calib.boards import BoardView
from rig.camera import CameraKind, CameraModel
from rig.errors import InputError

#: Views needed for a usable calibration (a single planar view cannot separate focal and pose).
MIN_VIEWS = 3
#: A view is rejected when its RMS exceeds this multiple of the median view RMS (and the floor).
OUTLIER_FACTOR = 3.0
OUTLIER_FLOOR_PX = 0.5
#: The image is split into COVERAGE_GRID × COVERAGE_GRID cells; coverage = fraction holding corners.
COVERAGE_GRID = 5
MIN_COVERAGE = 0.5
MAX_OK_RMS_PX = 1.0
_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-9)


@dataclass(eq=False)
class IntrinsicsResult:
    """A calibrated camera and the residuals behind it."""

    camera: CameraModel
    rms_px: float
    per_view_rms_px: dict[str, float]
    views_used: list[str]
    views_rejected: list[str]
    coverage: float
    verdict: str
    reasons: list[str] = field(default_factory=list)

    def quality(self) -> dict[str, Any]:
        """The ``quality:`` block of ``calib.yaml`` for the intrinsics."""
        return {
            "intrinsics": {
                "rms_px": self.rms_px,
                "views_used": len(self.views_used),
                "views_rejected": self.views_rejected,
                "per_view_rms_px": self.per_view_rms_px,
                "coverage": self.coverage,
                "verdict": self.verdict,
                "reasons": self.reasons,
            }
        }

    def to_json(self) -> dict[str, Any]:
        """The fields ``lts calibrate intrinsics --json`` prints."""
        return {
            "rms_px": self.rms_px,
            "K": self.camera.K.tolist(),
            "dist": self.camera.dist.tolist(),
            "model": self.camera.model,
            "width": self.camera.width,
            "height": self.camera.height,
            "views_used": self.views_used,
            "views_rejected": self.views_rejected,
            "per_view_rms_px": self.per_view_rms_px,
            "coverage": self.coverage,
            "verdict": self.verdict,
            "reasons": self.reasons,
        }


def coverage_fraction(views: Sequence[BoardView], width: int, height: int) -> float:
    """Fraction of a COVERAGE_GRID² grid of image cells that hold at least one corner."""
    pts = np.concatenate([v.image_points for v in views]).reshape(-1, 2)
    cx = np.clip((pts[:, 0] / width * COVERAGE_GRID).astype(int), 0, COVERAGE_GRID - 1)
    cy = np.clip((pts[:, 1] / height * COVERAGE_GRID).astype(int), 0, COVERAGE_GRID - 1)
    return len(set(zip(cx.tolist(), cy.tolist(), strict=True))) / COVERAGE_GRID**2


def _fit(
    views: Sequence[BoardView], size: tuple[int, int], model: CameraKind
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fit one model; returns ``K (3, 3)``, ``dist (k,)`` and per-view RMS ``(V,)`` in pixels."""
    # OpenCV 5's fisheye solver wants (1, N, C) arrays; the pinhole one takes them too.
    obj = [v.object_points.reshape(1, -1, 3).astype(np.float64) for v in views]
    img = [v.image_points.reshape(1, -1, 2).astype(np.float64) for v in views]
    if model == "fisheye":
        flags = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
        _, K, dist, rvecs, tvecs = cv2.fisheye.calibrate(
            obj, img, size, None, None, flags=flags, criteria=_CRITERIA
        )
        errors = []
        for o, i, r, t in zip(obj, img, rvecs, tvecs, strict=True):
            proj, _ = cv2.fisheye.projectPoints(o, r, t, K, dist)
            errors.append(np.sqrt(np.mean(np.sum((proj - i) ** 2, axis=-1))))
        return K, dist.reshape(-1), np.asarray(errors)
    obj32 = [o.astype(np.float32) for o in obj]
    img32 = [i.astype(np.float32) for i in img]
    _, K, dist, _, _, _, _, per_view = cv2.calibrateCameraExtended(
        obj32, img32, size, None, None, criteria=_CRITERIA
    )
    return K, dist.reshape(-1), per_view.reshape(-1)


def calibrate_intrinsics(
    views: Sequence[BoardView], width: int, height: int, model: CameraKind = "pinhole"
) -> IntrinsicsResult:
    """Calibrate a camera of ``width`` × ``height`` pixels from board views.

    Fits, rejects views whose RMS exceeds ``OUTLIER_FACTOR`` × the median (and
    ``OUTLIER_FLOOR_PX``), and refits until no view is rejected. Raises :class:`InputError` with
    fewer than 1 usable view; fewer than ``MIN_VIEWS`` gives a ``poorly constrained`` verdict.
    """
    if model not in ("pinhole", "fisheye"):
        raise InputError(f"unknown model {model!r}; expected pinhole or fisheye", field="model")
    used = [v for v in views if len(v.image_points) >= 6]
    if not used:
        raise InputError("no image shows the board", field="images")
    rejected: list[str] = []
    while True:
        K, dist, errors = _fit(used, (width, height), model)
        limit = max(OUTLIER_FACTOR * float(np.median(errors)), OUTLIER_FLOOR_PX)
        worst = int(np.argmax(errors))
        if errors[worst] <= limit or len(used) <= MIN_VIEWS:
            break
        rejected.append(used[worst].name)
        used = [v for i, v in enumerate(used) if i != worst]
    n_points = np.array([len(v.image_points) for v in used])
    rms = float(np.sqrt(np.sum(errors**2 * n_points) / n_points.sum()))
    coverage = coverage_fraction(used, width, height)
    reasons = []
    if len(used) < MIN_VIEWS:
        reasons.append(f"only {len(used)} board view(s); need at least {MIN_VIEWS} distinct poses")
    if coverage < MIN_COVERAGE:
        reasons.append(
            f"corners cover {coverage:.0%} of the image (want >= {MIN_COVERAGE:.0%}); "
            "move the board to the edges"
        )
    if rms > MAX_OK_RMS_PX:
        reasons.append(f"reprojection RMS {rms:.2f} px > {MAX_OK_RMS_PX} px")
    return IntrinsicsResult(
        camera=CameraModel(model, width, height, K, dist),
        rms_px=rms,
        per_view_rms_px={v.name: float(e) for v, e in zip(used, errors, strict=True)},
        views_used=[v.name for v in used],
        views_rejected=rejected,
        coverage=coverage,
        verdict="poorly constrained" if reasons else "ok",
        reasons=reasons,
    )
