"""``handmocap fuse`` and ``handmocap evaluate fusion`` (issue 15)."""

from __future__ import annotations

import cv2
import numpy as np

from handmocap.app.cli.main import main
from handmocap.core.camera.files import save_camera
from handmocap.core.camera.writers import write_depth_frames
from handmocap.core.evaluation.fusion import occluded_take, rgbd_frames
from handmocap.core.io import save_take


def test_fusion_cli_fuse_writes_result_and_refuses_to_overwrite(tmp_path, capsys):
    simulated, take, _ = occluded_take(seed=6, n_frames=50)
    recording = rgbd_frames(simulated)
    save_take(take, tmp_path / "take.c3d")
    save_camera(simulated.camera, tmp_path / "camera.json")
    rgbd = tmp_path / "rgbd"
    (rgbd / "depth").mkdir(parents=True)
    (rgbd / "colour").mkdir()
    count = len(recording.depth)
    write_depth_frames(rgbd / "depth", (recording.depth.frame(k) for k in range(count)), 1.0)
    for k in range(count):
        cv2.imwrite(str(rgbd / "colour" / f"colour_{k:05d}.png"), recording.colour.frame(k))
    cv2.imwrite(str(tmp_path / "plate.png"), recording.background)
    out = tmp_path / "fused.npz"
    arguments = ["fuse", str(tmp_path / "take.c3d"), "--camera", str(tmp_path / "camera.json"), "--rgbd", str(rgbd),
                 "--background", str(tmp_path / "plate.png"), "--out", str(out)]
    assert main(arguments) == 0
    printed = capsys.readouterr()
    assert "fused" in printed.out and "frames/s" in printed.out
    assert "%" not in printed.err   # progress is drawn only on a terminal (one in-place line), not into a capture
    with np.load(out) as result:
        assert result["joint_angles"].shape == (take.n_frames, 26) and str(result["optimiser"]) == "icp"
        assert np.isfinite(result["joint_angles"]).all()
    assert main(arguments) == 2
    assert "exists" in capsys.readouterr().err
    assert main(["fuse", str(tmp_path / "take.c3d"), "--camera", str(tmp_path / "camera.json"), "--rgbd",
                 str(tmp_path / "missing"), "--out", str(tmp_path / "other.npz")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_fusion_cli_evaluate_prints_the_figures(monkeypatch, capsys):
    import json

    import handmocap.core.evaluation.fusion as evaluation

    def quick(seeds, settings, swarm):
        return {"occluded_joint_error_mm_markers_only": 2.0, "occluded_joint_error_mm_fused": 1.0,
                "visible_joint_error_mm_fused": 0.4, "fused_frames_per_s": 5.0, "seeds": list(seeds), "swarm": swarm}

    monkeypatch.setattr(evaluation, "evaluate_fusion", quick)
    assert main(["evaluate", "fusion", "--seeds", "7", "--no-pso", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert figures["seeds"] == [7] and figures["swarm"] is False and figures["occluded_joint_error_mm_fused"] == 1.0
