"""The layout energy ``E = w₁ E_cond + w₂ E_dist`` (journal eq. 9–11) over precomputed keyframes.

``E_cond``: mean over keyframes of ``κ(JᵀJ) = κ(J)²`` with ``J`` the marker Jacobian in the subspace,
``J·M`` with ``M = diag(I₆, P_l)``, without the three translation columns: ``(3k, 3 + l)``.
``E_dist``: ``-√(min over keyframes and marker pairs of the squared distance) / L`` (scale-invariant).

A :class:`LayoutProblem` holds, per keyframe, the positions and reduced Jacobians of every candidate
point (feasible vertices, or a base layout's markers) once; a layout is a row of candidate indices.
Since ``JᵀJ = Σᵢ Jᵢᵀ Jᵢ`` over markers, the batched evaluation sums precomputed per-candidate Gram
matrices and takes their extreme eigenvalues (``σ(JᵀJ) = σ(J)²``; numba: Householder tridiagonal form,
then Laguerre from outside the spectrum), which is exact and about 20 times faster than a batched SVD
of the stacked Jacobians; :func:`layout_terms` keeps the SVD form as the reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from handmocap.core.errors import InputError
from handmocap.core.layout.feasible import feasible_vertices, keyframes
from handmocap.core.model import HandModel, MarkerLayout, MarkerSet, MarkerSpec, resolve_layout
from handmocap.core.model.kinematics import ANCESTOR, points_and_jacobian_kernel
from handmocap.core.model.skeleton import N_GLOBAL
from handmocap.core.prior import PosturePrior, load_default_prior

CONDITION_WEIGHT = 0.1     # w₁
DISTANCE_WEIGHT = 100.0    # w₂
MARKER_OFFSET_MM = 4.0     # marker centre above the skin (radius + base)
RANK_TOLERANCE = 1e-12    # eigenvalues below this fraction of the largest count as zero


@dataclass(frozen=True, eq=False)
class LayoutProblem:
    """Everything the energy needs, precomputed.

    ``candidates``: the candidate points as a :class:`MarkerSet` (``C`` points, mm, rest pose);
    ``keyframe_angles (K, 26)``; ``positions (K, C, 3)`` mm; ``jacobians (K, C, 3, 3 + l)`` mm/rad
    (rotation columns, then the ``l`` principal components); ``gram (K, C, 3 + l, 3 + l)`` their
    per-candidate ``JᵢᵀJᵢ``; ``hand_length`` ``L`` mm.
    """

    model: HandModel
    candidates: MarkerSet
    keyframe_angles: np.ndarray
    positions: np.ndarray
    jacobians: np.ndarray
    gram: np.ndarray
    subspace_dims: int
    hand_length: float

    @property
    def n_candidates(self) -> int:
        return len(self.candidates.vertex)

    @property
    def n_columns(self) -> int:
        """Columns of the reduced Jacobian, ``3 + l``."""
        return self.jacobians.shape[-1]

    def check_marker_count(self, n_markers: int) -> None:
        """:class:`InputError` unless ``n_markers`` can be placed and constrain the ``3 + l`` DoFs."""
        if n_markers > self.n_candidates:
            raise InputError(f"cannot place {n_markers} markers: only {self.n_candidates} candidate positions")
        needed = -(-self.n_columns // 3)
        if n_markers < needed:
            raise InputError(f"{n_markers} markers cannot constrain {self.n_columns} DoFs (3 rotations + "
                             f"{self.subspace_dims} PCs): use at least {needed} markers or fewer PCs")


def default_subspace_dims(n_markers: int) -> int:
    """The IK's automatic subspace size for ``n_markers`` finger markers: one PC per marker, 2 to 6."""
    return int(np.clip(n_markers, 2, 6))


def vertex_layout(model: HandModel, vertices: np.ndarray, name: str = "optimised",
                  offset_mm: float = MARKER_OFFSET_MM, anatomical_names: bool = True) -> MarkerLayout:
    """A layout of markers on the given vertex ids ``(k,)``, named after the segment each sits on
    (``index_dist``, ``thumb_prox``, ``hand_back``..., see :func:`segment_marker_names`) or ``m1..mk``."""
    from handmocap.core.layout.placement_sheet import segment_marker_names

    names = (segment_marker_names(model, vertices) if anatomical_names
             else [f"m{i + 1}" for i in range(len(vertices))])
    markers = tuple(MarkerSpec(name=marker_name, vertex=int(v), offset_mm=offset_mm)
                    for marker_name, v in zip(names, vertices, strict=True))
    return MarkerLayout(name=name, markers=markers,
                        description=f"{len(markers)} markers on model '{model.name}'")


def build_problem(model: HandModel, motion: np.ndarray, subspace_dims: int, n_keyframes: int = 10,
                  prior: PosturePrior | None = None, candidates: MarkerSet | None = None,
                  offset_mm: float = MARKER_OFFSET_MM) -> LayoutProblem:
    """Precompute the keyframes of ``motion (F, 26)`` and every candidate's positions and Jacobians.

    ``candidates``: the points a layout is chosen from; by default the feasible vertices with
    markers ``offset_mm`` above the skin.
    """
    prior = prior or load_default_prior()
    if not 1 <= subspace_dims <= prior.n_components:
        raise InputError(f"the prior has {prior.n_components} components; cannot use {subspace_dims}")
    if candidates is None:
        vertices = feasible_vertices(model)
        if len(vertices) == 0:
            raise InputError(f"model '{model.name}' has no feasible marker positions on the back of the hand")
        candidates = resolve_layout(model, vertex_layout(model, vertices, "feasible", offset_mm,
                                                         anatomical_names=False))
    angles = np.asarray(motion, dtype=float)[keyframes(motion, n_keyframes)]
    basis = prior.components[:, :subspace_dims]
    chain = model.chain
    positions, frame_jacobians = [], []
    for theta in angles:
        points, jacobian = points_and_jacobian_kernel(
            np.ascontiguousarray(theta), chain.relative_rest, chain.offsets, chain.abduction_sign, ANCESTOR,
            candidates.influence_joints, candidates.influence_weights, candidates.local_points)
        positions.append(points)
        frame_jacobians.append(np.concatenate([jacobian[:, :, 3:N_GLOBAL], jacobian[:, :, N_GLOBAL:] @ basis],
                                              axis=2))
    jacobians = np.stack(frame_jacobians)
    gram = np.einsum("kcri,kcrj->kcij", jacobians, jacobians)
    return LayoutProblem(model, candidates, angles, np.stack(positions), jacobians, gram, subspace_dims,
                         model.hand_length)


@njit(cache=True)
def _tridiagonal(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Householder reduction of a symmetric ``(c, c)`` matrix (overwritten) to its tridiagonal form:
    diagonal ``(c,)`` and off-diagonal ``(c - 1,)``, same eigenvalues."""
    n = matrix.shape[0]
    diagonal = np.empty(n)
    off = np.zeros(max(n - 1, 1))
    v = np.empty(n)
    p = np.empty(n)
    for k in range(n - 2):
        norm = 0.0
        for i in range(k + 1, n):
            norm += matrix[i, k] * matrix[i, k]
        norm = np.sqrt(norm)
        alpha = -norm if matrix[k + 1, k] >= 0.0 else norm
        diagonal[k] = matrix[k, k]
        off[k] = alpha
        vv = 0.0
        for i in range(k + 1, n):
            v[i] = matrix[i, k]
        v[k + 1] -= alpha
        for i in range(k + 1, n):
            vv += v[i] * v[i]
        if vv == 0.0:
            continue
        beta = 2.0 / vv
        vp = 0.0
        for i in range(k + 1, n):
            total = 0.0
            for j in range(k + 1, n):
                total += matrix[i, j] * v[j]
            p[i] = beta * total
            vp += v[i] * p[i]
        half = 0.5 * beta * vp
        for i in range(k + 1, n):
            p[i] -= half * v[i]
        for i in range(k + 1, n):
            for j in range(k + 1, n):
                matrix[i, j] -= v[i] * p[j] + p[i] * v[j]
    if n >= 2:
        diagonal[n - 2] = matrix[n - 2, n - 2]
        off[n - 2] = matrix[n - 1, n - 2]
    diagonal[n - 1] = matrix[n - 1, n - 1]
    return diagonal, off


@njit(cache=True)
def _laguerre_root(diagonal: np.ndarray, off: np.ndarray, start: float) -> float:
    """The eigenvalue of a symmetric tridiagonal matrix nearest to ``start`` when ``start`` lies outside
    the spectrum (below the smallest or above the largest): Laguerre's method on the characteristic
    polynomial (all roots real, so it converges monotonically and cubically from outside)."""
    n = diagonal.shape[0]
    x = start
    for _ in range(100):
        p0, p1 = 1.0, diagonal[0] - x          # p, its first and second derivatives by the recurrence
        d0, d1 = 0.0, -1.0
        s0, s1 = 0.0, 0.0
        for i in range(1, n):
            e2 = off[i - 1] * off[i - 1]
            a = diagonal[i] - x
            p0, p1, d0, d1, s0, s1 = (p1, a * p1 - e2 * p0, d1, a * d1 - p1 - e2 * d0,
                                      s1, a * s1 - 2.0 * d1 - e2 * s0)
        if p1 == 0.0:
            return x
        g = d1 / p1
        h = g * g - s1 / p1
        root = np.sqrt(max((n - 1) * (n * h - g * g), 0.0))
        step = n / (g + root if abs(g + root) >= abs(g - root) else g - root)
        x -= step
        if abs(step) <= 1e-13 * abs(x):
            break
    return x


@njit(cache=True)
def energy_terms_kernel(gram: np.ndarray, positions: np.ndarray, layouts: np.ndarray) -> tuple[np.ndarray,
                                                                                              np.ndarray]:
    """Per layout ``(P, k)``: mean over keyframes of κ(JᵀJ) with ``JᵀJ = Σ gram`` (inf when singular;
    0 when ``3k < c``, too few rows to be regular) and the minimum squared marker distance (mm², inf for
    ``k = 1``). ``gram (K, C, c, c)``, ``positions (K, C, 3)``."""
    n_keyframes, _, columns, _ = gram.shape
    n_layouts, n_markers = layouts.shape
    condition = np.zeros(n_layouts)
    min_squared = np.full(n_layouts, np.inf)
    matrix = np.empty((columns, columns))
    for key in range(n_keyframes):             # keyframe outermost: its candidate data stays in cache
        for layout in range(n_layouts):
            matrix[:, :] = 0.0
            for marker in range(n_markers):
                candidate = layouts[layout, marker]
                for i in range(columns):
                    for j in range(i, columns):
                        matrix[i, j] += gram[key, candidate, i, j]
                for other in range(marker):
                    second = layouts[layout, other]
                    squared = 0.0
                    for axis in range(3):
                        delta = positions[key, candidate, axis] - positions[key, second, axis]
                        squared += delta * delta
                    min_squared[layout] = min(min_squared[layout], squared)
            if 3 * n_markers < columns:
                continue
            bound = 0.0
            for i in range(columns):
                row = 0.0
                for j in range(columns):
                    row += abs(matrix[min(i, j), max(i, j)])
                bound = max(bound, row)
            for i in range(columns):
                for j in range(i):
                    matrix[i, j] = matrix[j, i]
            diagonal, off = _tridiagonal(matrix)
            largest = _laguerre_root(diagonal, off, bound)
            smallest = _laguerre_root(diagonal, off, 0.0)
            if smallest <= RANK_TOLERANCE * largest:
                condition[layout] = np.inf
            else:
                condition[layout] += largest / smallest / n_keyframes
    return condition, min_squared


def _partial_condition(problem: LayoutProblem, layouts: np.ndarray) -> np.ndarray:
    """For ``3k < c`` (greedy add phase): mean over keyframes of ``λ_max / λ_3k`` of ``JᵀJ``, the
    condition of the constrained part, ``(P,)``; inf when singular."""
    eigenvalues = np.linalg.eigvalsh(problem.gram[:, layouts].sum(axis=2))      # (K, P, c) ascending
    largest, smallest = eigenvalues[..., -1], eigenvalues[..., -3 * layouts.shape[1]]
    singular = smallest <= RANK_TOLERANCE * largest
    return np.where(singular, np.inf, largest / np.where(singular, 1.0, smallest)).mean(axis=0)


def layout_energies(problem: LayoutProblem, layouts: np.ndarray) -> np.ndarray:
    """``E (P,)`` for layouts ``(P, k)`` of candidate indices (a duplicate gives distance 0)."""
    layouts = np.ascontiguousarray(np.atleast_2d(layouts), dtype=np.int64)
    condition, min_squared = energy_terms_kernel(problem.gram, problem.positions, layouts)
    if 3 * layouts.shape[1] < problem.n_columns:
        condition = _partial_condition(problem, layouts)
    distance_energy = -np.sqrt(np.where(np.isfinite(min_squared), min_squared, 0.0)) / problem.hand_length
    return CONDITION_WEIGHT * condition + DISTANCE_WEIGHT * distance_energy


def layout_terms(problem: LayoutProblem, layout: np.ndarray) -> dict[str, float]:
    """The terms of one layout ``(k,)`` computed directly (SVD of the stacked Jacobians, all marker
    pairs): ``condition`` (E_cond), ``min_distance_mm``, ``distance`` (E_dist) and ``energy``."""
    layout = np.asarray(layout)
    jacobian = problem.jacobians[:, layout].reshape(len(problem.keyframe_angles), -1, problem.n_columns)
    singular = np.linalg.svd(jacobian, compute_uv=False)            # (K, c), descending
    smallest = singular[:, min(3 * len(layout), problem.n_columns) - 1]
    singular_frame = smallest**2 <= RANK_TOLERANCE * singular[:, 0] ** 2
    kappa = np.where(singular_frame, np.inf, singular[:, 0] ** 2 / np.where(singular_frame, 1.0, smallest**2))
    first, second = np.triu_indices(len(layout), k=1)
    points = problem.positions[:, layout]
    distances = np.linalg.norm(points[:, first] - points[:, second], axis=2)
    distance = float(distances.min()) if distances.size else float("inf")
    distance_energy = -distance / problem.hand_length if np.isfinite(distance) else 0.0
    condition = float(kappa.mean())
    return {"condition": condition, "min_distance_mm": distance, "distance": distance_energy,
            "energy": CONDITION_WEIGHT * condition + DISTANCE_WEIGHT * distance_energy}
