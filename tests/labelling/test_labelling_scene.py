"""Scene labelling: one hand, left hand, two hands with rigid objects, online/offline, late start, bad input."""

from functools import lru_cache

import numpy as np
import pytest

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.evaluation.labelling_metrics import labelling_accuracy
from handmocap.core.io import Take
from handmocap.core.labelling import SceneSettings, label_scene
from handmocap.core.labelling.fragments import extend_trajectories, free_fragments
from handmocap.core.simulate import simulate_scene, simulate_take


@lru_cache(maxsize=4)
def _one_hand(layout: str, seed: int = 3, frames: int = 300):
    return simulate_take(layout=layout, n_frames=frames, seed=seed, noise_mm=0.3, ghost_rate=0.05, occlusion=True,
                         unlabelled=True)


@lru_cache(maxsize=2)
def _scene(layout: str = "dense", frames: int = 300, hands: str = "both", objects: int = 2, seed: int = 4):
    return simulate_scene(layout=layout, n_frames=frames, seed=seed, hands=hands, n_objects=objects)


def _assert_targets(accuracy: dict) -> None:
    assert accuracy["observed_samples"] > 0 and accuracy["ghost_points"] > 0, accuracy
    assert accuracy["correct_share"] >= 0.995, accuracy
    assert accuracy["ghost_labelled_share"] < 0.005, accuracy
    assert accuracy["longest_swap_frames"] <= 10, accuracy


@pytest.mark.parametrize("layout", ["dense", "glove-13"])
def test_one_hand_meets_the_targets(layout):
    simulated = _one_hand(layout)
    result = label_scene(simulated.take, "right", layout)
    _assert_targets(labelling_accuracy(result, simulated.truth["point_marker"]))
    assert result.marker_names == list(simulated.truth["marker_names"])
    assert [model.kind for model in result.models] == ["right"] and result.models[0].init_frame == 0
    assert result.models[0].calibration["residual_after_mm"] <= result.models[0].calibration["residual_before_mm"]
    angles = result.joint_angles["right"]
    assert angles.shape == (300, 26) and np.isfinite(angles).all()
    truth = simulated.truth["joint_angles"]
    assert np.abs(angles[:, :3] - truth[:, :3]).mean() < 5.0   # wrist position (mm)


def test_two_hands_and_objects_meet_the_targets():
    scene = _scene()
    result = label_scene(scene.take, "both", "dense", objects=scene.objects)
    _assert_targets(labelling_accuracy(result, scene.truth["point_marker"]))
    assert result.marker_names == list(scene.truth["marker_names"])
    assert result.marker_names[0].startswith("R_") and any(name.startswith("L_") for name in result.marker_names)
    assert [(model.name, model.kind) for model in result.models] == [
        ("right", "right"), ("left", "left"), ("box", "object"), ("cup", "object")]
    assert np.array_equal(result.model_of_marker, scene.truth["model_of_marker"])
    for name in ("box", "cup"):
        poses, truth = result.object_poses[name], scene.truth[f"object_pose_{name}"]
        assert poses.shape == (300, 4, 4)
        assert np.abs(poses[:, :3, 3] - truth[:, :3, 3]).max() < 2.0
        rotation_error = np.arccos(np.clip((np.einsum("fab,fab->f", poses[:, :3, :3], truth[:, :3, :3]) - 1) / 2,
                                           -1, 1))
        assert np.degrees(rotation_error).max() < 2.0
    # measured coordinates are handed through unchanged
    labelled = result.labelled_positions()
    frames, markers = np.nonzero(result.assignment >= 0)
    assert np.array_equal(labelled[frames, markers], scene.take.marker_positions[frames, result.assignment[frames,
                                                                                                             markers]])
    assert np.isnan(labelled[result.assignment < 0]).all()
    labelled_take = result.labelled_take(scene.take)
    assert labelled_take.marker_names == result.marker_names


def test_left_and_right_are_told_apart_by_the_fit():
    scene = _scene(hands="left", objects=0, seed=5)
    result = label_scene(scene.take, "both", "dense")
    kinds = {model.name: model.init_frame for model in result.models}
    assert kinds["left"] == 0 and kinds["right"] == -1, kinds
    left = result.model("left").markers
    accuracy = labelling_accuracy(_sub(result, left), scene.truth["point_marker"])
    assert accuracy["correct_share"] >= 0.995, accuracy
    assert (result.assignment[:, result.model("right").markers] < 0).all()


def test_a_hand_fitted_one_finger_over_is_fitted_again_from_other_postures():
    """glove-13, seed 11: started from the prior's mean posture, the left hand's best first fit takes
    its markers one finger over (4 mm residual, 88 % correct over the take); starting again from other
    postures of the prior finds the right fit."""
    scene = simulate_scene(layout="glove-13", n_frames=300, seed=11, n_objects=2)
    result = label_scene(scene.take, "both", "glove-13", objects=scene.objects)
    _assert_targets(labelling_accuracy(result, scene.truth["point_marker"]))


def _sub(result, part):
    """The result restricted to one model's markers (their truth indices start at 0)."""
    class Sub:
        assignment = result.assignment[:, part]
        ghost_points = result.ghost_points
    return Sub()


def test_late_start_offline_backward_pass_and_online_causality():
    simulated = _one_hand("dense", seed=2, frames=200)
    positions = simulated.take.marker_positions.copy()
    truth = simulated.truth["point_marker"]
    # the first 40 frames show only 4 of the 24 markers: nothing initialises there
    hidden = (np.arange(len(positions)) < 40)[:, None] & ~np.isin(truth, [20, 21, 22, 23])
    positions[hidden] = np.nan
    take = Take(simulated.take.marker_names, positions, simulated.take.frame_rate)
    kept_truth = np.where(hidden, -1, truth)
    offline = label_scene(take, "right", "dense")
    assert offline.models[0].init_frame >= 40
    before = offline.assignment[:40]
    assert (before[:, 20:24] >= 0).mean() > 0.95            # the backward pass labelled them
    assert labelling_accuracy(offline, kept_truth)["wrong_share"] == 0.0
    online = label_scene(take, "right", "dense", online=True, settings=SceneSettings(calibration_frames=60))
    assert (online.assignment[:40] < 0).all()                 # causal: nothing before the initialisation
    shorter = Take(take.marker_names, positions[:120], take.frame_rate)
    prefix = label_scene(shorter, "right", "dense", online=True, settings=SceneSettings(calibration_frames=60))
    assert np.array_equal(prefix.assignment, online.assignment[:120])


def test_online_rescue_labels_a_lost_fingertip_from_causal_evidence_only():
    """glove-13, seed 2: the middle fingertip reappears where the posture estimate does not reach it.
    Online, its free trajectory is given to it once 20 frames of it fit, from then on; labelling a
    prefix of the take gives the same labels (nothing depends on later frames)."""
    simulated = _one_hand("glove-13", seed=2)
    take, truth = simulated.take, simulated.truth["point_marker"]
    online = label_scene(take, "right", "glove-13", online=True)
    accuracy = labelling_accuracy(online, truth)
    assert accuracy["correct_share"] >= 0.985 and accuracy["wrong_share"] == 0.0, accuracy
    shorter = Take(take.marker_names, take.marker_positions[:200], take.frame_rate)
    prefix = label_scene(shorter, "right", "glove-13", online=True)
    assert np.array_equal(prefix.assignment, online.assignment[:200])


def test_cancel_and_progress():
    simulated = _one_hand("glove-13", frames=60)
    reported = []
    label_scene(simulated.take, "right", "glove-13", progress=reported.append)
    assert reported[-1] == 1.0 and reported == sorted(reported)
    with pytest.raises(CancelledError):
        label_scene(simulated.take, "right", "glove-13", cancelled=lambda: True)


def _take(positions: np.ndarray) -> Take:
    return Take([f"point_{index:03d}" for index in range(positions.shape[1])], positions, 100.0)


def test_bad_input_gives_one_line_input_errors(tmp_path):
    with pytest.raises(InputError, match="no frames"):
        label_scene(_take(np.zeros((0, 3, 3))))
    with pytest.raises(InputError, match="all NaN"):
        label_scene(_take(np.full((5, 4, 3), np.nan)))
    few = np.full((5, 4, 3), np.nan)
    few[:, :2] = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]]
    with pytest.raises(InputError, match="3 or more"):
        label_scene(_take(few))
    scattered = np.random.default_rng(0).uniform(-3000, 3000, (20, 6, 3))
    with pytest.raises(InputError, match="initialises"):
        label_scene(_take(scattered))
    simulated = _one_hand("glove-13", frames=60)
    with pytest.raises(InputError, match="hands"):
        label_scene(simulated.take, "three")
    spec = tmp_path / "scene.json"
    spec.write_text("{not json")
    with pytest.raises(InputError, match="scene.json"):
        label_scene(simulated.take, "right", "glove-13", objects=spec)
    with pytest.raises(InputError, match="no such"):
        label_scene(simulated.take, "right", "glove-13", objects=tmp_path / "missing.json")
    spec.write_text('{"objects": [{"name": "b", "type": "rigid", "markers": {"thumb_tip": [0, 0, 0], '
                    '"x": [50, 0, 0], "y": [0, 60, 0]}}]}')
    with pytest.raises(InputError, match="used twice"):
        label_scene(simulated.take, "right", "glove-13", objects=spec)


def test_trajectory_extension_links_continuations_but_not_ghosts():
    frames = 30
    path = np.column_stack([np.linspace(0, 58, frames), np.zeros(frames), np.zeros(frames)])   # 2 mm/frame
    points = np.full((frames, 3, 3), np.nan)
    points[:, 0] = path
    points[12:18, 1] = path[12:18] + [0.0, 25.0, 0.0]                  # a ghost 25 mm away for 6 frames
    assignment = np.full((frames, 1), -1)
    assignment[20:, 0] = 0                                             # labelled from frame 20 on
    added = extend_trajectories(points, assignment, np.array([0]), link_mm=4.0)
    assert (assignment[:, 0] == 0).all() and len(added) == 20
    fragments = free_fragments(points, assignment, 4.0, 5)
    assert [(first, len(columns)) for first, columns in fragments] == [(12, 6)]
    forward_only = np.full((frames, 1), -1)
    forward_only[20:, 0] = 0
    assert extend_trajectories(points, forward_only, np.array([0]), 4.0, backward=False) == []


def test_a_fast_free_trajectory_is_one_fragment_from_its_first_sample():
    """A fingertip seen alone between two gaps, moving 6 mm per frame (0.6 m/s at 100 Hz): more than
    ``link_mm`` between its first two samples, yet one fragment (that the rescue can give to a marker)."""
    frames = 26
    path = np.column_stack([np.linspace(0, 150, frames), 10.0 * np.sin(np.linspace(0, 1, frames)), np.zeros(frames)])
    points = np.full((frames, 2, 3), np.nan)
    points[:, 0] = path
    points[5, 1] = path[5] + [0.0, 30.0, 0.0]                           # a one-frame ghost
    fragments = free_fragments(points, np.full((frames, 1), -1), 4.0, 20)
    assert [(first, len(columns)) for first, columns in fragments] == [(0, frames)]
    assert (fragments[0][1] == 0).all()


def test_free_fragments_end_at_ambiguity_and_are_listed_in_the_order_they_end():
    """Two free trajectories that come within ``2 · link_mm`` of each other stop being linked there (neither
    continuation is unambiguous) and start afresh after; fragments are listed as they end, those still open at
    the last frame last, each with its point column per frame."""
    frames, link = 40, 4.0
    t = np.arange(frames, dtype=float)
    points = np.full((frames, 3, 3), np.nan)
    points[:, 0] = np.column_stack([2.0 * t, np.zeros(frames), np.zeros(frames)])
    points[:, 1] = np.column_stack([2.0 * t, np.abs(t - 20.0) * 1.5 + 1.0, np.zeros(frames)])   # meets column 0
    points[:8, 2] = np.column_stack([np.full(8, 200.0), np.zeros(8), np.zeros(8)])           # a still point, 8 frames
    fragments = free_fragments(points, np.full((frames, 1), -1), link, 3)
    summary = [(first, len(columns), int(columns[0])) for first, columns in fragments]
    assert summary[0] == (0, 8, 2)                                # the still point ends first
    near = np.linalg.norm(points[:, 0] - points[:, 1], axis=1) < 2.0 * link
    assert near.any()
    ended_before_meeting = [entry for entry in summary[1:] if entry[0] == 0]
    assert sorted(entry[2] for entry in ended_before_meeting) == [0, 1]
    assert all(entry[1] <= int(np.argmax(near)) for entry in ended_before_meeting)
    assert summary[-2:] and all(first + length == frames for first, length, _ in summary[-2:])
    for first, columns in fragments:
        assert np.isfinite(points[first + np.arange(len(columns)), columns]).all()
