"""Automatic labelling of one right hand on simulated unlabelled takes with ghosts and occlusions."""

from functools import lru_cache

import numpy as np
import pytest

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.evaluation.labelling_metrics import labelling_accuracy
from handmocap.core.io import Take
from handmocap.core.labelling import label_scene
from handmocap.core.model import load_layout, load_template, marker_positions, resolve_layout
from handmocap.core.simulate import simulate_take


@lru_cache(maxsize=4)
def _simulated(layout: str, frames: int = 400):
    return simulate_take(layout=layout, n_frames=frames, seed=1, noise_mm=0.3, ghost_rate=0.05,
                         occlusion=True, unlabelled=True)


@lru_cache(maxsize=4)
def _labelled(layout: str, frames: int = 400):
    return label_scene(_simulated(layout, frames).take, "right", layout)


@pytest.mark.parametrize("layout", ["dense", "glove-13"])
def test_labels_simulated_take_with_ghosts_and_occlusions(layout):
    simulated, result = _simulated(layout), _labelled(layout)
    accuracy = labelling_accuracy(result, simulated.truth["point_marker"])
    assert accuracy["ghost_points"] > 0 and accuracy["observed_samples"] > 0
    assert accuracy["correct_share"] >= 0.995, accuracy
    assert accuracy["ghost_labelled_share"] < 0.005, accuracy
    assert accuracy["longest_swap_frames"] <= 10, accuracy
    frames, markers = result.assignment.shape
    angles = result.joint_angles["right"]
    assert angles.shape == (frames, 26) and np.isfinite(angles).all()
    labelled = result.assignment >= 0
    assert np.isfinite(result.residuals_mm[labelled]).all() and np.isnan(result.residuals_mm[~labelled]).all()
    assert np.nanmax(result.residuals_mm) <= 10.0
    assert (result.confidence[labelled] >= 0).all()


@pytest.mark.parametrize("layout", ["dense", "glove-13"])
def test_automatic_initialisation_finds_the_hand(layout):
    simulated, result = _simulated(layout), _labelled(layout)
    model = result.models[0].hand_model
    markers = result.models[0].marker_set
    template = load_template()
    true_positions = marker_positions(template, resolve_layout(template, load_layout(layout)),
                                      simulated.truth["joint_angles"][0])
    visible = simulated.truth["visible"][0]
    error = np.linalg.norm(marker_positions(model, markers, result.joint_angles["right"][0]) - true_positions,
                           axis=1)[visible]
    assert error.max() < 5.0, error


def test_given_initial_posture_is_used():
    simulated = _simulated("dense", 50)
    result = label_scene(simulated.take, "right", "dense",
                         initial_states={"right": simulated.truth["joint_angles"][0]})
    assert result.models[0].init_frame == 0
    assert labelling_accuracy(result, simulated.truth["point_marker"])["correct_share"] >= 0.995


def test_ghost_points_are_the_unlabelled_measured_points():
    simulated = _simulated("dense", 50)
    result = _labelled("dense", 50)
    present = np.isfinite(simulated.take.marker_positions).all(axis=2)
    labelled = np.zeros_like(present)
    frames, markers = np.nonzero(result.assignment >= 0)
    labelled[frames, result.assignment[frames, markers]] = True
    assert not (labelled & result.ghost_points).any()
    assert np.array_equal(labelled | result.ghost_points, present)


def test_cancel_raises_and_progress_reaches_one():
    simulated = _simulated("glove-13", 50)
    reported = []
    label_scene(simulated.take, "right", "glove-13", progress=reported.append)
    assert reported[-1] == 1.0 and reported == sorted(reported)
    with pytest.raises(CancelledError):
        label_scene(simulated.take, "right", "glove-13", cancelled=lambda: True)


def test_too_few_points_in_every_frame_is_an_input_error():
    positions = np.full((3, 4, 3), np.nan)
    positions[0, :2] = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]]
    positions[1:] = 1.0
    take = Take(marker_names=[f"point_{index:03d}" for index in range(4)], marker_positions=positions, frame_rate=100.0)
    # frames after the first are searched for a hand too; none has one here
    with pytest.raises(InputError, match="initialises"):
        label_scene(take, "right", "dense")


def test_accuracy_metrics_count_swaps_and_ghost_labels():
    simulated = _simulated("glove-13", 50)
    result = label_scene(simulated.take, "right", "glove-13")
    swapped = result.assignment.copy()
    swapped[10:22, [0, 1]] = swapped[10:22, [1, 0]]
    result.assignment = swapped
    accuracy = labelling_accuracy(result, simulated.truth["point_marker"])
    assert accuracy["longest_swap_frames"] >= 12 and accuracy["correct_share"] < 1.0
