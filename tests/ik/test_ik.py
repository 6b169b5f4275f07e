"""IK on the template hand: accuracy on simulated data, limits, missing markers, cancel, files."""

import numpy as np
import pytest

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.ik import IKSettings, solve_positions, solve_take
from handmocap.core.io import Take
from handmocap.core.model import load_layout, load_template, marker_positions_batch, resolve_layout
from handmocap.core.model.skeleton import default_joint_limits
from handmocap.core.prior import load_default_prior
from handmocap.core.simulate import simulate_take


@pytest.fixture(scope="module")
def model():
    return load_template()


@pytest.fixture(scope="module")
def dense(model):
    return resolve_layout(model, load_layout("dense"))


@pytest.fixture(scope="module")
def dense_take():
    return simulate_take(layout="dense", n_frames=300, seed=3, noise_mm=0.0)


def targets_of(simulated, names):
    return simulated.take.marker_positions[:, [simulated.take.marker_names.index(n) for n in names]]


@pytest.mark.parametrize("method", ["layered", "full"])
def test_dense_noise_free_recovers_angles(model, dense, dense_take, method):
    result = solve_positions(targets_of(dense_take, dense.names), model, dense, load_default_prior(),
                             IKSettings(method=method))
    error = np.degrees(np.abs(result.joint_angles[:, 6:] - dense_take.truth["joint_angles"][:, 6:]))
    assert error.mean() < 0.5
    assert result.mean_residual_mm < 0.05


def test_subspace_solution_lies_in_the_subspace(model, dense, dense_take):
    prior = load_default_prior()
    result = solve_positions(targets_of(dense_take, dense.names)[:50], model, dense, prior,
                             IKSettings(method="subspace", subspace_dims=4))
    basis = prior.components[:, :4]
    offset = result.joint_angles[:, 6:] - prior.mean
    off_subspace = offset - offset @ basis @ basis.T
    lower, upper = default_joint_limits()
    clipped = np.isclose(result.joint_angles[:, 6:], lower[6:]) | np.isclose(result.joint_angles[:, 6:], upper[6:])
    assert np.abs(off_subspace[~clipped.any(axis=1)]).max() < 1e-6


@pytest.mark.parametrize("method", ["layered", "subspace", "full"])
def test_never_returns_a_posture_outside_the_limits(model, dense, method):
    lower, upper = default_joint_limits()
    rng = np.random.default_rng(0)
    theta = np.zeros((40, 26))
    theta[:, 2] = 900.0
    theta[:, 6:] = rng.uniform(lower[6:] - 0.6, upper[6:] + 0.6, size=(40, 20))   # beyond the limits
    targets = marker_positions_batch(model, dense, theta)
    result = solve_positions(targets, model, dense, load_default_prior(), IKSettings(method=method))
    assert np.all(result.joint_angles[:, 6:] >= lower[6:] - 1e-9)
    assert np.all(result.joint_angles[:, 6:] <= upper[6:] + 1e-9)


def test_missing_markers_and_empty_frames(model, dense, dense_take):
    targets = targets_of(dense_take, dense.names)[:60].copy()
    targets[10:20, :5] = np.nan          # a few markers missing
    targets[30:35] = np.nan              # nothing seen: posture held
    result = solve_positions(targets, model, dense, load_default_prior())
    assert np.isnan(result.residuals_mm[10:20, :5]).all()
    assert np.nanmean(result.residuals_mm[10:20]) < 0.5
    np.testing.assert_allclose(result.joint_angles[30:35], result.joint_angles[29][None].repeat(5, axis=0))
    assert np.isfinite(result.joint_angles).all()


def test_progress_and_cancel(model, dense, dense_take):
    targets = targets_of(dense_take, dense.names)
    reported = []
    solve_positions(targets[:100], model, dense, progress=reported.append)
    assert reported[-1] == 1.0 and reported == sorted(reported)
    with pytest.raises(CancelledError):
        solve_positions(targets, model, dense, cancelled=lambda: True)


def test_solve_take_matches_names_and_rejects_foreign_takes(model, dense_take, tmp_path):
    take = dense_take.take
    shuffled = list(reversed(range(take.n_markers)))
    reordered = Take([take.marker_names[i] for i in shuffled], take.marker_positions[:50, shuffled],
                     take.frame_rate)
    result = solve_take(reordered, model, load_layout("dense"))
    assert result.mean_residual_mm < 0.1
    result.save(tmp_path / "result.npz")
    result.save_csv(tmp_path / "angles.csv")
    with np.load(tmp_path / "result.npz") as saved:
        assert saved["joint_angles"].shape == (50, 26)
        assert saved["residuals_mm"].shape == (50, 24)
    assert (tmp_path / "angles.csv").read_text().startswith("frame,time_s,wrist_tx_mm")
    foreign = Take(["a", "b"], np.zeros((5, 2, 3)), 100.0)
    with pytest.raises(InputError, match="no marker of layout"):
        solve_take(foreign, model, load_layout("dense"))


def test_layered_beats_standard_ik_on_held_out_grasps_with_four_markers():
    from handmocap.core.evaluation.ik import evaluate_ik

    figures = evaluate_ik()
    assert figures["grasp4_layered_mean_mm"] <= 0.6 * figures["grasp4_standard_mean_mm"]
    assert figures["grasp4_layered_max_mm"] <= 0.5 * figures["grasp4_standard_max_mm"]
    assert figures["dense_angle_error_deg"] < 0.5 and figures["dense_residual_mm"] < 0.05
