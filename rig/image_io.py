"""Reading image files with one-line errors that name the file."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from rig.errors import InputError


def read_image(path: str | Path, flags: int = cv2.IMREAD_COLOR, what: str = "the image") -> np.ndarray:
    """The image file ``path`` as OpenCV decodes it with ``flags`` (``(H, W, 3)`` BGR uint8 by
    default).

    Raises :class:`InputError` naming the file and ``what`` it is when the file is missing (checked
    first: OpenCV would print its own warning) or not an image OpenCV decodes.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"cannot read {what}: no such file", path=path)
    image = cv2.imread(str(path), flags)
    if image is None:
        raise InputError(f"cannot read {what}: not an image file", path=path)
    return image
