"""Surface-constrained particle swarm optimisation of a marker layout (journal "Marker PSO", eq. 12–13).

A particle is ``k`` marker positions (mm, rest pose). Each iteration applies the constricted PSO
velocity update, perturbs one random marker in a share of the particles every few iterations, projects
every marker to the nearest candidate point (``Π_V'``; a marker whose nearest point is already taken
by an earlier marker of the same particle takes its nearest free one), sets ``v = x_{t+1} − x_t`` and
evaluates all particles at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from core.errors import CancelledError
from core.layout.objective import LayoutProblem, layout_energies

ProgressCallback = Callable[[float, float], None]


@dataclass(frozen=True)
class PSOSettings:
    """Swarm parameters (journal defaults). ``perturbation_scale``: standard deviation of a perturbation
    as a fraction of the hand length ``L``."""

    particles: int = 1000
    iterations: int = 100
    c1: float = 2.8
    c2: float = 1.3
    perturb_every: int = 3
    perturb_fraction: float = 0.5
    perturbation_scale: float = 0.5

    @property
    def constriction(self) -> float:
        """``w = 2 / |2 − ψ − √(ψ² − 4ψ)|`` with ``ψ = c₁ + c₂`` (≈ 0.7298 for the defaults)."""
        psi = self.c1 + self.c2
        return 2.0 / abs(2.0 - psi - np.sqrt(psi * psi - 4.0 * psi))


@dataclass(frozen=True)
class OptimisationResult:
    """Best layout found: ``indices (k,)`` into the problem's candidates, ``vertices (k,)`` model vertex
    ids, its ``energy``, and ``history (n,)`` the best energy after initialisation and each step."""

    indices: np.ndarray
    vertices: np.ndarray
    energy: float
    history: np.ndarray


def project_to_candidates(tree: cKDTree, points: np.ndarray) -> np.ndarray:
    """Nearest candidate index ``(P, k)`` of marker positions ``(P, k, 3)``, distinct within a particle."""
    n_particles, n_markers, _ = points.shape
    _, nearest = tree.query(points.reshape(-1, 3), k=list(range(1, n_markers + 1)))
    nearest = nearest.reshape(n_particles, n_markers, n_markers)
    chosen = nearest[:, :, 0].copy()
    rows = np.arange(n_particles)
    for marker in range(1, n_markers):
        taken = (nearest[:, marker, :, None] == chosen[:, None, :marker]).any(axis=2)   # (P, k)
        chosen[:, marker] = nearest[rows, marker, taken.argmin(axis=1)]
    return chosen


def random_layouts(rng: np.random.Generator, n_layouts: int, n_markers: int, n_candidates: int) -> np.ndarray:
    """``(n_layouts, n_markers)`` candidate indices, distinct within each row, uniformly drawn."""
    return rng.random((n_layouts, n_candidates)).argpartition(n_markers - 1, axis=1)[:, :n_markers]


def optimise_pso(problem: LayoutProblem, n_markers: int, settings: PSOSettings | None = None, seed: int = 0,
                 progress: ProgressCallback | None = None,
                 cancelled: Callable[[], bool] | None = None) -> OptimisationResult:
    """Minimise the layout energy over ``n_markers`` distinct candidate points by surface-constrained PSO.

    ``progress(fraction, best_energy)`` is called after each iteration; :class:`CancelledError` is
    raised when ``cancelled()`` turns true. Deterministic for a given ``seed``.
    """
    settings = settings or PSOSettings()
    problem.check_marker_count(n_markers)
    rng = np.random.default_rng(seed)
    rest = problem.candidates.rest_positions
    tree = cKDTree(rest)
    weight = settings.constriction
    sigma = settings.perturbation_scale * problem.hand_length

    indices = random_layouts(rng, settings.particles, n_markers, problem.n_candidates)
    positions = rest[indices]
    velocity = np.zeros_like(positions)
    energy = layout_energies(problem, indices)
    best_indices, best_energy = indices.copy(), energy.copy()
    leader = int(np.argmin(best_energy))
    history = [float(best_energy[leader])]
    for iteration in range(settings.iterations):
        if cancelled is not None and cancelled():
            raise CancelledError("layout optimisation cancelled")
        r1, r2 = rng.random((2, *positions.shape))
        velocity = weight * (velocity + settings.c1 * r1 * (rest[best_indices] - positions)
                             + settings.c2 * r2 * (rest[best_indices[leader]] - positions))
        moved = positions + velocity
        if iteration % settings.perturb_every == settings.perturb_every - 1:
            chosen = np.flatnonzero(rng.random(settings.particles) < settings.perturb_fraction)
            marker = rng.integers(n_markers, size=len(chosen))
            moved[chosen, marker] += rng.normal(0.0, sigma, (len(chosen), 3))
        indices = project_to_candidates(tree, moved)
        velocity = rest[indices] - positions
        positions = rest[indices]
        energy = layout_energies(problem, indices)
        improved = energy < best_energy
        best_indices[improved], best_energy[improved] = indices[improved], energy[improved]
        leader = int(np.argmin(best_energy))
        history.append(float(best_energy[leader]))
        if progress is not None:
            progress((iteration + 1) / settings.iterations, history[-1])
    best = best_indices[leader]
    return OptimisationResult(best.copy(), problem.candidates.vertex[best], history[-1], np.array(history))
