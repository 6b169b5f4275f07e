"""``detect_board_in_files``: the one reader of board image files for the CLI and the camera wizard."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from handmocap.core.camera.intrinsics import BoardSpec, board_image, detect_board_in_files
from handmocap.core.errors import InputError


def _write(path, image):
    assert cv2.imwrite(str(path), image)
    return path


def test_detects_each_file_and_calls_before_in_order(tmp_path):
    spec = BoardSpec("chessboard", (7, 5), 20.0)
    image, _ = board_image(spec, 40)
    paths = [_write(tmp_path / "board.png", image), _write(tmp_path / "blank.png", np.full_like(image, 255))]
    seen = []
    detections, size = detect_board_in_files(paths, spec, seen.append)
    assert seen == [0, 1]
    assert size == (image.shape[1], image.shape[0])
    assert detections[0] is not None and detections[1] is None


def test_refuses_images_of_another_size_and_no_images(tmp_path):
    spec = BoardSpec("chessboard", (7, 5), 20.0)
    image, _ = board_image(spec, 40)
    paths = [_write(tmp_path / "a.png", image), _write(tmp_path / "b.png", image[:-8])]
    with pytest.raises(InputError, match="b.png is .* but the first image is"):
        detect_board_in_files(paths, spec)
    with pytest.raises(InputError, match="no board images"):
        detect_board_in_files([], spec)
