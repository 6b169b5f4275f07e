"""Marker-layout optimisation: feasibility, keyframes, the energy, PSO, greedy, subset selection, metrics."""

from itertools import combinations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from core.errors import CancelledError, InputError
from core.layout import (
    PSOSettings,
    build_problem,
    evaluate_layout,
    feasible_vertices,
    keyframes,
    layout_energies,
    layout_terms,
    motion_from_results,
    motion_set,
    optimise_greedy,
    optimise_pso,
    select_subset,
    vertex_layout,
)
from core.layout.pso import project_to_candidates, random_layouts
from core.model import load_layout, load_template, resolve_layout

SMALL_SWARM = PSOSettings(particles=200, iterations=30)


@pytest.fixture(scope="module")
def model():
    return load_template()


@pytest.fixture(scope="module")
def grasps():
    return motion_set("grasps", n_frames=1500)


@pytest.fixture(scope="module")
def problem(model, grasps):
    return build_problem(model, grasps, subspace_dims=4, n_keyframes=5)


def test_feasible_vertices_face_the_back_and_move_rigidly(model):
    vertices = feasible_vertices(model)
    assert 100 < len(vertices) < len(model.vertices) // 2
    assert (model.vertex_normals[vertices] @ model.back_direction > 0.9).all()
    assert np.isclose(model.skin_weights[vertices].max(axis=1), 1.0).all()


@pytest.mark.parametrize("name", ["grasps", "gestures", "all"])
def test_motion_sets_are_finite_joint_angles(name):
    motion = motion_set(name, n_frames=300)
    assert motion.shape == (300, 26) and np.isfinite(motion).all()


def test_motion_from_solved_results(tmp_path, grasps):
    angles = grasps[:50].copy()
    angles[3] = np.nan
    np.savez(tmp_path / "take.npz", joint_angles=angles)
    assert motion_set(str(tmp_path / "take.npz")).shape == (49, 26)
    with pytest.raises(InputError, match="empty"):
        np.savez(tmp_path / "empty.npz", joint_angles=np.full((5, 26), np.nan))
        motion_from_results([tmp_path / "empty.npz"])


def test_keyframes_spread_over_postures(grasps):
    chosen = keyframes(grasps, 6)
    assert len(set(chosen.tolist())) == 6
    postures = grasps[:, 6:]
    spread = np.linalg.norm(postures[chosen][:, None] - postures[chosen][None], axis=2)
    random = postures[np.random.default_rng(0).choice(len(postures), 6, replace=False)]
    assert spread[np.triu_indices(6, 1)].min() > np.linalg.norm(random[:, None] - random[None], axis=2)[
        np.triu_indices(6, 1)].min()


def test_batched_energy_matches_the_svd_definition(problem):
    layouts = random_layouts(np.random.default_rng(3), 50, 5, problem.n_candidates)
    batched = layout_energies(problem, layouts)
    reference = np.array([layout_terms(problem, layout)["energy"] for layout in layouts])
    finite = np.isfinite(reference) & (np.abs(reference) < 1e5)
    assert finite.sum() > 10
    np.testing.assert_allclose(batched[finite], reference[finite], rtol=1e-6)


def test_energy_penalises_close_markers(problem):
    layout = random_layouts(np.random.default_rng(4), 1, 5, problem.n_candidates)[0]
    duplicated = layout.copy()
    duplicated[1] = duplicated[0]
    terms = layout_terms(problem, duplicated)
    assert terms["min_distance_mm"] == 0.0 and terms["distance"] == 0.0


def test_projection_keeps_markers_distinct(problem):
    tree = cKDTree(problem.candidates.rest_positions)
    point = problem.candidates.rest_positions[7]
    projected = project_to_candidates(tree, np.tile(point, (3, 4, 1)))
    assert (projected[:, 0] == 7).all()
    assert all(len(set(row.tolist())) == 4 for row in projected)


def test_pso_improves_reports_progress_and_is_seedable(problem):
    reports = []
    result = optimise_pso(problem, 5, SMALL_SWARM, seed=1, progress=lambda f, e: reports.append((f, e)))
    again = optimise_pso(problem, 5, SMALL_SWARM, seed=1)
    assert np.array_equal(result.vertices, again.vertices)
    assert len(result.history) == SMALL_SWARM.iterations + 1
    assert (np.diff(result.history) <= 0).all() and result.history[-1] < result.history[0]
    assert reports[-1] == (1.0, result.energy)
    assert len(set(result.vertices.tolist())) == 5
    assert np.isclose(layout_terms(problem, result.indices)["energy"], result.energy, rtol=1e-6)


def test_pso_can_be_cancelled(problem):
    with pytest.raises(CancelledError):
        optimise_pso(problem, 5, SMALL_SWARM, cancelled=lambda: True)


def test_greedy_swap_never_worsens_the_start(problem):
    start = random_layouts(np.random.default_rng(5), 1, 5, problem.n_candidates)[0]
    result = optimise_greedy(problem, 5, initial=start)
    assert result.energy <= layout_energies(problem, start)[0]
    assert (np.diff(result.history) < 0).all()


def test_subset_selection_is_exhaustive_for_a_small_base(model, grasps):
    base = resolve_layout(model, load_layout("glove-13"))
    problem = build_problem(model, grasps, subspace_dims=2, n_keyframes=3, candidates=base)
    result = select_subset(problem, 4)
    energies = layout_energies(problem, np.array(list(combinations(range(13), 4))))
    assert np.isclose(result.energy, energies.min())


def test_bad_marker_counts_and_motion_are_input_errors(model, problem):
    with pytest.raises(InputError, match="only"):
        optimise_pso(problem, problem.n_candidates + 1, SMALL_SWARM)
    with pytest.raises(InputError, match="at least 3 markers"):
        optimise_pso(problem, 2, SMALL_SWARM)
    with pytest.raises(InputError, match="empty"):
        build_problem(model, np.empty((0, 26)), subspace_dims=4)
    with pytest.raises(InputError, match="keyframes"):
        keyframes(np.zeros((10, 26)), 20)


def test_evaluate_layout_reports_all_metrics(model, grasps, problem):
    result = optimise_pso(problem, 5, SMALL_SWARM, seed=0)
    layout = vertex_layout(model, result.vertices)
    metrics = evaluate_layout(model, layout, grasps, subspace_dims=4, step=50, reconstruction_frames=150)
    assert 1.0 < metrics.mean_condition < metrics.worst_occluded_condition
    assert metrics.min_distance_mm > 0 and metrics.closest_pair[0] != metrics.closest_pair[1]
    assert 0 < metrics.reconstruction_mean_mm <= metrics.reconstruction_max_mm < 50
