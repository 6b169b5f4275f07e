"""``handmocap camera ...`` end to end on a small synthetic camera take (issue 14)."""

from __future__ import annotations

import json

import numpy as np

from handmocap.app.cli.main import main


def test_camera_commands_end_to_end(tmp_path, capsys):
    folder = tmp_path / "sim"
    assert main(["camera", "simulate", "--out", str(folder), "--seed", "2", "--frames", "150", "--boards", "8",
                 "--offset", "0.1"]) == 0
    boards = sorted(str(p) for p in (folder / "board").glob("*.png"))
    camera = tmp_path / "cam.json"
    assert main(["camera", "calibrate", *boards, "--out", str(camera)]) == 0
    calibrated = json.loads(camera.read_text())
    truth = json.loads((folder / "camera_truth.json").read_text())
    assert abs(calibrated["camera_matrix"][0][0] / truth["camera_matrix"][0][0] - 1) < 0.01
    assert main(["camera", "calibrate", *boards, "--out", str(camera)]) == 2          # refuses to overwrite
    assert "--overwrite" in capsys.readouterr().err
    registered = tmp_path / "registered.json"
    assert main(["camera", "register", str(folder / "take.c3d"), str(folder / "video.avi"),
                 "--camera", str(folder / "camera_truth.json"), "--offset", "0.0", "--out", str(registered)]) == 0
    assert abs(json.loads(registered.read_text())["time_offset_s"] - 0.1) < 0.01 + 1e-9
    overlay = tmp_path / "overlay.avi"
    assert main(["camera", "overlay", str(folder / "take.c3d"), str(folder / "video.avi"),
                 "--camera", str(registered), "--out", str(overlay)]) == 0
    from handmocap.core.camera.frames import VideoFrames

    with VideoFrames(overlay) as video:
        assert video.count > 30 and np.asarray(video.frame(5)).shape == (480, 640, 3)
    assert main(["camera", "overlay", str(folder / "take.c3d"), str(tmp_path / "missing.avi"),
                 "--camera", str(registered), "--out", str(tmp_path / "o2.avi")]) == 2
