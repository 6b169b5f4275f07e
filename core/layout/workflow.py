"""The layout tools as the CLI and the GUI use them: optimise a layout for a motion set, the table of
reconstruction error against the number of markers, benchmark."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.layout.evaluate import reconstruction_error
from handmocap.core.layout.feasible import motion_set
from handmocap.core.layout.greedy import optimise_greedy, select_subset
from handmocap.core.layout.objective import (
    LayoutProblem,
    build_problem,
    default_subspace_dims,
    layout_energies,
    vertex_layout,
)
from handmocap.core.layout.pso import OptimisationResult, PSOSettings, optimise_pso
from handmocap.core.model import HandModel, MarkerLayout, load_layout, resolve_layout

METHODS = ("pso", "pso-swap", "greedy", "subset")
TABLE_COUNTS = tuple(range(4, 13))
GENERIC_MOTIONS = "gestures"      # the journal's generic layouts: general gestures and hand articulations


def optimise_layout(model: HandModel, motions: str | Path | list[str | Path] | np.ndarray, n_markers: int,
                    method: str = "pso", base_layout: str | Path | MarkerLayout = "dense",
                    subspace_dims: int | None = None, n_keyframes: int = 10, seed: int = 0,
                    progress: Callable[[float, float], None] | None = None,
                    cancelled: Callable[[], bool] | None = None,
                    settings: PSOSettings | None = None,
                    name: str | None = None) -> tuple[MarkerLayout, OptimisationResult]:
    """A ``n_markers`` layout for ``motions`` (a motion-set name, solved-take result files, or a motion
    ``(F, 26)``) by ``method``: surface PSO or greedy over the feasible vertices, or the best subset of
    ``base_layout``; ``pso-swap``: PSO, then greedy swap passes from the swarm's best (a local polish that
    is not in the journal; it never raises the energy). ``progress(fraction, best_energy)`` is called per
    PSO iteration / greedy step.
    Markers are named after the segment they sit on (``index_dist``, ``hand_back``...)."""
    if method not in METHODS:
        raise InputError(f"unknown layout method '{method}' (use {', '.join(METHODS)})")
    if n_markers < 1:
        raise InputError(f"a layout needs at least one marker, not {n_markers}")
    motion = motions if isinstance(motions, np.ndarray) else motion_set(motions)
    label = "custom motion" if isinstance(motions, np.ndarray) else (
        ", ".join(Path(str(path)).name for path in motions) if isinstance(motions, list) else str(motions))
    dims = subspace_dims or default_subspace_dims(n_markers)
    if method == "subset":
        base = base_layout if isinstance(base_layout, MarkerLayout) else load_layout(base_layout)
        problem = build_problem(model, motion, dims, n_keyframes, candidates=resolve_layout(model, base))
        result = select_subset(problem, n_markers, progress=progress, cancelled=cancelled)
        chosen = [base.markers[int(index)] for index in result.indices]
        layout = MarkerLayout(name or f"{base.name}-subset-{n_markers}", tuple(chosen),
                              f"{n_markers} of the {base.name} layout's markers, chosen for {label} "
                              f"({dims} PCs, energy {result.energy:.2f})")
        return layout, result
    problem = build_problem(model, motion, dims, n_keyframes)
    if method in ("pso", "pso-swap"):
        scale = 0.9 if method == "pso-swap" else 1.0

        def pso_progress(fraction: float, energy: float) -> None:
            if progress is not None:
                progress(scale * fraction, energy)

        result = optimise_pso(problem, n_markers, settings, seed=seed, progress=pso_progress, cancelled=cancelled)
        if method == "pso-swap":
            result = refine_by_swaps(problem, result, progress, cancelled)
    else:
        result = optimise_greedy(problem, n_markers, progress=progress, cancelled=cancelled)
    layout = vertex_layout(model, result.vertices, name=name or f"{method}-{n_markers}")
    description = (f"{n_markers} markers optimised by {method} for {label} ({dims} PCs, "
                   f"{problem.keyframe_angles.shape[0]} keyframes, energy {result.energy:.2f})")
    return MarkerLayout(layout.name, layout.markers, description), result


def refine_by_swaps(problem: LayoutProblem, result: OptimisationResult,
                    progress: Callable[[float, float], None] | None = None,
                    cancelled: Callable[[], bool] | None = None) -> OptimisationResult:
    """``result`` polished by greedy swap passes (every marker to its best free candidate while that
    lowers the energy); the history continues the optimiser's, evaluations add up."""
    swapped = optimise_greedy(problem, len(result.indices), initial=result.indices, cancelled=cancelled)
    if progress is not None:
        progress(1.0, swapped.energy)
    return OptimisationResult(swapped.indices, swapped.vertices, swapped.energy,
                              np.concatenate([result.history, swapped.history[1:]]),
                              result.evaluations + swapped.evaluations)


@dataclass(frozen=True)
class ErrorRow:
    """Held-out grasp reconstruction error (mm) of a ``markers``-marker layout optimised for the
    specific motions and of one optimised for the generic motions, with ``subspace_dims`` PCs."""

    markers: int
    subspace_dims: int
    specific_mean_mm: float
    specific_max_mm: float
    generic_mean_mm: float
    generic_max_mm: float

    def to_json(self) -> dict:
        return {key: (round(value, 3) if isinstance(value, float) else value) for key, value in vars(self).items()}


def error_against_markers(model: HandModel, counts: tuple[int, ...] | list[int] = TABLE_COUNTS,
                          specific: str = "grasps", generic: str = GENERIC_MOTIONS,
                          settings: PSOSettings | None = None, seed: int = 0, n_keyframes: int = 10,
                          reconstruction_frames: int = 1500,
                          progress: Callable[[float], None] | None = None,
                          cancelled: Callable[[], bool] | None = None,
                          row_done: Callable[[ErrorRow], None] | None = None) -> list[ErrorRow]:
    """The journal's Fig. 11: for each marker count, optimise a layout (PSO) for the ``specific``
    motions and one for the ``generic`` motions, and reconstruct HELD-OUT grasps (layered IK, global
    pose given) with each; ``row_done(row)`` hears each row as it is finished."""
    counts = sorted({int(count) for count in counts})
    if not counts:
        raise InputError("give at least one marker count for the error table")
    motions = {"specific": motion_set(specific), "generic": motion_set(generic)}
    steps = 2 * len(counts)
    rows: list[ErrorRow] = []
    for index, count in enumerate(counts):
        dims = default_subspace_dims(count)
        figures = {}
        for part, (kind, motion) in enumerate(motions.items()):
            step = 2 * index + part

            def report(fraction: float, _energy: float = 0.0, step: int = step) -> None:
                if progress is not None:
                    progress((step + 0.8 * fraction) / steps)

            layout, _ = optimise_layout(model, motion, count, "pso", subspace_dims=dims, n_keyframes=n_keyframes,
                                        seed=seed, progress=report, cancelled=cancelled, settings=settings)
            if cancelled is not None and cancelled():
                raise CancelledError("error table cancelled")
            figures[kind] = reconstruction_error(model, layout, n_frames=reconstruction_frames, subspace_dims=dims)
            report(1.0 / 0.8)
        row = ErrorRow(count, dims, *figures["specific"], *figures["generic"])
        rows.append(row)
        if row_done is not None:
            row_done(row)
    return rows


def bench_pso(n_markers: int = 6, n_keyframes: int = 10, seed: int = 0, seeds: int = 1) -> dict:
    """PSO (1000 particles × 100 iterations) against greedy add-then-swap on the grasp motion set.
    With ``seeds > 1`` also the PSO energy for seeds ``seed .. seed + seeds - 1`` (its spread)."""
    from handmocap.core.model import load_template

    model = load_template()
    problem = build_problem(model, motion_set("grasps"), default_subspace_dims(n_markers), n_keyframes)
    layout_energies(problem, np.arange(n_markers)[None])      # compile the kernels before timing
    start = time.perf_counter()
    pso = optimise_pso(problem, n_markers, seed=seed)
    pso_seconds = time.perf_counter() - start
    start = time.perf_counter()
    greedy = optimise_greedy(problem, n_markers)
    greedy_seconds = time.perf_counter() - start
    start = time.perf_counter()
    polished = refine_by_swaps(problem, pso)
    swap_seconds = time.perf_counter() - start
    figures: dict[str, float | list[float]] = {"pso_seconds": round(pso_seconds, 3), "pso_energy": round(pso.energy, 4),
               "greedy_seconds": round(greedy_seconds, 3), "greedy_energy": round(greedy.energy, 4),
               "pso_evaluations": pso.evaluations, "greedy_evaluations": greedy.evaluations,
               "pso_swap_seconds": round(pso_seconds + swap_seconds, 3), "pso_swap_energy": round(polished.energy, 4),
               "markers": n_markers, "keyframes": n_keyframes, "candidates": problem.n_candidates}
    if seeds > 1:
        runs = [pso] + [optimise_pso(problem, n_markers, seed=other) for other in range(seed + 1, seed + seeds)]
        energies = [run.energy for run in runs]
        polished_energies = [polished.energy] + [refine_by_swaps(problem, run).energy for run in runs[1:]]
        figures["pso_swap_energy_seeds"] = [round(energy, 4) for energy in polished_energies]
        figures.update({"pso_energy_seeds": [round(energy, 4) for energy in energies],
                        "pso_energy_min": round(min(energies), 4), "pso_energy_max": round(max(energies), 4),
                        "pso_energy_std": round(float(np.std(energies)), 4),
                        "pso_runs_below_greedy": int(sum(energy < greedy.energy - 1e-6 for energy in energies))})
    return figures
