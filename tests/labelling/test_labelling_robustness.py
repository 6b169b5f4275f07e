"""Labelling beyond the home recording (issue 10): gates from the measured noise, automatic side,
competing first fits, health warnings; on simulated takes of seeds not used in development and on the
real recording with noise added."""

from __future__ import annotations

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.evaluation.labelling import REAL_RECORDING
from handmocap.core.evaluation.labelling_metrics import labelling_accuracy
from handmocap.core.evaluation.labelling_robustness import Condition, evaluate_condition, hide_runs
from handmocap.core.labelling import SceneSettings, label_scene
from handmocap.core.labelling.sides import SIDE_MARGIN
from handmocap.core.labelling.take_statistics import TakeStatistics, measure_take
from handmocap.core.simulate import simulate_scene

needs_real = pytest.mark.skipif(not REAL_RECORDING.exists(), reason="shared real recording absent")


@pytest.mark.parametrize("noise", [0.5, 2.0])
def test_measured_noise_matches_the_simulated_noise(noise):
    scene = simulate_scene(layout="glove-13", n_frames=600, seed=104, hands="right", n_objects=0, noise_mm=noise)
    statistics = measure_take(scene.take.marker_positions)
    assert statistics.measured and statistics.chains > 1000
    assert statistics.noise_mm == pytest.approx(noise, rel=0.1)
    # the extrapolation error holds at least the noise part √6 σ per axis
    assert statistics.extrapolation_mm > np.sqrt(6) * noise


def test_gates_keep_their_floors_on_a_quiet_take_and_grow_with_noise():
    defaults = SceneSettings()
    quiet = defaults.adapted(TakeStatistics(noise_mm=0.05, extrapolation_mm=3.0, step_mm=5.0, chains=500))
    assert quiet == defaults
    noisy = defaults.adapted(TakeStatistics(noise_mm=2.0, extrapolation_mm=20.0, step_mm=10.0, chains=500))
    assert noisy.continuity_mm == pytest.approx(25.0)
    assert noisy.threshold_floor_mm > 8.0 and noisy.reappear_floor_mm > 8.0
    assert noisy.gate_mm >= 2 * noisy.continuity_mm
    assert defaults.adapted(TakeStatistics(np.nan, np.nan, np.nan, 0)) == defaults
    fixed = SceneSettings(self_tuning=False)
    assert fixed.adapted(TakeStatistics(2.0, 20.0, 10.0, 500)) == fixed


def test_a_noisy_take_is_labelled_and_the_report_says_it_is_noisy():
    scene = simulate_scene(layout="glove-13", n_frames=600, seed=105, hands="right", n_objects=0, noise_mm=2.0)
    result = label_scene(scene.take, "right", "glove-13")
    accuracy = labelling_accuracy(result, scene.truth["point_marker"])
    assert accuracy["correct_share"] >= 0.99, accuracy
    assert accuracy["wrong_share"] <= 0.005, accuracy
    assert result.noise_mm == pytest.approx(2.0, rel=0.1)
    assert "noisy_take" in [warning.kind for warning in result.health]
    quiet = simulate_scene(layout="glove-13", n_frames=300, seed=105, hands="right", n_objects=0, noise_mm=0.3)
    assert "noisy_take" not in [warning.kind for warning in label_scene(quiet.take, "right", "glove-13").health]


@pytest.mark.parametrize("side", ["left", "right"])
def test_auto_finds_the_side_of_one_hand(side):
    scene = simulate_scene(layout="glove-13", n_frames=400, seed=106, hands=side, n_objects=0)
    result = label_scene(scene.take, "auto", "glove-13")
    assert [model.kind for model in result.models] == [side]
    assert result.side_decision.margins[side] > SIDE_MARGIN
    assert labelling_accuracy(result, scene.truth["point_marker"])["correct_share"] >= 0.995


def test_auto_finds_both_hands_of_a_scene():
    scene = simulate_scene(layout="dense", n_frames=300, seed=107, n_objects=0)
    result = label_scene(scene.take, "auto", "dense")
    assert sorted(model.kind for model in result.models) == ["left", "right"]
    assert labelling_accuracy(result, scene.truth["point_marker"])["correct_share"] >= 0.995


def test_auto_says_clearly_when_no_hand_is_there():
    scattered = np.random.default_rng(0).uniform(-3000, 3000, (30, 12, 3))
    from handmocap.core.io import Take

    with pytest.raises(InputError, match="no frame of the take initialises a hand"):
        label_scene(Take([f"p{i}" for i in range(12)], scattered, 100.0), "auto", "glove-13")


def test_hidden_runs_hide_the_requested_share_of_hand_samples():
    scene = simulate_scene(layout="glove-13", n_frames=300, seed=108, hands="right", n_objects=0)
    truth = scene.truth["point_marker"]
    before = np.isfinite(scene.take.marker_positions).all(axis=2) & (truth >= 0)
    hidden, kept = hide_runs(scene.take, truth, 0.1, np.random.default_rng(0))
    after = np.isfinite(hidden.marker_positions).all(axis=2) & (truth >= 0)
    assert 0.07 <= 1 - after.sum() / before.sum() <= 0.13
    assert ((kept >= 0) == after).all()          # the truth no longer holds the hidden points
    assert (np.isfinite(hidden.marker_positions).all(axis=2) | ~np.isfinite(scene.take.marker_positions).all(axis=2)
            | (truth >= 0)).all()              # only hand points were hidden


@needs_real
def test_real_recording_with_two_millimetres_of_noise_and_mirrored():
    result = evaluate_condition(Condition(2.0, mirror=True, hands="auto"), layouts=(), seeds=(7,), real_frames=800)
    figures = result["summary"]["real glove-13"]
    assert figures["sides_right"] == 1
    assert figures["correct_share"] >= 0.99, figures
    assert figures["wrong_share"] <= 0.005, figures


@needs_real
def test_the_whole_real_recording_labels_at_least_as_well_as_its_halves():
    """Subject calibration pooled over windows across the take, refreshed where the markers moved."""
    from handmocap.core.evaluation.labelling_robustness import evaluate_long_take

    figures = evaluate_long_take(seed=0)
    assert figures["whole_at_least_halves"], figures
    assert figures["whole"]["correct_share"] >= 0.995, figures
    assert figures["whole"]["mean_residual_mm"] <= 2.1, figures
