"""Subject calibration (Zhao et al. eq. 2): bone scales and marker offsets from labelled frames."""

import numpy as np
import pytest

from handmocap.core.calibration.subject import calibrate_subject, calibrated_model
from handmocap.core.errors import InputError
from handmocap.core.ik import solve_positions
from handmocap.core.model import load_layout, load_template, marker_positions, marker_positions_batch, resolve_layout
from handmocap.core.simulate import simulate_joint_angles


@pytest.fixture(scope="module")
def subject():
    """A re-proportioned subject: fingers 8-12 % longer, knuckles 5 % farther, markers 2-3 mm off the
    template's places; 200 frames of varied motion with 0.3 mm noise."""
    template = load_template()
    layout = load_layout("dense")
    markers = resolve_layout(template, layout)
    rng = np.random.default_rng(3)
    scales = np.ones(15)
    for digit in range(5):
        scales[3 * digit] = 1.05
        scales[3 * digit + 1:3 * digit + 3] = rng.uniform(1.08, 1.12, 2)
    offsets = rng.normal(0.0, 1.5, (len(markers.names), 3))
    model, subject_markers = calibrated_model(template, markers, scales, offsets)
    thetas = simulate_joint_angles(200, seed=4)
    positions = marker_positions_batch(model, subject_markers, thetas) + rng.normal(0.0, 0.3, (200, 24, 3))
    positions[rng.random((200, 24)) < 0.1] = np.nan
    return template, layout, positions, scales


def test_calibration_moves_bone_scales_towards_the_subject_and_lowers_the_residual(subject):
    template, layout, positions, true_scales = subject
    model, markers, report = calibrate_subject(positions, template, layout)
    found = np.array(report["scales"])
    assert np.abs(found - true_scales).mean() < 0.5 * np.abs(1.0 - true_scales).mean(), (found, true_scales)
    assert report["residual_after_mm"] < 0.5 * report["residual_before_mm"]
    # the calibrated hand tracks the whole take (not only the calibration frames) better
    before = solve_positions(positions, template, resolve_layout(template, layout)).mean_residual_mm
    after = solve_positions(positions, model, markers).mean_residual_mm
    assert after < 0.6 * before, (before, after)
    assert model.side == "right" and markers.names == layout.names
    assert np.isfinite(model.vertices).all() and model.vertices.shape == template.vertices.shape


def test_identity_calibration_reproduces_the_model():
    template = load_template()
    markers = resolve_layout(template, load_layout("glove-13"))
    model, moved = calibrated_model(template, markers, np.ones(15), np.zeros((len(markers.names), 3)))
    assert np.allclose(model.skeleton.rest_positions, template.skeleton.rest_positions)
    theta = np.zeros(26)
    theta[7] = 0.5
    assert np.allclose(marker_positions(model, moved, theta), marker_positions(template, markers, theta))


def test_left_hand_calibration_keeps_the_side():
    template = load_template("left")
    markers = resolve_layout(template, load_layout("glove-13"))
    thetas = simulate_joint_angles(60, seed=1)
    positions = marker_positions_batch(template, markers, thetas)
    model, _, report = calibrate_subject(positions, template, markers)
    assert model.side == "left" and report["residual_after_mm"] < 0.5
    assert np.allclose(report["scales"], 1.0, atol=0.03)


def test_calibration_input_errors():
    template = load_template()
    layout = load_layout("glove-13")
    with pytest.raises(InputError, match="must be"):
        calibrate_subject(np.zeros((5, 4, 3)), template, layout)
    with pytest.raises(InputError, match="at least 3"):
        calibrate_subject(np.full((5, 13, 3), np.nan), template, layout)
