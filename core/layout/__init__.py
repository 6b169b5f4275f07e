"""Marker-layout optimisation: feasible positions, the layout energy, surface PSO, greedy baselines and
layout metrics (journal "Reduced marker layouts" to "Marker PSO")."""

from handmocap.core.layout.evaluate import LayoutMetrics, evaluate_layout, reconstruction_error
from handmocap.core.layout.feasible import feasible_vertices, gesture_motion, keyframes, motion_from_results, motion_set
from handmocap.core.layout.greedy import optimise_greedy, select_subset
from handmocap.core.layout.objective import (
    LayoutProblem,
    build_problem,
    default_subspace_dims,
    layout_energies,
    layout_terms,
    vertex_layout,
)
from handmocap.core.layout.placement_sheet import PlacementSheet, placement_sheet, segment_marker_names
from handmocap.core.layout.pso import OptimisationResult, PSOSettings, optimise_pso

__all__ = [
    "LayoutMetrics", "LayoutProblem", "OptimisationResult", "PSOSettings", "build_problem",
    "default_subspace_dims", "evaluate_layout", "feasible_vertices", "gesture_motion", "keyframes",
    "layout_energies", "layout_terms", "motion_from_results", "motion_set", "optimise_greedy",
    "optimise_pso", "PlacementSheet", "placement_sheet", "reconstruction_error", "segment_marker_names",
    "select_subset", "vertex_layout",
]
