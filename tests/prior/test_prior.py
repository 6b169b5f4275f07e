"""Posture prior: canonical posture library, PCA prior, persistence, soft prior matrix."""

from pathlib import Path

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.model.skeleton import N_POSTURE, default_joint_limits
from handmocap.core.prior import (
    DEFAULT_PRIOR_PATH,
    HELDOUT_GRASPS,
    PosturePrior,
    build_default_prior,
    build_prior,
    build_prior_from_results,
    canonical_postures,
    default_prior_samples,
    describe_prior,
    heldout_grasp_postures,
    load_default_prior,
    prior_grasp_postures,
    prior_postures,
    soft_prior_matrix,
)

LOWER, UPPER = (limit[6:] for limit in default_joint_limits())


@pytest.fixture(scope="module")
def prior() -> PosturePrior:
    return build_default_prior(seed=0)


def test_canonical_postures_are_within_the_default_limits():
    postures = canonical_postures()
    assert len(postures) >= 40
    for name, posture in postures.items():
        assert posture.shape == (N_POSTURE,), name
        assert np.all(posture >= LOWER - 1e-12) and np.all(posture <= UPPER + 1e-12), name


def test_canonical_library_has_taxonomy_grasps_and_gestures():
    names = set(canonical_postures())
    for expected in ("large_wrap", "small_wrap", "power_sphere", "tripod", "lateral_pinch", "tip_pinch",
                     "fixed_hook", "platform", "flat", "fist", "point", "ok_sign", "count_3", "spread"):
        assert expected in names


def test_heldout_postures_are_not_in_the_prior_set():
    prior_set = prior_postures()
    heldout = heldout_grasp_postures()
    assert set(heldout) == set(HELDOUT_GRASPS)
    assert not set(heldout) & set(prior_set)
    assert not set(heldout) & set(prior_grasp_postures())
    assert set(prior_set) | set(heldout) == set(canonical_postures())
    for name, posture in heldout.items():
        distance = min(np.abs(posture - other).max() for other in prior_set.values())
        assert distance > np.radians(5.0), name


def test_pca_components_orthonormal_sorted_and_variance_bounded(prior):
    count = prior.n_components
    assert prior.components.shape == (N_POSTURE, count)
    np.testing.assert_allclose(prior.components.T @ prior.components, np.eye(count), atol=1e-10)
    assert np.all(np.diff(prior.stddev) <= 1e-12)
    assert np.all(np.diff(prior.explained_variance_ratio) <= 1e-12)
    assert prior.explained_variance_ratio.sum() <= 1.0 + 1e-12
    assert np.all(np.diff(prior.cumulative_variance()) >= 0)


def test_pca_limits_cover_the_training_data(prior):
    samples = default_prior_samples(seed=0)
    projections = (samples - prior.mean) @ prior.components
    assert np.all(projections >= prior.alpha_lower - 1e-9) and np.all(projections <= prior.alpha_upper + 1e-9)
    assert np.all(samples >= prior.angle_lower - 1e-9) and np.all(samples <= prior.angle_upper + 1e-9)
    assert np.all(prior.angle_lower >= LOWER - 1e-12) and np.all(prior.angle_upper <= UPPER + 1e-12)
    assert prior.n_samples == len(samples)


def test_pca_reconstructs_a_low_rank_data_set_exactly():
    rng = np.random.default_rng(1)
    basis = np.linalg.qr(rng.normal(size=(N_POSTURE, 2)))[0]
    postures = 0.3 + rng.normal(size=(50, 2)) * [0.4, 0.1] @ basis.T
    prior = build_prior(postures, "synthetic")
    assert prior.cumulative_variance()[1] == pytest.approx(1.0)
    plane, mean = prior.subspace(2)
    rebuilt = mean + (postures - mean) @ plane @ plane.T
    np.testing.assert_allclose(rebuilt, postures, atol=1e-10)


def test_save_load_round_trip(prior, tmp_path):
    path = tmp_path / "prior.npz"
    prior.save(path)
    loaded = PosturePrior.load(path)
    for field in ("mean", "components", "stddev", "explained_variance_ratio", "alpha_lower", "alpha_upper",
                  "angle_lower", "angle_upper"):
        np.testing.assert_array_equal(getattr(loaded, field), getattr(prior, field))
    assert loaded.source == prior.source and loaded.n_samples == prior.n_samples
    assert [p.name for p in tmp_path.iterdir()] == ["prior.npz"]


@pytest.mark.parametrize("postures", [
    np.zeros((2, N_POSTURE)),
    np.zeros((10, 19)),
    np.zeros(N_POSTURE),
    np.vstack([np.zeros((5, N_POSTURE)), np.full((1, N_POSTURE), np.nan)]),
])
def test_bad_postures_are_rejected(postures):
    with pytest.raises(InputError):
        build_prior(postures, "bad")


def test_bad_files_are_rejected(prior, tmp_path):
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip file at all")
    with pytest.raises(InputError):
        PosturePrior.load(garbage)
    with pytest.raises(InputError):
        PosturePrior.load(tmp_path / "missing.npz")
    incomplete = tmp_path / "incomplete.npz"
    np.savez(incomplete, mean=prior.mean)
    with pytest.raises(InputError):
        PosturePrior.load(incomplete)
    broken = tmp_path / "broken.npz"
    fields = {name: getattr(prior, name) for name in ("mean", "stddev", "explained_variance_ratio",
                                                      "alpha_lower", "alpha_upper", "angle_lower",
                                                      "angle_upper")}
    np.savez(broken, components=2.0 * prior.components, source="x", n_samples=3, **fields)
    with pytest.raises(InputError, match="orthonormal"):
        PosturePrior.load(broken)


def test_subspace_dimension_is_checked(prior):
    basis, mean = prior.subspace(3)
    assert basis.shape == (N_POSTURE, 3) and mean.shape == (N_POSTURE,)
    for dims in (0, prior.n_components + 1):
        with pytest.raises(InputError):
            prior.subspace(dims)


def test_default_prior_file_loads_and_is_up_to_date(prior):
    repo = Path(__file__).resolve().parents[2]
    assert DEFAULT_PRIOR_PATH.resolve() == repo / "resources" / "priors" / "default_prior.npz"
    shipped = load_default_prior()
    assert shipped is load_default_prior()
    assert shipped.cumulative_variance()[5] >= 0.85
    np.testing.assert_allclose(shipped.components, prior.components, atol=1e-6)
    np.testing.assert_allclose(shipped.stddev, prior.stddev, atol=1e-6)


def test_describe_prior_lists_every_component(prior):
    text = describe_prior(prior)
    assert len(text.splitlines()) == 3 + prior.n_components
    assert f"{100 * prior.cumulative_variance()[5]:.2f} %" in text


def test_prior_from_results_drops_nan_frames(tmp_path):
    rng = np.random.default_rng(2)
    paths = []
    for index in range(2):
        angles = rng.uniform(0.0, 0.5, (30, 26))
        angles[::5, 10] = np.nan
        path = tmp_path / f"take{index}.npz"
        np.savez(path, joint_angles=angles)
        paths.append(path)
    prior = build_prior_from_results(paths)
    assert prior.n_samples == 2 * 24
    assert "take0.npz" in prior.source
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, joint_angles=np.zeros((5, 20)))
    for bad in ([], [wrong], [tmp_path / "missing.npz"]):
        with pytest.raises(InputError):
            build_prior_from_results(bad)


def test_soft_prior_matrix(prior):
    dims = 4
    basis, mean = prior.subspace(dims)
    projector = soft_prior_matrix(prior, dims, omega4=1.0, omega5=0.0)
    np.testing.assert_allclose(projector @ projector, projector, atol=1e-12)
    np.testing.assert_allclose(projector @ basis, 0.0, atol=1e-12)
    soft = soft_prior_matrix(prior, dims, omega4=1.0, omega5=0.5)
    np.testing.assert_allclose(soft, soft.T, atol=1e-12)
    eigenvalues = np.linalg.eigvalsh(soft)
    assert eigenvalues.min() > 0.0 and eigenvalues.max() <= 1.0 + 1e-12
    # in-subspace deviations are penalised less along components of larger variance
    first, last = (np.linalg.norm(soft @ basis[:, k]) for k in (0, dims - 1))
    assert first < last < 1.0
    with pytest.raises(InputError):
        soft_prior_matrix(prior, dims, omega4=0.0, omega5=1.0)
