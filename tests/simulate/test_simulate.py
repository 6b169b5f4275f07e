"""Simulator: motions, marker takes with noise, occlusions, ghosts, unlabelled export, truth files."""

import time

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.model import load_layout
from handmocap.core.model.skeleton import HandProportions, default_joint_limits
from handmocap.core.prior import heldout_grasp_postures
from handmocap.core.simulate import (
    MOTIONS,
    WORKSPACE_CENTRE,
    load_truth,
    minimum_jerk_trajectory,
    save_truth,
    simulate_joint_angles,
    simulate_take,
)

LOWER, UPPER = default_joint_limits()


def gap_lengths(visible: np.ndarray) -> np.ndarray:
    """Lengths (frames) of every run of False in each column of ``visible (F, M)``."""
    lengths = []
    for column in visible.T:
        change = np.diff(np.concatenate([[1], column.astype(int), [1]]))
        lengths.extend(np.flatnonzero(change == 1) - np.flatnonzero(change == -1))
    return np.array(lengths)


@pytest.fixture(scope="module")
def occluded():
    return simulate_take("dense", n_frames=2000, seed=3, noise_mm=0.3, ghost_rate=0.05, occlusion=True)


@pytest.fixture(scope="module")
def unlabelled():
    return simulate_take("glove-13", n_frames=800, seed=5, noise_mm=0.3, ghost_rate=0.1, occlusion=True,
                         unlabelled=True)


@pytest.mark.parametrize("motion", MOTIONS)
def test_joint_angles_stay_within_limits_and_move_at_human_speeds(motion):
    thetas = simulate_joint_angles(1500, seed=2, motion=motion)
    assert thetas.shape == (1500, 26)
    assert np.all(thetas >= LOWER - 1e-12) and np.all(thetas <= UPPER + 1e-12)
    finger_speed = np.degrees(np.abs(np.diff(thetas[:, 6:], axis=0))).max() * 100.0
    assert 50.0 < finger_speed < 800.0
    offset = np.abs(thetas[:, :3] - WORKSPACE_CENTRE)
    assert np.all(offset <= [150.0, 150.0, 100.0])
    assert np.abs(np.diff(thetas[:, 3:6], axis=0)).max() < 0.1


def test_joint_angles_are_deterministic_per_seed():
    np.testing.assert_array_equal(simulate_joint_angles(300, seed=7), simulate_joint_angles(300, seed=7))
    assert not np.array_equal(simulate_joint_angles(300, seed=7), simulate_joint_angles(300, seed=8))


def test_heldout_motion_reaches_the_heldout_grasps():
    fingers = simulate_joint_angles(3000, seed=1, motion="heldout")[:, 6:]
    reached = [np.abs(fingers - posture).max(axis=1).min() < np.radians(10.0)
               for posture in heldout_grasp_postures().values()]
    assert sum(reached) >= 3


def test_bad_arguments_are_rejected():
    with pytest.raises(InputError):
        simulate_joint_angles(100, motion="dance")
    with pytest.raises(InputError):
        simulate_joint_angles(0)
    with pytest.raises(InputError):
        simulate_take("dense", n_frames=10, ghost_rate=1.5)


def test_minimum_jerk_passes_through_keys_with_zero_velocity():
    values = np.array([[0.0], [1.0], [1.0], [-2.0]])
    times = np.array([0.0, 0.5, 0.8, 1.6])
    trajectory = minimum_jerk_trajectory(values, times, 201, 100.0)[:, 0]
    np.testing.assert_allclose(trajectory[[0, 50, 80, 160, 200]], [0.0, 1.0, 1.0, -2.0, -2.0])
    assert abs(trajectory[51] - trajectory[49]) < 1e-3


def test_take_shapes_and_truth(occluded):
    take, truth = occluded.take, occluded.truth
    names = load_layout("dense").names
    frames, count = 2000, len(names)
    ghosts = truth["ghost_positions"].shape[1]
    assert take.marker_positions.shape == (frames, count + ghosts, 3)
    assert take.marker_names[:count] == names
    assert take.frame_rate == 100.0
    assert truth["joint_angles"].shape == (frames, 26)
    assert truth["marker_positions"].shape == (frames, count, 3)
    assert list(truth["marker_names"]) == names
    assert truth["visible"].shape == (frames, count) and truth["visible"].dtype == bool
    assert not np.isnan(truth["marker_positions"]).any()
    np.testing.assert_array_equal(truth["joint_angles"], simulate_joint_angles(frames, seed=3))
    np.testing.assert_array_equal(np.isnan(take.marker_positions[:, :count, 0]), ~truth["visible"])


def test_take_is_deterministic_per_seed():
    first = simulate_take("glove-13", n_frames=300, seed=11, noise_mm=0.3, ghost_rate=0.1, occlusion=True)
    second = simulate_take("glove-13", n_frames=300, seed=11, noise_mm=0.3, ghost_rate=0.1, occlusion=True)
    other = simulate_take("glove-13", n_frames=300, seed=12, noise_mm=0.3, ghost_rate=0.1, occlusion=True)
    np.testing.assert_array_equal(first.take.marker_positions, second.take.marker_positions)
    assert first.take.marker_names == second.take.marker_names
    assert not np.array_equal(first.truth["joint_angles"], other.truth["joint_angles"])


def test_noise_level_matches_the_request(occluded):
    count = occluded.truth["marker_positions"].shape[1]
    error = occluded.take.marker_positions[:, :count] - occluded.truth["marker_positions"]
    assert np.nanstd(error) == pytest.approx(0.3, rel=0.05)
    assert abs(np.nanmean(error)) < 0.01
    clean = simulate_take("grasp-4", n_frames=50, seed=3)
    np.testing.assert_array_equal(clean.take.marker_positions, clean.truth["marker_positions"])


def test_occlusion_gaps_are_realistic(occluded):
    visible = occluded.truth["visible"]
    gaps = gap_lengths(visible)
    assert 0.8 < visible.mean() < 0.99
    assert len(gaps) > 20
    assert 3 <= np.median(gaps) <= 60
    assert np.mean(gaps <= 100) > 0.8
    assert visible.sum(axis=1).min() >= 1
    assert not occluded.truth["visible"].all(axis=0).all()


def test_occlusion_never_hides_every_marker_of_a_sparse_layout():
    simulated = simulate_take("grasp-4", n_frames=1500, seed=9, occlusion=True, motion="grasps")
    assert simulated.truth["visible"].any(axis=1).all()


def test_ghosts_appear_at_the_requested_rate(occluded):
    ghosts = occluded.truth["ghost_positions"]
    alive = ~np.isnan(ghosts).any(axis=2)
    assert alive.any(axis=1).mean() == pytest.approx(0.05, abs=0.01)
    lives = gap_lengths(~alive)             # a column holds ghosts one after the other, apart
    assert lives.min() >= 1 and lives.max() <= 10
    assert ghosts.shape[1] < len(lives) / 5
    count = occluded.truth["marker_positions"].shape[1]
    ghost_columns = occluded.take.marker_positions[:, count:]
    np.testing.assert_array_equal(~np.isnan(ghost_columns).any(axis=2), alive)
    assert all(name.startswith("ghost_") for name in occluded.take.marker_names[count:])
    frames, columns = np.nonzero(alive)
    offsets = ghosts[frames, columns][:, None] - occluded.truth["marker_positions"][frames]
    assert np.linalg.norm(offsets, axis=2).min(axis=1).max() <= 60.0 + 1e-9


def test_unlabelled_points_are_shuffled_and_consistent_with_truth(unlabelled):
    take, truth = unlabelled.take, unlabelled.truth
    points = take.marker_positions
    point_marker = truth["point_marker"]
    assert point_marker.shape == points.shape[:2]
    assert take.marker_names[0] == "point_000"
    present = ~np.isnan(points).any(axis=2)
    frames, columns = np.nonzero(point_marker >= 0)
    markers = point_marker[frames, columns]
    assert np.all(truth["visible"][frames, markers])
    assert len(frames) == truth["visible"].sum()
    error = points[frames, columns] - truth["marker_positions"][frames, markers]
    assert np.abs(error).max() < 2.0
    ghost_points = (point_marker == -1) & present
    alive = ~np.isnan(truth["ghost_positions"]).any(axis=2)
    np.testing.assert_array_equal(ghost_points.sum(axis=1), alive.sum(axis=1))
    assert np.all(point_marker[~present] == -1)
    assert len(np.unique(point_marker[:, 0])) > 5
    # points fill the first columns; NaN padding only after them
    assert np.all(np.diff(present.astype(int), axis=1) <= 0)


def test_truth_round_trip(unlabelled, tmp_path):
    path = tmp_path / "truth.npz"
    save_truth(unlabelled.truth, path)
    loaded = load_truth(path)
    assert set(loaded) == set(unlabelled.truth)
    for key, value in unlabelled.truth.items():
        np.testing.assert_array_equal(loaded[key], value)
    assert loaded["marker_names"].dtype.kind == "U"
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"nonsense")
    with pytest.raises(InputError):
        load_truth(bad)
    partial = tmp_path / "partial.npz"
    np.savez(partial, joint_angles=np.zeros((2, 26)))
    with pytest.raises(InputError):
        load_truth(partial)


def test_dense_take_of_2000_frames_simulates_in_under_two_seconds():
    simulate_take("dense", n_frames=50, seed=0, occlusion=True, ghost_rate=0.05)
    start = time.perf_counter()
    simulate_take("dense", n_frames=2000, seed=1, noise_mm=0.3, occlusion=True, ghost_rate=0.05)
    assert time.perf_counter() - start < 2.0


@pytest.mark.slow
def test_reproportioned_hand_changes_the_markers():
    proportions = HandProportions().scaled(finger_scale=1.15, palm_width_scale=1.1)
    default = simulate_take("glove-13", n_frames=20, seed=4)
    bigger = simulate_take("glove-13", n_frames=20, seed=4, proportions=proportions)
    np.testing.assert_array_equal(default.truth["joint_angles"], bigger.truth["joint_angles"])
    spread = np.linalg.norm(np.ptp(bigger.truth["marker_positions"][0], axis=0))
    assert spread > 1.05 * np.linalg.norm(np.ptp(default.truth["marker_positions"][0], axis=0))
