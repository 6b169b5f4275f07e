"""Baselines of the journal's "Layout optimization" results: greedy add-then-swap, and subset selection.

Greedy (after Schlömer et al.'s farthest-point optimisation): add, one at a time, the candidate that
gives the lowest energy of the markers so far; then, marker by marker, replace each with the best
candidate not in the layout while that lowers the energy, until a whole pass changes nothing. Every
step tries every feasible vertex (the journal's baseline, not a cheaper variant), all at once through
the same batched energy kernel as the PSO, so a run costs ``k · C · (passes + 1)`` evaluations
(``OptimisationResult.evaluations``) at the PSO's per-layout cost. Subset selection picks ``k`` of a
base layout's markers: exhaustively when the number of subsets is small, else by the same greedy method.
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import combinations
from math import comb

import numpy as np

from handmocap.core.errors import CancelledError
from handmocap.core.layout.objective import LayoutProblem, layout_energies
from handmocap.core.layout.pso import OptimisationResult, ProgressCallback

EXHAUSTIVE_LIMIT = 50_000   # subsets evaluated one by one below this count
_CHUNK = 2_000              # layouts per batched evaluation


def _check(cancelled: Callable[[], bool] | None) -> None:
    if cancelled is not None and cancelled():
        raise CancelledError("layout optimisation cancelled")


def _best_replacement(problem: LayoutProblem, layout: np.ndarray, slot: int) -> tuple[int, float, int]:
    """The candidate not in ``layout`` that, put at ``slot`` (``len(layout)`` = appended), gives the
    lowest energy, that energy, and the number of layouts evaluated."""
    free = np.setdiff1d(np.arange(problem.n_candidates), np.delete(layout, slot) if slot < len(layout) else layout)
    trials = np.empty((len(free), max(len(layout), slot + 1)), dtype=np.int64)
    trials[:, :len(layout)] = layout
    trials[:, slot] = free
    energies = np.concatenate([layout_energies(problem, trials[start:start + _CHUNK])
                               for start in range(0, len(trials), _CHUNK)])
    best = int(np.argmin(energies))
    return int(free[best]), float(energies[best]), len(trials)


def optimise_greedy(problem: LayoutProblem, n_markers: int, initial: np.ndarray | None = None,
                    progress: ProgressCallback | None = None,
                    cancelled: Callable[[], bool] | None = None) -> OptimisationResult:
    """Greedy add-then-swap over all candidates; ``initial (k,)`` candidate indices skip the add phase.

    ``history``: the energy after each add and each accepted swap. ``progress(fraction, energy)``: the
    add phase covers 0–0.5, swap pass ``n`` ends at ``1 − 0.5ⁿ⁺¹``.
    """
    problem.check_marker_count(n_markers)
    history: list[float] = []
    evaluations = 0
    if initial is None:
        layout = np.empty(0, dtype=np.int64)
        for added in range(n_markers):
            _check(cancelled)
            candidate, energy, count = _best_replacement(problem, layout, len(layout))
            evaluations += count
            layout = np.append(layout, candidate)
            history.append(energy)
            if progress is not None:
                progress(0.5 * (added + 1) / n_markers, energy)
    else:
        layout = np.asarray(initial, dtype=np.int64).copy()
        history.append(float(layout_energies(problem, layout)[0]))
        evaluations += 1
    energy = history[-1]
    swap_pass, improved = 0, True
    while improved:
        improved = False
        for slot in range(n_markers):
            _check(cancelled)
            candidate, trial_energy, count = _best_replacement(problem, layout, slot)
            evaluations += count
            if trial_energy < energy:
                layout[slot], energy, improved = candidate, trial_energy, True
                history.append(energy)
        swap_pass += 1
        if progress is not None:
            progress(1.0 - 0.5 ** (swap_pass + 1), energy)
    return OptimisationResult(layout, problem.candidates.vertex[layout], energy, np.array(history), evaluations)


def select_subset(problem: LayoutProblem, n_markers: int, progress: ProgressCallback | None = None,
                  cancelled: Callable[[], bool] | None = None) -> OptimisationResult:
    """The ``n_markers`` of the problem's candidates (e.g. a base layout's markers) with the lowest energy:
    every subset when there are at most :data:`EXHAUSTIVE_LIMIT`, else greedy add-then-swap."""
    problem.check_marker_count(n_markers)
    total = comb(problem.n_candidates, n_markers)
    if total > EXHAUSTIVE_LIMIT:
        return optimise_greedy(problem, n_markers, progress=progress, cancelled=cancelled)
    subsets = np.fromiter(combinations(range(problem.n_candidates), n_markers),
                          dtype=np.dtype((np.int64, n_markers)), count=total)
    best_layout, best_energy, history = subsets[0], np.inf, []
    for start in range(0, total, _CHUNK):
        _check(cancelled)
        energies = layout_energies(problem, subsets[start:start + _CHUNK])
        index = int(np.argmin(energies))
        if energies[index] < best_energy:
            best_layout, best_energy = subsets[start + index], float(energies[index])
        history.append(best_energy)
        if progress is not None:
            progress(min(1.0, (start + _CHUNK) / total), best_energy)
    return OptimisationResult(best_layout.copy(), problem.candidates.vertex[best_layout], best_energy,
                              np.array(history), total)
