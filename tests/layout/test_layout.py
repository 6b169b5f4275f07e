"""Marker-layout optimisation: feasibility, keyframes, the energy, PSO, greedy, subset selection, metrics."""

from itertools import combinations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.layout import (
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
from handmocap.core.layout.pso import align_to, project_to_candidates, random_layouts
from handmocap.core.layout.workflow import error_against_markers, optimise_layout
from handmocap.core.model import load_layout, load_template, resolve_layout

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
    calls = []
    with pytest.raises(CancelledError):
        optimise_pso(problem, 5, SMALL_SWARM, progress=lambda f, e: calls.append(e), cancelled=lambda: len(calls) >= 3)
    assert len(calls) == 3


def test_pso_counts_each_distinct_layout_once(problem):
    settings = PSOSettings(particles=60, iterations=10)
    result = optimise_pso(problem, 5, settings, seed=2)
    assert 0 < result.evaluations <= settings.particles * (settings.iterations + 1)
    every = optimise_pso(problem, 5, settings, seed=2)
    assert every.energy == result.energy and every.evaluations == result.evaluations


def test_pso_starts_from_a_given_layout_and_never_ends_worse(problem):
    start = optimise_greedy(problem, 5).indices
    result = optimise_pso(problem, 5, PSOSettings(particles=50, iterations=5), seed=0, initial=start)
    assert result.energy <= layout_energies(problem, start)[0] + 1e-9


def test_align_pairs_each_marker_with_its_nearest_best_marker():
    reference = np.array([[0.0, 0, 0], [100, 0, 0], [0, 100, 0]])
    particle = reference[[2, 0, 1]] + 1.0
    aligned = align_to(reference, particle[None])
    np.testing.assert_array_equal(aligned[0], reference[[2, 0, 1]])


def test_unknown_perturbation_is_an_input_error(problem):
    with pytest.raises(InputError, match="perturbation"):
        optimise_pso(problem, 5, PSOSettings(particles=10, iterations=1, perturbation="cauchy"))


def test_pso_beats_or_ties_greedy_on_the_grasp_problem(problem):
    """A small swarm (300 × 40) on the 5-keyframe problem: the best of three seeds at most greedy's energy,
    none more than 10 % above it (the full-size comparison is tests/bench/bench_pso.py)."""
    greedy = optimise_greedy(problem, 5)
    energies = [optimise_pso(problem, 5, PSOSettings(particles=300, iterations=40), seed=seed).energy
                for seed in range(3)]
    assert min(energies) <= greedy.energy + 1e-9
    assert max(energies) <= greedy.energy * 1.10


def test_greedy_swap_never_worsens_the_start(problem):
    start = random_layouts(np.random.default_rng(5), 1, 5, problem.n_candidates)[0]
    result = optimise_greedy(problem, 5, initial=start)
    assert result.energy <= layout_energies(problem, start)[0]
    assert (np.diff(result.history) < 0).all()


def test_greedy_is_a_local_optimum_over_all_candidates(problem):
    """After greedy add-then-swap no single marker can move to any free candidate and lower the energy
    (the journal's baseline, evaluated over every feasible vertex)."""
    result = optimise_greedy(problem, 4)
    layout = result.indices
    assert result.evaluations >= 4 * (problem.n_candidates - 4)
    for slot in range(4):
        free = np.setdiff1d(np.arange(problem.n_candidates), layout)
        trials = np.repeat(layout[None], len(free), axis=0)
        trials[:, slot] = free
        assert layout_energies(problem, trials).min() >= result.energy - 1e-9


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
    assert 0.0 <= metrics.risk_fraction <= 1.0


def test_optimised_layouts_get_anatomical_names(model, grasps):
    layout, result = optimise_layout(model, grasps[::3], 5, "pso", subspace_dims=4, n_keyframes=4,
                                     settings=PSOSettings(particles=80, iterations=8), name="tiny")
    assert layout.name == "tiny" and len(set(layout.names)) == 5
    assert all(name.split("_")[0] in ("thumb", "index", "middle", "ring", "little", "hand") for name in layout.names)
    assert "energy" in layout.description and result.energy < np.inf


def test_pso_swap_polish_never_raises_the_pso_energy(model, grasps):
    settings = PSOSettings(particles=60, iterations=6)
    plain, pso = optimise_layout(model, grasps[::3], 5, "pso", subspace_dims=4, n_keyframes=4, settings=settings)
    polished, result = optimise_layout(model, grasps[::3], 5, "pso-swap", subspace_dims=4, n_keyframes=4,
                                       settings=settings)
    assert result.energy <= pso.energy + 1e-9 and result.evaluations > pso.evaluations
    assert len(result.history) >= len(pso.history) and np.all(np.diff(result.history) <= 1e-9)


def test_workflow_rejects_bad_requests(model):
    with pytest.raises(InputError, match="only"):
        optimise_layout(model, "grasps", 100_000, "greedy")
    with pytest.raises(InputError, match="at least"):
        optimise_layout(model, "grasps", 2, "pso", subspace_dims=6)
    with pytest.raises(InputError, match="unknown motion set"):
        optimise_layout(model, "dancing", 6)
    with pytest.raises(InputError, match="method"):
        optimise_layout(model, "grasps", 6, "annealing")


def test_error_table_rows_and_cancel(model):
    rows = []
    table = error_against_markers(model, [4], "grasps", "gestures", PSOSettings(particles=40, iterations=4),
                                  n_keyframes=3, reconstruction_frames=60, row_done=rows.append)
    assert table == rows and table[0].markers == 4 and table[0].subspace_dims == 4
    assert 0 < table[0].specific_mean_mm <= table[0].specific_max_mm
    assert set(table[0].to_json()) >= {"markers", "specific_mean_mm", "generic_mean_mm"}
    with pytest.raises(CancelledError):
        error_against_markers(model, [4], settings=PSOSettings(particles=20, iterations=2), cancelled=lambda: True)
