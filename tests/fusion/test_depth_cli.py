"""``handmocap depth fit`` and ``handmocap depth track`` (issue 27, item 1): the JSON result and the overlay, the
track of a folder (warm starts, re-initialisation), and bad input as one line."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from handmocap.app.cli.main import main
from handmocap.core.evaluation.data import RGBD_FRAMES
from handmocap.core.fusion.depth_track import DepthTracker, parse_intrinsics, read_depth_image

FOLDER = RGBD_FRAMES / "sr305_open_right_hand"
INTRINSICS = "476.007,476.007,313.683,242.755"
needs_frames = pytest.mark.skipif(not FOLDER.is_dir(), reason="the real depth frames are not in ../shared/data/rgbd")


@needs_frames
def test_depth_fit_cli_writes_the_result_and_the_overlay(tmp_path, capsys):
    out, overlay = tmp_path / "fit.json", tmp_path / "fit.png"
    arguments = ["depth", "fit", str(FOLDER / "150.png"), "--intrinsics", INTRINSICS, "--depth-unit-mm", "0.125",
                 "--out", str(out), "--overlay", str(overlay)]
    assert main(arguments) == 0
    assert "trusted" in capsys.readouterr().out
    result = json.loads(out.read_text())
    assert result["trusted"] is True and result["why_not"] == []
    assert set(result["residuals"]) >= {"depth_mm", "silhouette", "missed_share", "outside_share"}
    assert len(result["palm_uv"]) == 2 and len(result["theta"]) == 26 and "index_mcp_flexion" in result["pose"]
    image = cv2.imread(str(overlay))
    assert image.shape == (480, 640, 3)
    assert (np.abs(image.astype(int) - image[..., ::-1]).sum(axis=2) > 60).sum() > 2000   # the coloured hand drawn
    assert main(arguments) == 2 and "exists" in capsys.readouterr().err


@needs_frames
@pytest.mark.parametrize(("argument", "message"), [
    ("folder", "is a folder"), ("jpeg", "16-bit PNG"), ("eight_bit", "16-bit one-channel"),
    ("missing", "does not exist"), ("intrinsics", "four numbers"), ("unit", "depth unit"), ("empty", "no depth"),
    ("size", "outside the"),
])
def test_depth_fit_cli_bad_input_is_one_line(tmp_path, capsys, argument, message):
    frame, intrinsics, unit = str(FOLDER / "150.png"), INTRINSICS, "0.125"
    if argument == "folder":
        frame = str(FOLDER)
    elif argument == "jpeg":
        frame = str(tmp_path / "frame.jpg")
        cv2.imwrite(frame, np.zeros((48, 64, 3), np.uint8))
    elif argument == "eight_bit":
        frame = str(tmp_path / "frame.png")
        cv2.imwrite(frame, np.full((48, 64), 7, np.uint8))
    elif argument == "missing":
        frame = str(tmp_path / "none.png")
    elif argument == "intrinsics":
        intrinsics = "476,476,313"
    elif argument == "unit":
        unit = "-1"
    elif argument == "empty":
        frame = str(tmp_path / "frame.png")
        cv2.imwrite(frame, np.zeros((48, 64), np.uint16))
    elif argument == "size":
        intrinsics = "476,476,900,242"
    assert main(["depth", "fit", frame, "--intrinsics", intrinsics, "--depth-unit-mm", unit, "--out",
                 str(tmp_path / "fit.json")]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and message in error, error
    assert not (tmp_path / "fit.json").exists()


@needs_frames
def test_depth_track_cli_tracks_the_shared_folder(tmp_path, capsys):
    out, overlays = tmp_path / "track.json", tmp_path / "overlays"
    assert main(["depth", "track", str(FOLDER), "--intrinsics", INTRINSICS, "--depth-unit-mm", "0.125",
                 "--out", str(out), "--overlays", str(overlays)]) == 0
    assert "8 trusted" in capsys.readouterr().out
    track = json.loads(out.read_text())
    assert [frame["frame"] for frame in track["frames"]] == sorted(path.name for path in FOLDER.glob("*.png"))
    assert track["frames"][0]["mode"] == "initialised" and track["summary"]["lost"] == 0
    assert len(list(overlays.glob("*_overlay.png"))) == 8


@needs_frames
def test_depth_track_warm_starts_follow_a_turning_hand_and_reinitialise_when_lost():
    """Frame 110 turned 4° and moved 3 px a frame: the warm start follows it (temporal terms, no new search);
    a frame without the hand is lost, and the next frame with it is re-initialised."""
    depth = read_depth_image(FOLDER / "110.png", 0.125)
    tracker = DepthTracker(parse_intrinsics(INTRINSICS, (640, 480)))
    modes = []
    for step in range(6):
        turn = cv2.getRotationMatrix2D((270, 247), 4.0 * step, 1.0)
        turn[0, 2] += 3 * step
        fit, mode = tracker.step(cv2.warpAffine(depth, turn, (640, 480), flags=cv2.INTER_NEAREST))
        assert fit.trusted, (step, fit.reasons)
        modes.append(mode)
    assert modes[0] == "initialised" and modes[1:].count("tracked") >= 4, modes
    assert len(tracker.history) == 2                                # the temporal terms' two previous frames
    _, mode = tracker.step(np.full((480, 640), 900.0, np.float32))
    assert mode == "lost"
    _, mode = tracker.step(depth)
    assert mode == "re-initialised"
