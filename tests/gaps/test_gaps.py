"""Gap detection, fills, fill check, fill-all and the gap-fill evaluation on the real recording."""


import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.evaluation.gaps import evaluate_gap_fill
from handmocap.core.gaps import (
    ModelContext,
    check_gap,
    fill_all,
    fill_codes,
    fill_gap,
    fill_linear,
    fill_method_names,
    fill_model,
    fill_pattern,
    fill_rigid,
    fill_spline,
    find_gaps,
    minimum_acceleration_interpolation,
    recommend,
)
from handmocap.core.io import Take
from handmocap.core.model import load_layout, load_template
from handmocap.core.model.kinematics import rotation_from_vector
from handmocap.core.simulate import simulate_take

needs_real = pytest.mark.skipif(not REAL_RECORDING.exists(), reason="shared data absent")


def straight_line(n_frames: int = 60) -> np.ndarray:
    frames = np.arange(n_frames)[:, None]
    return np.array([10.0, -20.0, 300.0]) + frames * np.array([1.5, -0.5, 2.0])


def circle(n_frames: int = 200, radius: float = 80.0, period: float = 100.0) -> np.ndarray:
    phase = 2.0 * np.pi * np.arange(n_frames) / period
    return np.column_stack([radius * np.cos(phase), radius * np.sin(phase), np.full(n_frames, 500.0)])


def rigid_cluster(n_frames: int = 80) -> np.ndarray:
    """(F, 5, 3): five points of one rigid body rotating and translating."""
    local = np.array([[0.0, 0.0, 0.0], [60.0, 0.0, 0.0], [0.0, 45.0, 0.0], [10.0, 20.0, 30.0], [40.0, 30.0, -15.0]])
    time = np.arange(n_frames) / 100.0
    rotations = np.stack([rotation_from_vector(np.array([0.8 * t, 0.3 * np.sin(3 * t), 1.2 * t])) for t in time])
    translations = np.column_stack([200 * time, 50 * np.sin(2 * time), 400 + 30 * time ** 2])
    return np.einsum("fij,mj->fmi", rotations, local) + translations[:, None]


def with_gap(trajectory: np.ndarray, start: int, length: int) -> np.ndarray:
    hidden = trajectory.copy()
    hidden[start:start + length] = np.nan
    return hidden


def test_find_gaps_closed_open_and_fully_missing():
    positions = np.zeros((20, 3, 3)) + 1.0
    positions[0:3, 0] = np.nan
    positions[8:11, 0] = np.nan
    positions[17:, 0] = np.nan
    positions[:, 1] = np.nan
    positions[5, 2] = np.nan
    take = Take(["a", "b", "c"], positions, 100.0)
    gaps = find_gaps(take)
    assert [(g.name, g.start, g.length, g.open) for g in gaps] == [
        ("a", 0, 3, True), ("a", 8, 3, False), ("a", 17, 3, True), ("c", 5, 1, False)]
    assert gaps[1].end == 11 and gaps[0].marker == 0 and gaps[3].marker == 2


def test_linear_and_spline_exact_on_a_straight_line():
    line = straight_line()
    for fill in (fill_linear, fill_spline):
        assert np.allclose(fill(with_gap(line, 20, 15), 20, 15), line[20:35], atol=1e-9)


def test_spline_exact_on_a_cubic_and_close_on_a_circle():
    time = np.arange(50.0)[:, None]
    cubic = np.array([1.0, 2.0, -1.0]) + time * np.array([0.5, -0.2, 0.1]) + 0.01 * time ** 3 * np.array([1, 2, -3])
    assert np.allclose(fill_spline(with_gap(cubic, 20, 12), 20, 12), cubic[20:32], atol=1e-8)
    ring = circle()
    spline_error = np.linalg.norm(fill_spline(with_gap(ring, 50, 20), 50, 20) - ring[50:70], axis=1).max()
    linear_error = np.linalg.norm(fill_linear(with_gap(ring, 50, 20), 50, 20) - ring[50:70], axis=1).max()
    assert spline_error < 1.0 < 10.0 < linear_error


def test_pattern_fill_exact_for_a_translated_donor():
    donor = circle()
    marker = donor + np.array([12.0, -4.0, 7.0])
    assert np.allclose(fill_pattern(with_gap(marker, 60, 30), 60, 30, donor), marker[60:90], atol=1e-9)
    drifting = donor + np.arange(len(donor))[:, None] * np.array([0.1, 0.2, 0.0])
    assert np.allclose(fill_pattern(with_gap(drifting, 60, 30), 60, 30, donor), drifting[60:90], atol=1e-9)


def test_rigid_body_fill_exact_for_a_rigid_cluster():
    cluster = rigid_cluster()
    filled = fill_rigid(with_gap(cluster[:, 4], 30, 25), 30, 25, cluster[:, :3])
    assert np.allclose(filled, cluster[30:55, 4], atol=1e-9)


def test_minimum_acceleration_system_is_a_c1_cubic():
    rng = np.random.default_rng(1)
    before, after = rng.normal(size=(2, 26)), rng.normal(size=(2, 26))
    length = 17
    full = np.concatenate([before, minimum_acceleration_interpolation(before, after, length), after])
    assert np.allclose(np.diff(full, n=4, axis=0), 0.0, atol=1e-10)  # one cubic through all frames
    assert np.allclose(full[:2], before) and np.allclose(full[-2:], after)
    # the fill is the cubic through the four fixed frames: same values and velocities at both gap ends
    time = np.arange(length + 4.0)
    ends = [0, 1, length + 2, length + 3]
    coefficients = np.polynomial.polynomial.polyfit(time[ends], full[ends], 3)
    assert np.allclose(np.polynomial.polynomial.polyval(time, coefficients).T, full, atol=1e-9)
    cubic_truth = 0.3 - 0.1 * time + 0.02 * time ** 2 - 0.004 * time ** 3
    inner = minimum_acceleration_interpolation(cubic_truth[:2, None], cubic_truth[-2:, None], length)
    assert np.allclose(inner[:, 0], cubic_truth[2:-2], atol=1e-9)


def test_fills_refuse_what_they_cannot_do():
    line = straight_line()
    with pytest.raises(InputError, match="needs 1 observed frame"):
        fill_linear(with_gap(line, 0, 5), 0, 5)
    with pytest.raises(InputError, match="needs 2 observed frame"):
        fill_spline(np.vstack([line[:1], with_gap(line[1:], 0, 5)]), 1, 5)
    cluster = rigid_cluster()
    with pytest.raises(InputError, match="at least 3 donor"):
        fill_rigid(with_gap(cluster[:, 4], 30, 5), 30, 5, cluster[:, :2])
    collinear = np.stack([cluster[:, 0], cluster[:, 1], 0.5 * (cluster[:, 0] + cluster[:, 1])], axis=1)
    with pytest.raises(InputError, match="collinear"):
        fill_rigid(with_gap(cluster[:, 4], 30, 5), 30, 5, collinear)
    with pytest.raises(InputError, match="not observed through the gap"):
        fill_pattern(with_gap(cluster[:, 4], 30, 5), 30, 5, with_gap(cluster[:, 0], 32, 1))
    take = Take(["a", "b", "c", "d", "e"], rigid_cluster(), 100.0)
    with pytest.raises(InputError, match="needs a hand model"):
        fill_gap(take.marker_positions, 4, 30, 5, "model")
    with pytest.raises(InputError, match="unknown fill method"):
        fill_gap(take.marker_positions, 4, 30, 5, "cubic")


def test_fill_all_provenance_and_measured_samples_unchanged():
    positions = rigid_cluster(120)
    positions[40:52, 4] = np.nan   # closed, 12 frames
    positions[70:75, 3] = np.nan   # closed, 5 frames
    positions[90:110, 2] = np.nan  # closed but longer than max_gap
    positions[:6, 1] = np.nan      # open at the start
    take = Take(["a", "b", "c", "d", "e"], positions, 100.0)
    filled, provenance = fill_all(take, max_gap=15)
    measured = ~take.missing_mask
    assert np.array_equal(filled[measured], positions[measured])
    assert (provenance[measured] == 0).all()
    assert (provenance[90:110, 2] == -1).all() and (provenance[:6, 1] == -1).all()
    assert set(provenance[40:52, 4]) <= set(fill_codes().values()) and len(set(provenance[40:52, 4])) == 1
    assert np.isfinite(filled[40:52, 4]).all() and np.isfinite(filled[70:75, 3]).all()
    truth = rigid_cluster(120)
    assert np.abs(filled[40:52, 4] - truth[40:52, 4]).max() < 1.0
    linear, codes = fill_all(take, max_gap=15, method="linear")
    assert (codes[40:52, 4] == fill_codes()["linear"]).all() and (codes[70:75, 3] == 1).all()
    assert np.array_equal(linear[measured], positions[measured])
    with pytest.raises(InputError, match="needs a marker layout"):
        fill_all(take, max_gap=15, method="model")


def test_check_gap_hides_a_stretch_next_to_the_gap_and_recommends():
    positions = rigid_cluster(200)
    positions[100:110, 4] = np.nan
    take = Take(["a", "b", "c", "d", "e"], positions, 100.0)
    gap = find_gaps(take)[0]
    check = check_gap(take, gap)
    assert check.test_start + gap.length + 10 <= gap.start or check.test_start - 10 >= gap.end
    assert abs(check.test_start - gap.start) < 3 * gap.length
    assert set(check.errors_mm) == {"linear", "spline", "pattern", "rigid", "pca"} and "model" in check.reasons
    assert check.errors_mm["rigid"] < 1e-6 and check.errors_mm["pca"] < 1e-6   # both exact on a rigid body
    assert recommend(take, gap) in ("rigid", "pca")


def test_model_fill_on_a_simulated_take_with_true_angles():
    simulated = simulate_take(layout="glove-13", n_frames=120, seed=2, noise_mm=0.0)
    model, layout = load_template(), load_layout("glove-13")
    context = ModelContext.for_take(simulated.take.marker_names, model, layout)
    positions = context.layout_positions(simulated.take.marker_positions)
    marker = context.markers.names.index("index_tip")
    hidden = positions.copy()
    hidden[50:60, marker] = np.nan
    filled = fill_model(hidden, 50, 10, marker, simulated.truth["joint_angles"], model, context.markers)
    assert np.linalg.norm(filled - positions[50:60, marker], axis=1).mean() < 1.0


@pytest.fixture
def real_take(real_recording):
    return real_recording


@needs_real
def test_real_recording_thumb_gaps_filled(real_take):
    layout = load_layout("glove-13")
    gaps = [gap for gap in find_gaps(real_take) if not gap.open]
    assert gaps and {gap.name for gap in gaps} == {"thumb_tip"}
    context = ModelContext.for_take(real_take.marker_names, load_template(), layout)
    check = check_gap(real_take, gaps[0], context)
    assert set(check.errors_mm) == set(fill_method_names())
    filled, provenance = fill_all(real_take, max_gap=100, layout=layout)
    measured = ~real_take.missing_mask
    assert np.array_equal(filled[measured], real_take.marker_positions[measured])
    for gap in gaps:
        if gap.length <= 100:
            assert (provenance[gap.start:gap.end, gap.marker] > 0).all()


@needs_real
def test_real_recording_model_fill_accuracy(real_take):
    evaluation = evaluate_gap_fill(real_take, load_template(), load_layout("glove-13"), (10, 20, 40), n_trials=30)
    errors = evaluation["mean_error_mm"]
    assert all(count == 30 for count in evaluation["trials"]["model"].values())
    assert errors["model"][40] <= errors["spline"][40]
    assert errors["model"][20] < 5.0
