"""Calibration on OpenCV's real chessboard photographs of ``../shared/data/chessboard`` (issue 27, item 4): the
folder in one command, agreeing with ``cv2.calibrateCamera`` run directly on the same files with the same
detection settings; inner-corner counts accepted and a wrong count explained; a video as input; the sub-pixel
window from the square's size and the focal length's sensitivity to it. Skipped when the data is absent."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from handmocap.app.cli.main import main
from handmocap.core.camera.intrinsics import (
    _CHESSBOARD_FLAGS,
    _SUBPIX_CRITERIA,
    BoardSpec,
    board_views,
    calibrate_views,
    smallest_square_px,
)
from handmocap.core.evaluation.data import SHARED_DATA

FOLDER = SHARED_DATA / "chessboard"
pytestmark = pytest.mark.skipif(not FOLDER.is_dir(), reason="the chessboard photographs are not in ../shared/data")


def _direct(files: list, windows: list[int], criteria=_SUBPIX_CRITERIA) -> tuple[np.ndarray, np.ndarray, float]:
    """``cv2.findChessboardCorners`` + ``cv2.cornerSubPix`` + ``cv2.calibrateCamera`` on ``files``, nothing of
    ours: (camera matrix, distortion, RMS)."""
    pattern = np.zeros((9 * 6, 3), np.float32)
    pattern[:, :2] = np.mgrid[0:9, 0:6].T.reshape(-1, 2)
    image_points = []
    for path, window in zip(files, windows, strict=True):
        grey = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        found, corners = cv2.findChessboardCorners(grey, (9, 6), flags=_CHESSBOARD_FLAGS)
        assert found, path
        image_points.append(cv2.cornerSubPix(grey, corners, (window, window), (-1, -1), criteria))
    rms, matrix, distortion, _, _ = cv2.calibrateCamera([pattern] * len(files), image_points, (640, 480), None,
                                                        None)
    return matrix, distortion.ravel(), rms


def test_chessboard_folder_in_one_command_agrees_with_opencv(tmp_path, capsys):
    out = tmp_path / "camera.json"
    assert main(["camera", "calibrate", str(FOLDER), "--board", "chessboard", "--inner-corners", "9x6",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "skipped left14.jpg: 2462×3045 px" in printed and "from 12 of 12 images" in printed   # a stray photo
    assert "sub-pixel window" in printed and "focal length moves" in printed
    saved = json.loads(out.read_text())
    ours = np.array(saved["camera_matrix"], float)
    report = saved["report"]["intrinsics"]
    window = report["subpixel_window"]
    assert 5 <= window["window_px"][0] <= window["window_px"][2] <= 15
    assert all(abs(change) < 0.5 for change in window["focal_change_percent"].values())

    found = board_views([FOLDER])
    spec = BoardSpec("chessboard", (10, 7), 1.0)
    result, _ = calibrate_views(found.views, found.size, spec)
    files = [FOLDER / view.name for view in found.views]
    windows = []
    for path in files:
        grey = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        _, corners = cv2.findChessboardCorners(grey, (9, 6), flags=_CHESSBOARD_FLAGS)
        side = smallest_square_px(corners.reshape(-1, 2), np.arange(54), spec)
        windows.append(int(np.clip(round(0.3 * side), 2, 15)))
    matrix, distortion, rms = _direct(files, windows)
    print(f"ours f {ours[0, 0]:.4f} {ours[1, 1]:.4f} c {ours[0, 2]:.4f} {ours[1, 2]:.4f} rms "
          f"{report['reprojection_px']}; cv2 directly f {matrix[0, 0]:.4f} {matrix[1, 1]:.4f} c {matrix[0, 2]:.4f} "
          f"{matrix[1, 2]:.4f} rms {rms:.4f}")
    assert np.abs(ours - matrix).max() < 1e-3                   # every parameter (px) as OpenCV's own calls give
    assert np.abs(result.camera.distortion - distortion).max() < 1e-5
    tutorial, _, tutorial_rms = _direct(files, [11] * len(files),
                                        (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001))
    print(f"OpenCV's tutorial settings (11 px window): f {tutorial[0, 0]:.4f} {tutorial[1, 1]:.4f} rms "
          f"{tutorial_rms:.4f}")
    assert report["reprojection_px"] < tutorial_rms


@pytest.mark.parametrize(("arguments", "advice"), [
    (["--board", "chessboard", "--squares", "9x6"], "found as a chessboard of 9×6 inner corners (10×7 squares) in "
                                                    "4 of 4 images tried: use --squares 10x7 (or --inner-corners 9x6)"),
    (["--squares", "10x7"], "use --board chessboard --squares 10x7"),
    ([], "check --board and --squares"),
    (["--squares", "10x7", "--inner-corners", "9x6"], "give the board's size once"),
    (["--squares", "ten"], "must look like 10x7"),
])
def test_chessboard_wrong_size_or_kind_says_what_fits(tmp_path, capsys, arguments, advice):
    assert main(["camera", "calibrate", str(FOLDER), *arguments, "--out", str(tmp_path / "camera.json")]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and advice in error, error


def test_chessboard_video_and_mixed_inputs(tmp_path, capsys):
    """A video of the photographs (each held for three frames, MJPG) calibrates like the folder; files, a folder
    and a video can be mixed."""
    video = tmp_path / "board.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (640, 480))
    images = sorted(FOLDER.glob("left*.jpg"))
    for path in images:
        image = cv2.imread(str(path))
        if image.shape[:2] != (480, 640):
            continue
        for _ in range(3):
            writer.write(image)
    writer.release()
    assert main(["camera", "calibrate", str(video), "--board", "chessboard", "--squares", "10x7",
                 "--video-views", "36", "--out", str(tmp_path / "video.json")]) == 0
    assert "of 36 images" in capsys.readouterr().out
    from_video = np.array(json.loads((tmp_path / "video.json").read_text())["camera_matrix"])
    assert main(["camera", "calibrate", str(FOLDER), "--board", "chessboard", "--squares", "10x7",
                 "--out", str(tmp_path / "folder.json")]) == 0
    from_folder = np.array(json.loads((tmp_path / "folder.json").read_text())["camera_matrix"])
    assert abs(from_video[0, 0] / from_folder[0, 0] - 1) < 0.01
    mixed = board_views([images[0], FOLDER, video], video_views=5)
    assert len(mixed.views) == 1 + 12 + 5 and [name for name, _ in mixed.skipped] == ["left14.jpg"]
