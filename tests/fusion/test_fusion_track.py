"""fuse_take on a short synthetic take (issue 15): the fused occluded fingers beat markers-only IK, progress and
cancel, refusal of an unregistered camera, the result file."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.evaluation.fusion import OCCLUDED_DIGITS, VISIBLE_DIGITS, joint_errors, occluded_take, rgbd_frames
from handmocap.core.fusion import FusionSettings, fuse_take
from handmocap.core.fusion.icp import ICPSettings

FAST = FusionSettings(icp=ICPSettings(iterations=4, depth_points=200), max_side=72)


@pytest.fixture(scope="module")
def short_take():
    simulated, take, hidden = occluded_take(seed=5, n_frames=100, motion="heldout")
    return simulated, take, hidden, rgbd_frames(simulated)


def test_fusion_fused_occluded_fingers_beat_markers_only(short_take, tmp_path):
    simulated, take, hidden, frames = short_take
    reported = []
    result = fuse_take(take, simulated.camera, frames, FAST, progress=reported.append)
    truth = simulated.simulated.truth["joint_angles"]
    frames_hidden = np.nonzero(hidden)[0]
    frames_hidden = frames_hidden[frames_hidden <= result.rgbd_mocap_frames.max()]
    assert len(frames_hidden) > 40 and len(result.rgbd_frames) >= 25
    markers_only = joint_errors(result.markers_only, truth, frames_hidden, OCCLUDED_DIGITS)
    fused = joint_errors(result.joint_angles, truth, frames_hidden, OCCLUDED_DIGITS)
    assert fused < 0.8 * markers_only
    assert joint_errors(result.joint_angles, truth, frames_hidden, VISIBLE_DIGITS) < 1.2 * joint_errors(
        result.markers_only, truth, frames_hidden, VISIBLE_DIGITS) + 0.1
    assert reported[-1] == 1.0 and all(b >= a for a, b in zip(reported, reported[1:], strict=False))
    assert result.joint_angles.shape == (take.n_frames, 26) and np.isfinite(result.joint_angles).all()
    assert set(result.silhouette_sources) == {"colour"}
    path = tmp_path / "fused.npz"
    result.save(path)
    with np.load(path) as stored:
        assert np.array_equal(stored["joint_angles"], result.joint_angles)
        assert list(stored["energy_term_names"]) == ["marker", "silhouette", "depth", "edge", "smoothness"]


def test_fusion_cancel_and_unregistered_camera(short_take, cancel_after):
    simulated, take, _, frames = short_take
    with pytest.raises(CancelledError):
        fuse_take(take, simulated.camera, frames, FAST, cancelled=cancel_after(3))
    with pytest.raises(InputError, match="not registered"):
        fuse_take(take, replace(simulated.camera, registered=False), frames, FAST)
    with pytest.raises(InputError, match="unknown optimiser"):
        FusionSettings(optimiser="gradient")


def test_fusion_swarm_optimiser_runs_on_chosen_frames(short_take):
    simulated, take, hidden, frames = short_take
    settings = replace(FAST, optimiser="pso", swarm=replace(FAST.swarm, particles=12, generations=8))
    result = fuse_take(take, simulated.camera, frames, settings, camera_frames=[12, 13, 14])
    assert list(result.rgbd_frames) == [12, 13, 14] and result.optimiser == "pso"
    assert (result.energy_terms[:, 0] < 8.0).all()
