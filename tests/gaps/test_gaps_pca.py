"""PCA marker-intercorrelation gap fill (Gløersen & Federolf 2016), the fill check's ranking, and the
evaluation of many gaps hidden at once through the fill of the command line."""


import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.evaluation.gaps import evaluate_hidden_gaps, hide_gaps
from handmocap.core.gaps import FillCheck, Gap, fill_gap, fill_linear, fill_pca, fill_spline
from handmocap.core.gaps.check import LOCAL_HORIZON_S
from handmocap.core.io import Take
from handmocap.core.model import load_layout
from handmocap.core.simulate import simulate_take

needs_real = pytest.mark.skipif(not REAL_RECORDING.exists(), reason="shared data absent")
FINGERS = ("thumb_tip", "thumb_middle", "index_tip", "index_middle", "middle_tip", "middle_middle", "ring_tip",
           "ring_middle", "little_tip", "little_middle")


def hidden(positions: np.ndarray, marker: int, start: int, length: int) -> np.ndarray:
    copy = positions.copy()
    copy[start:start + length, marker] = np.nan
    return copy


@pytest.fixture(scope="module")
def simulated():
    return simulate_take(layout="glove-13", n_frames=600, seed=4, noise_mm=0.3).take


def test_pca_fill_reconstructs_simulated_gaps(simulated):
    positions = simulated.marker_positions
    rng = np.random.default_rng(0)
    errors: dict[str, list[np.ndarray]] = {"pca": [], "linear": []}
    for _ in range(20):
        marker, length = int(rng.integers(3, 13)), int(rng.choice([20, 40, 60]))
        start = int(rng.integers(20, len(positions) - length - 20))
        gap = hidden(positions, marker, start, length)
        truth = positions[start:start + length, marker]
        errors["pca"].append(np.linalg.norm(fill_pca(gap, marker, start, length) - truth, axis=1))
        errors["linear"].append(np.linalg.norm(fill_linear(gap[:, marker], start, length) - truth, axis=1))
    pca, linear = np.concatenate(errors["pca"]), np.concatenate(errors["linear"])
    assert pca.mean() < 2.5 and pca.mean() < 0.25 * linear.mean()
    assert np.percentile(pca, 95) < 0.5 * np.percentile(linear, 95)


def test_pca_fill_joins_the_measured_ends_and_ignores_the_gap_samples(simulated):
    positions = simulated.marker_positions
    marker = simulated.marker_names.index("ring_tip")
    start, length = 250, 30
    filled = fill_pca(positions, marker, start, length)           # the gap samples are present but ignored
    np.testing.assert_allclose(filled, fill_pca(hidden(positions, marker, start, length), marker, start, length))
    path = np.vstack([positions[start - 1, marker], filled, positions[start + length, marker]])
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    measured_steps = np.linalg.norm(np.diff(positions[start - 5:start, marker], axis=0), axis=1)
    assert steps[0] < 3.0 * measured_steps.max() + 0.5 and steps[-1] < 3.0 * measured_steps.max() + 0.5


def test_pca_fill_works_on_a_window_around_the_gap(simulated):
    positions = simulated.marker_positions
    marker = simulated.marker_names.index("middle_tip")
    far = hidden(positions, marker, 300, 20)
    changed = far.copy()
    changed[:50] += 40.0                                           # more than a window away from the gap
    np.testing.assert_allclose(fill_pca(far, marker, 300, 20, window=200), fill_pca(changed, marker, 300, 20,
                                                                                     window=200))


def test_pca_fill_refuses_what_it_cannot_do(simulated):
    positions = simulated.marker_positions
    with pytest.raises(InputError, match="measured frame on each side"):
        fill_pca(hidden(positions, 0, 0, 10), 0, 0, 10)
    lonely = np.full_like(positions, np.nan)
    lonely[:, :2] = positions[:, :2]
    lonely[100:120, 0] = np.nan
    with pytest.raises(InputError, match="2 other markers"):
        fill_pca(lonely, 0, 100, 20)
    with pytest.raises(InputError, match="marker 99"):
        fill_pca(positions, 99, 100, 10)


def check_with(length: int, stretches: dict[str, list[tuple[float, float]]]) -> FillCheck:
    check = FillCheck(Gap(0, "m", 100, length), (50, 150), frame_rate=100.0)
    for method, per_stretch in stretches.items():
        check.stretch_errors_mm[method] = per_stretch
        check.errors_mm[method] = float(np.mean([mean for mean, _ in per_stretch]))
        check.worst_mm[method] = float(np.max([worst for _, worst in per_stretch]))
    return check


def test_ranking_keeps_pca_first_unless_clearly_beaten_on_a_short_gap():
    close = {"pca": [(1.0, 2.0), (1.0, 2.0)], "spline": [(0.8, 1.8), (0.3, 0.5)]}
    assert check_with(10, close).ranking() == ["pca", "spline"]
    clear = {"pca": [(1.0, 2.0), (1.0, 2.0)], "spline": [(0.4, 0.9), (0.3, 0.5)], "linear": [(3.0, 5.0)] * 2}
    assert check_with(10, clear).ranking() == ["spline", "pca", "linear"]
    long = int(LOCAL_HORIZON_S * 100) + 1
    assert check_with(long, clear).ranking()[0] == "pca"
    assert check_with(10, {"spline": [(0.4, 0.9)] * 2, "linear": [(0.3, 2.0)] * 2}).ranking() == ["spline", "linear"]


@pytest.fixture
def real_half(real_recording):
    take = real_recording
    return Take(list(take.marker_names), take.marker_positions[:take.n_frames // 2], take.frame_rate)


@needs_real
def test_pca_fill_beats_linear_and_spline_on_real_gaps(real_half):
    rng = np.random.default_rng(5)
    columns = [real_half.marker_names.index(name) for name in FINGERS]
    errors: dict[str, list[float]] = {"pca": [], "linear": [], "spline": []}
    for length in (20, 40, 80):
        take, gaps = hide_gaps(real_half, columns, length, 8, rng)
        for column, start in gaps:
            truth = real_half.marker_positions[start:start + length, column]
            positions = take.marker_positions
            errors["pca"].append(np.linalg.norm(fill_gap(positions, column, start, length, "pca") - truth,
                                                axis=1).mean())
            errors["linear"].append(np.linalg.norm(fill_linear(positions[:, column], start, length) - truth,
                                                   axis=1).mean())
            errors["spline"].append(np.linalg.norm(fill_spline(positions[:, column], start, length) - truth,
                                                   axis=1).mean())
    assert np.mean(errors["pca"]) < 0.5 * np.mean(errors["spline"]) < np.mean(errors["linear"])


@needs_real
def test_many_hidden_gaps_filled_by_auto_and_pca(real_half):
    result = evaluate_hidden_gaps(real_half, load_layout("glove-13"), lengths=(40,), n_gaps=6, seed=1)
    assert result["gaps"][40] == 6
    for method in ("auto", "pca"):
        assert result["unfilled"][method][40] == 0
        assert result["mean_error_mm"][method][40] < 3.0
        assert result["worst_error_mm"][method][40] >= result["mean_error_mm"][method][40]
    assert result["chosen"]["pca"][40] == {"pca": 6}
