"""Image files read with one-line errors naming the file, and without OpenCV's own warning."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from rig.errors import InputError
from rig.image_io import read_image


def test_an_image_is_read_as_opencv_decodes_it(tmp_path):
    picture = np.arange(48 * 64 * 3, dtype=np.uint8).reshape(48, 64, 3)
    cv2.imwrite(str(tmp_path / "a.png"), picture)
    np.testing.assert_array_equal(read_image(tmp_path / "a.png"), picture)
    assert read_image(tmp_path / "a.png", cv2.IMREAD_GRAYSCALE).shape == (48, 64)


def test_missing_and_broken_files_name_the_file(tmp_path, capfd):
    with pytest.raises(InputError, match=r"gone\.png: cannot read the keyframe image: no such file"):
        read_image(tmp_path / "gone.png", what="the keyframe image")
    assert "WARN" not in capfd.readouterr().err  # OpenCV's warning for a missing file is not shown
    (tmp_path / "text.png").write_text("not an image")
    with pytest.raises(InputError, match=r"text\.png: cannot read the image: not an image file"):
        read_image(tmp_path / "text.png")
