"""Surface-constrained particle swarm optimisation of a marker layout (journal "Marker PSO", eq. 12–13).

A particle is ``k`` marker positions (mm, rest pose). Each iteration applies the constricted PSO
velocity update ``ṽ = w (v + c₁ r₁ (x̄_par − x) + c₂ r₂ (x̄_pop − x))`` (c₁ = 2.8, c₂ = 1.3, w ≈ 0.7298),
perturbs one random marker in 50 % of the particles every third iteration, projects every marker to
the nearest candidate point (``Π_V'``; a marker whose nearest point is already taken by an earlier
marker of the same particle takes its nearest free one), sets ``v = x_{t+1} − x_t`` and evaluates the
particles. 1000 particles, 100 iterations by default.

Details the paper leaves open, settled here (each measured against the plain reading on the grasp
problem, see ``tests/bench/bench_pso.py``):

- A layout is a *set*: the order of its markers means nothing, but the update pulls marker ``i`` of a
  particle towards marker ``i`` of the swarm's best. Before each update the swarm's best is re-ordered,
  per particle, to match that particle's markers (greedy nearest pairing), so a marker is drawn to the
  corresponding best marker, not to an arbitrary one on another finger.
- Feasible vertices form islands (one per bone segment: the joints, where skin weights blend, are
  excluded), which small velocity steps rarely cross. A perturbation therefore re-places the chosen
  marker on a uniformly drawn feasible point, and the perturbed particle first returns to its own best
  layout, so the move is tried in the best context the particle knows.
- Particles whose layout did not change since they were last evaluated (as a set) keep their energy,
  and identical layouts within an iteration are evaluated once; the result is the same as evaluating
  every particle every time, only cheaper. ``OptimisationResult.evaluations`` counts real evaluations.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.layout.objective import LayoutProblem, layout_energies

ProgressCallback = Callable[[float, float], None]
PERTURBATIONS = ("uniform", "gaussian")


@dataclass(frozen=True)
class PSOSettings:
    """Swarm parameters (journal defaults). ``perturbation``: ``"uniform"`` re-places the perturbed
    marker on a feasible point drawn uniformly (a fresh random position, as the random re-initialisation
    of part of a particle in Oikonomidis et al.), ``"gaussian"`` moves it by a normal step with standard
    deviation ``perturbation_scale × L``; ``perturb_from_best``: a perturbed particle first returns to
    its own best layout, so the one re-placed marker is tried in the best context the particle knows;
    ``align_best``: re-order the swarm's best per particle."""

    particles: int = 1000
    iterations: int = 100
    c1: float = 2.8
    c2: float = 1.3
    perturb_every: int = 3
    perturb_fraction: float = 0.5
    perturbation: str = "uniform"
    perturbation_scale: float = 0.5
    perturb_from_best: bool = True
    align_best: bool = True

    @property
    def constriction(self) -> float:
        """``w = 2 / |2 − ψ − √(ψ² − 4ψ)|`` with ``ψ = c₁ + c₂`` (≈ 0.7298 for the defaults)."""
        psi = self.c1 + self.c2
        return 2.0 / abs(2.0 - psi - np.sqrt(psi * psi - 4.0 * psi))


@dataclass(frozen=True)
class OptimisationResult:
    """Best layout found: ``indices (k,)`` into the problem's candidates, ``vertices (k,)`` model vertex
    ids, its ``energy``, ``history (n,)`` the best energy after initialisation and each step, and
    ``evaluations`` the number of layouts whose energy was computed."""

    indices: np.ndarray
    vertices: np.ndarray
    energy: float
    history: np.ndarray
    evaluations: int = field(default=0)


def project_to_candidates(tree: cKDTree, points: np.ndarray) -> np.ndarray:
    """Nearest candidate index ``(P, k)`` of marker positions ``(P, k, 3)``, distinct within a particle
    (a later marker whose nearest candidate is taken takes its nearest free one)."""
    n_particles, n_markers, _ = points.shape
    _, chosen = tree.query(points.reshape(-1, 3))
    chosen = chosen.reshape(n_particles, n_markers)
    ordered = np.sort(chosen, axis=1)
    clash = np.flatnonzero((ordered[:, 1:] == ordered[:, :-1]).any(axis=1))
    if len(clash):                                 # rare: resolve those particles with k nearest
        _, nearest = tree.query(points[clash].reshape(-1, 3), k=list(range(1, n_markers + 1)))
        nearest = nearest.reshape(len(clash), n_markers, n_markers)
        fixed = nearest[:, :, 0].copy()
        rows = np.arange(len(clash))
        for marker in range(1, n_markers):
            taken = (nearest[:, marker, :, None] == fixed[:, None, :marker]).any(axis=2)   # (P', k)
            fixed[:, marker] = nearest[rows, marker, taken.argmin(axis=1)]
        chosen[clash] = fixed
    return chosen


def random_layouts(rng: np.random.Generator, n_layouts: int, n_markers: int, n_candidates: int) -> np.ndarray:
    """``(n_layouts, n_markers)`` candidate indices, distinct within each row, uniformly drawn."""
    return rng.random((n_layouts, n_candidates)).argpartition(n_markers - 1, axis=1)[:, :n_markers]


def align_to(reference: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``reference (k, 3)`` re-ordered for each particle of ``points (P, k, 3)`` so that its marker ``i``
    is the one paired with the particle's marker ``i``: ``(P, k, 3)``. Pairs are taken greedily,
    closest first (vectorised over particles)."""
    n_particles, n_markers, _ = points.shape
    cost = np.linalg.norm(points[:, :, None, :] - reference[None, None, :, :], axis=3)   # (P, k, k)
    order = np.empty((n_particles, n_markers), dtype=np.int64)
    rows = np.arange(n_particles)
    for _ in range(n_markers):
        flat = cost.reshape(n_particles, -1).argmin(axis=1)
        marker, target = np.divmod(flat, n_markers)
        order[rows, marker] = target
        cost[rows, marker, :] = np.inf
        cost[rows, :, target] = np.inf
    return reference[order]


class _EnergyCache:
    """Energies of layouts seen before, keyed by the sorted candidate indices (a layout is a set)."""

    def __init__(self, problem: LayoutProblem) -> None:
        self.problem = problem
        self.known: dict[bytes, float] = {}
        self.evaluations = 0

    def __call__(self, layouts: np.ndarray) -> np.ndarray:
        keys = np.sort(layouts, axis=1)
        unique, inverse = np.unique(keys, axis=0, return_inverse=True)
        names = [row.tobytes() for row in unique]
        missing = [index for index, name in enumerate(names) if name not in self.known]
        if missing:
            energies = layout_energies(self.problem, unique[missing])
            self.evaluations += len(missing)
            self.known.update(zip((names[index] for index in missing), energies.tolist(), strict=True))
        return np.array([self.known[name] for name in names])[inverse.ravel()]


def optimise_pso(problem: LayoutProblem, n_markers: int, settings: PSOSettings | None = None, seed: int = 0,
                 progress: ProgressCallback | None = None, cancelled: Callable[[], bool] | None = None,
                 initial: np.ndarray | None = None) -> OptimisationResult:
    """Minimise the layout energy over ``n_markers`` distinct candidate points by surface-constrained PSO.

    ``progress(fraction, best_energy)`` is called after each iteration (the per-iteration energy for a
    live plot); :class:`CancelledError` is raised when ``cancelled()`` turns true. ``initial (k,)``:
    candidate indices given to the first particle (the journal's "identical initialisation" when
    comparing with greedy). Deterministic for a given ``seed``.
    """
    settings = settings or PSOSettings()
    if settings.perturbation not in PERTURBATIONS:
        raise InputError(f"unknown perturbation '{settings.perturbation}' (use {', '.join(PERTURBATIONS)})")
    if settings.particles < 1 or settings.iterations < 0:
        raise InputError(f"PSO needs at least one particle and no negative iteration count "
                         f"({settings.particles} particles, {settings.iterations} iterations)")
    problem.check_marker_count(n_markers)
    rng = np.random.default_rng(seed)
    rest = problem.candidates.rest_positions
    tree = cKDTree(rest)
    weight = settings.constriction
    sigma = settings.perturbation_scale * problem.hand_length
    energies = _EnergyCache(problem)

    indices = random_layouts(rng, settings.particles, n_markers, problem.n_candidates)
    if initial is not None:
        indices[0] = np.asarray(initial, dtype=np.int64)
    positions = rest[indices]
    velocity = np.zeros_like(positions)
    energy = energies(indices)
    best_indices, best_energy = indices.copy(), energy.copy()
    leader = int(np.argmin(best_energy))
    history = [float(best_energy[leader])]
    for iteration in range(settings.iterations):
        if cancelled is not None and cancelled():
            raise CancelledError("layout optimisation cancelled")
        leader_points = rest[best_indices[leader]]
        swarm_best = align_to(leader_points, positions) if settings.align_best else leader_points[None]
        r1, r2 = rng.random((2, *positions.shape))
        velocity = weight * (velocity + settings.c1 * r1 * (rest[best_indices] - positions)
                             + settings.c2 * r2 * (swarm_best - positions))
        moved = positions + velocity
        if iteration % settings.perturb_every == settings.perturb_every - 1:
            chosen = np.flatnonzero(rng.random(settings.particles) < settings.perturb_fraction)
            marker = rng.integers(n_markers, size=len(chosen))
            if settings.perturb_from_best:
                moved[chosen] = rest[best_indices[chosen]]
            if settings.perturbation == "uniform":
                moved[chosen, marker] = rest[rng.integers(problem.n_candidates, size=len(chosen))]
            else:
                moved[chosen, marker] += rng.normal(0.0, sigma, (len(chosen), 3))
        indices = project_to_candidates(tree, moved)
        velocity = rest[indices] - positions
        positions = rest[indices]
        energy = energies(indices)
        improved = energy < best_energy
        best_indices[improved], best_energy[improved] = indices[improved], energy[improved]
        leader = int(np.argmin(best_energy))
        history.append(float(best_energy[leader]))
        if progress is not None:
            progress((iteration + 1) / settings.iterations, history[-1])
    best = best_indices[leader].copy()
    return OptimisationResult(best, problem.candidates.vertex[best], history[-1], np.array(history),
                              energies.evaluations)
