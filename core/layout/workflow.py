"""The layout tools as the CLI and the GUI use them: optimise a layout for a motion set, benchmark."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from core.errors import InputError
from core.layout.feasible import motion_set
from core.layout.greedy import optimise_greedy, select_subset
from core.layout.objective import build_problem, default_subspace_dims, layout_energies, vertex_layout
from core.layout.pso import OptimisationResult, optimise_pso
from core.model import HandModel, MarkerLayout, load_layout, resolve_layout

METHODS = ("pso", "greedy", "subset")


def optimise_layout(model: HandModel, motions: str | Path | list[str | Path], n_markers: int,
                    method: str = "pso", base_layout: str | Path = "dense", subspace_dims: int | None = None,
                    n_keyframes: int = 10, seed: int = 0,
                    progress: Callable[[float, float], None] | None = None,
                    cancelled: Callable[[], bool] | None = None) -> tuple[MarkerLayout, OptimisationResult]:
    """A ``n_markers`` layout for ``motions`` (a motion-set name or solved-take result files) by
    ``method``: surface PSO or greedy over the feasible vertices, or the best subset of ``base_layout``."""
    if method not in METHODS:
        raise InputError(f"unknown layout method '{method}' (use {', '.join(METHODS)})")
    motion = motion_set(motions)
    dims = subspace_dims or default_subspace_dims(n_markers)
    if method == "subset":
        base = load_layout(base_layout)
        problem = build_problem(model, motion, dims, n_keyframes, candidates=resolve_layout(model, base))
        result = select_subset(problem, n_markers, progress=progress, cancelled=cancelled)
        chosen = [base.markers[int(index)] for index in result.indices]
        layout = MarkerLayout(f"{base.name}-subset-{n_markers}", tuple(chosen),
                              f"{n_markers} of the {base.name} layout's markers, chosen for {motions}")
        return layout, result
    problem = build_problem(model, motion, dims, n_keyframes)
    optimiser = optimise_pso if method == "pso" else optimise_greedy
    options = {"seed": seed} if method == "pso" else {}
    result = optimiser(problem, n_markers, progress=progress, cancelled=cancelled, **options)
    layout = vertex_layout(model, result.vertices, name=f"{method}-{n_markers}")
    return layout, result


def bench_pso(n_markers: int = 6, n_keyframes: int = 10, seed: int = 0) -> dict:
    """PSO (1000 particles × 100 iterations) against greedy add-then-swap on the grasp motion set."""
    from core.model import load_template

    model = load_template()
    problem = build_problem(model, motion_set("grasps"), default_subspace_dims(n_markers), n_keyframes)
    layout_energies(problem, np.arange(n_markers)[None])      # compile the kernels before timing
    start = time.perf_counter()
    pso = optimise_pso(problem, n_markers, seed=seed)
    pso_seconds = time.perf_counter() - start
    start = time.perf_counter()
    greedy = optimise_greedy(problem, n_markers)
    greedy_seconds = time.perf_counter() - start
    return {"pso_seconds": round(pso_seconds, 3), "pso_energy": round(pso.energy, 4),
            "greedy_seconds": round(greedy_seconds, 3), "greedy_energy": round(greedy.energy, 4),
            "markers": n_markers, "keyframes": n_keyframes, "candidates": problem.n_candidates}
