"""Non-rigid template fitting (journal "Hand model generation", eq. 14–17; Achenbach et al. 2015).

Minimises over the template vertices ``X (V,3)`` (mm)

    E(X) = λ_lm / |L| Σ_l ‖x_l − p_l‖²  +  λ_fit / |C| Σ_c ‖x_c − p_c‖²  +  λ_reg / |V| Σ_v ‖Δx_v − R_v Δx̄_v‖²

``Δ`` is the normalised cotangent Laplacian of the template (weights clamped at 0 against obtuse
triangles, divided by their sum, so ``Δx`` is in mm), ``R_v`` the per-vertex transform that best maps
the undeformed one-ring edges onto the deformed ones (ARAP local step, batched 3×3 SVD). Every
iteration alternates the local step and one sparse global solve of the normal equations; the global
system is factorised once per weight/correspondence setting (``splu`` in symmetric mode on the
diagonally equilibrated matrix) and re-used for the inner iterations and the three coordinates; in
the landmark phase, where only λ_reg changes, one factorisation serves every λ through the Woodbury
identity on the rank-|L| landmark term.

Schedule (paper): landmarks only with λ_reg halved every iteration from 1 to 1e-6, then closest-point
fitting (λ_fit = 1) with λ_reg halved from 1e-6 to 1e-8.

Where this implementation settles what the paper leaves open (each measured on synthetic scans with
holes, see ``core.evaluation.calibration``):

* ``R_v`` is a rotation times a per-vertex scale (clamped to :data:`SCALE_RANGE`): subjects' fingers
  differ in length by ±15 %, and a pure rotation makes the surface over a scan hole in a stretched
  region cave in like a tight membrane;
* the local step runs in the landmark phase only; the closest-point phase keeps the transforms it
  ended with (:data:`FIT_ROTATIONS`), because transforms re-estimated from a surface snapped to noisy
  points let the surface over a hole drift by several millimetres per iteration;
* the closest-point target of a vertex is its projection, along its normal, onto the plane through the
  centroid of the :data:`SURFACE_NEIGHBOURS` scan points around its closest scan point (averages the
  scanner noise: mean surface error 0.2 instead of 0.45 mm at 0.5 mm noise);
* correspondences pair every vertex with its closest scan point and are rejected when farther than
  ``max(MIN_REJECT_MM, REJECT_MEDIAN_FACTOR × median)``, when the normals disagree by more than
  ``MAX_NORMAL_ANGLE_DEG``, when the offset runs along the surface (:data:`TANGENTIAL_REJECT_MM`), or
  when the scan point is clearly closer to another vertex (:data:`MUTUAL_MM`): vertices over a hole
  would otherwise all be pulled onto the hole's rim.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree

from handmocap.core.calibration.nearest import nearest_neighbours
from handmocap.core.errors import CancelledError, InputError
from handmocap.core.model.hand_model import mesh_vertex_normals

MAX_NORMAL_ANGLE_DEG = 60.0
REJECT_MEDIAN_FACTOR = 3.0
MIN_REJECT_MM = 3.0
MAX_REJECT_MM = 15.0
SCALE_RANGE = (0.7, 1.4)       # per-vertex scale of the regulariser's similarity (see module docstring)
FIT_ROTATIONS = False          # re-estimate R_v in the closest-point phase too (see module docstring)
SURFACE_NEIGHBOURS = 8         # scan points averaged into one closest-point target
MUTUAL_MM = 0.5                # see closest_point_pairs
TANGENTIAL_REJECT_MM = 1.5     # pairs whose offset has a larger component along the surface are rejected
                               # (vertices over a hole would otherwise be dragged onto the hole's rim)


@dataclass(frozen=True)
class FitSchedule:
    """The λ schedule of the fit (defaults: the paper's)."""

    reg_start: float = 1.0
    reg_landmark_end: float = 1e-6
    reg_fit_end: float = 1e-8
    lambda_landmark: float = 1.0
    lambda_fit: float = 1.0
    inner_iterations: int = 2          # local/global iterations per weight setting (one factorisation)
    reg_factor: float = 0.5            # λ_reg multiplier per outer iteration

    def steps(self) -> list[tuple[str, float]]:
        """``(phase, λ_reg)`` of every outer iteration; phase is ``"landmarks"`` or ``"fit"``."""
        result = []
        reg = self.reg_start
        while reg >= self.reg_landmark_end * (1 - 1e-9):
            result.append(("landmarks", reg))
            reg *= self.reg_factor
        reg = self.reg_landmark_end
        while reg >= self.reg_fit_end * (1 - 1e-9):
            result.append(("fit", reg))
            reg *= self.reg_factor
        return result


def cotangent_laplacian(vertices: np.ndarray, faces: np.ndarray) -> tuple[sparse.csr_matrix, np.ndarray,
                                                                            np.ndarray, np.ndarray]:
    """Normalised cotangent Laplacian ``Δ (V,V)`` (rows: Σ_j w_ij x_j / Σ_j w_ij − x_i) and the directed
    edges ``rows (E,)``, ``cols (E,)`` with their normalised weights ``(E,)``."""
    count = len(vertices)
    rows_list, cols_list, weights_list = [], [], []
    for k in range(3):
        i, j, o = faces[:, k], faces[:, (k + 1) % 3], faces[:, (k + 2) % 3]
        a, b = vertices[i] - vertices[o], vertices[j] - vertices[o]
        cross = np.linalg.norm(np.cross(a, b), axis=1)
        cot = np.einsum("na,na->n", a, b) / np.maximum(cross, 1e-12)
        weight = np.maximum(0.5 * cot, 1e-3)
        rows_list += [i, j]
        cols_list += [j, i]
        weights_list += [weight, weight]
    matrix = sparse.coo_matrix((np.concatenate(weights_list), (np.concatenate(rows_list),
                                                               np.concatenate(cols_list))),
                               shape=(count, count)).tocsr()
    matrix.sum_duplicates()
    totals = np.asarray(matrix.sum(axis=1)).ravel()
    normalised = sparse.diags(1.0 / np.maximum(totals, 1e-12)) @ matrix
    normalised = normalised.tocsr()
    coo = normalised.tocoo()
    laplacian = (normalised - sparse.identity(count, format="csr")).tocsr()
    return laplacian, coo.row.astype(np.int64), coo.col.astype(np.int64), coo.data


def best_rotations(rest: np.ndarray, deformed: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                   weights: np.ndarray, with_scale: bool = True) -> np.ndarray:
    """Per-vertex similarity parts ``s_v R_v`` (V,3,3) best mapping the rest one-ring edges onto the deformed
    ones (Umeyama per one-ring; ``s_v = 1`` without ``with_scale``, scales clamped to ``SCALE_RANGE``)."""
    rest_edges = rest[cols] - rest[rows]
    deformed_edges = deformed[cols] - deformed[rows]
    products = weights[:, None, None] * deformed_edges[:, :, None] * rest_edges[:, None, :]   # (E,3,3)
    covariance = np.zeros((len(rest), 9))
    flat = products.reshape(-1, 9)
    for k in range(9):
        covariance[:, k] = np.bincount(rows, weights=flat[:, k], minlength=len(rest))
    u, singular, vt = np.linalg.svd(covariance.reshape(-1, 3, 3))
    signs = np.ones((len(rest), 3))
    signs[:, 2] = np.sign(np.linalg.det(u) * np.linalg.det(vt))
    signs[signs == 0] = 1.0
    rotations = (u * signs[:, None, :]) @ vt
    if not with_scale:
        return rotations
    variance = np.bincount(rows, weights=weights * np.einsum("ea,ea->e", rest_edges, rest_edges),
                           minlength=len(rest))
    scales = np.clip(np.einsum("va,va->v", singular, signs) / np.maximum(variance, 1e-12), *SCALE_RANGE)
    return rotations * scales[:, None, None]


def estimate_normals(points: np.ndarray, k: int = 12) -> np.ndarray:
    """Unoriented unit normals (N,3) of a point cloud from the PCA of ``k`` nearest neighbours."""
    _, neighbours = nearest_neighbours(cKDTree(points), points, k=min(k, len(points)))
    local = points[neighbours] - points[neighbours].mean(axis=1, keepdims=True)
    covariance = np.einsum("nka,nkb->nab", local, local)
    _, vectors = np.linalg.eigh(covariance)
    return vectors[:, :, 0]


class _Factor:
    """Sparse LU of a symmetric positive definite system ``A``, equilibrated as ``D^-½ A D^-½``
    (``D = diag A``): the data rows (weights ~1/|C|) and the rows of unsupported vertices (~λ_reg/|V|)
    differ by up to 1e8, which without scaling costs millimetres of accuracy inside scan holes."""

    def __init__(self, system: sparse.spmatrix) -> None:
        system = sparse.csc_matrix(system)
        self.scale = 1.0 / np.sqrt(np.maximum(system.diagonal(), 1e-300))
        scaling = sparse.diags(self.scale)
        self.lu = splu(sparse.csc_matrix(scaling @ system @ scaling), permc_spec="MMD_AT_PLUS_A",
                       diag_pivot_thresh=0.0, options={"SymmetricMode": True})

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        scale = self.scale if rhs.ndim == 1 else self.scale[:, None]
        return scale * self.lu.solve(scale * rhs)


def _factorise(system: sparse.spmatrix) -> _Factor:
    return _Factor(system)


class _LandmarkSolver:
    """Solves ``(LᵀL + β SᵀS) x = r`` for any β with one factorisation (Woodbury identity on the
    rank-|L| landmark term): ``K = LᵀL + μ SᵀS`` is factorised once, ``U = Sᵀ``."""

    def __init__(self, normal_matrix: sparse.spmatrix, selector: sparse.csr_matrix, reference: float) -> None:
        self.reference = reference
        self.factor = _factorise(normal_matrix + reference * (selector.T @ selector))
        self.selector = selector
        self.k_inverse_u = self.factor.solve(np.asarray(selector.T.todense()))          # (V,L)
        self.gram = np.asarray(selector @ self.k_inverse_u)                             # (L,L)

    def solve(self, rhs: np.ndarray, beta: float) -> np.ndarray:
        solution = self.factor.solve(rhs)
        change = beta - self.reference
        if abs(change) < 1e-12 * self.reference:
            return solution
        small = np.eye(len(self.gram)) / change + self.gram
        return solution - self.k_inverse_u @ np.linalg.solve(small, self.selector @ solution)


def _solve_landmarks(solver: _LandmarkSolver, w_reg: float, beta: float, rhs: np.ndarray) -> np.ndarray:
    """``(w_reg LᵀL + w_lm SᵀS) x = rhs`` solved as ``(LᵀL + β SᵀS) x = rhs / w_reg`` (β = w_lm / w_reg)."""
    return solver.solve(rhs / w_reg, beta)


@dataclass
class FitResult:
    """Output of :func:`fit_nonrigid`: ``vertices (V,3)`` mm, ``iterations``, last correspondence count,
    and the landmark RMS (mm) after each outer iteration."""

    vertices: np.ndarray
    iterations: int
    correspondences: int
    landmark_rms_mm: list[float]


def closest_point_pairs(vertices: np.ndarray, normals: np.ndarray, tree: cKDTree, scan_points: np.ndarray,
                        scan_normals: np.ndarray | None, oriented: bool = True,
                        candidates: np.ndarray | None = None, tangential_mm: float | None = None,
                        mutual_mm: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Accepted ``(vertex indices (C,), scan point indices (C,))`` of the closest-point correspondences.

    Rejected: farther than ``max(MIN_REJECT_MM, REJECT_MEDIAN_FACTOR × median)`` (at most
    ``MAX_REJECT_MM``), normals more than ``MAX_NORMAL_ANGLE_DEG`` apart, and, when ``tangential_mm`` is
    given, an offset with a component along the surface longer than that; with ``mutual_mm``, pairs whose
    scan point is more than that closer to another vertex (vertices over a hole all pairing with its rim).
    """
    indices = np.arange(len(vertices)) if candidates is None else candidates
    distances, nearest = nearest_neighbours(tree, vertices[indices], upper_bound_mm=MAX_REJECT_MM)
    finite = np.isfinite(distances)
    if not np.any(finite):
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    limit = max(MIN_REJECT_MM, REJECT_MEDIAN_FACTOR * float(np.median(distances[finite])))
    accepted = finite & (distances <= limit)
    if scan_normals is not None:
        agreement = np.einsum("na,na->n", normals[indices],
                              scan_normals[np.minimum(nearest, len(scan_points) - 1)])
        if not oriented:
            agreement = np.abs(agreement)
        accepted &= agreement >= np.cos(np.radians(MAX_NORMAL_ANGLE_DEG))
    if tangential_mm is not None:
        offsets = scan_points[np.minimum(nearest, len(scan_points) - 1)] - vertices[indices]
        along_normal = np.einsum("na,na->n", offsets, normals[indices])
        tangential = np.sqrt(np.maximum(np.einsum("na,na->n", offsets, offsets) - along_normal ** 2, 0.0))
        accepted &= tangential <= tangential_mm
    if mutual_mm is not None and np.any(accepted):
        chosen = np.flatnonzero(accepted)
        points = scan_points[nearest[chosen]]
        nearest_vertex_distance, _ = nearest_neighbours(cKDTree(vertices), points)
        accepted[chosen] = distances[chosen] <= nearest_vertex_distance + mutual_mm
    return indices[accepted], nearest[accepted]


def _surface_targets(vertices: np.ndarray, normals: np.ndarray, nearest: np.ndarray, tree: cKDTree,
                     scan_points: np.ndarray, radius_mm: float) -> np.ndarray:
    """The scan surface point under each vertex (C,3): the vertex moved along its normal onto the plane
    through the centroid of the :data:`SURFACE_NEIGHBOURS` scan points around its closest scan point
    (within ``radius_mm``). Averaging the scanner noise this way keeps the fitted surface smooth."""
    distances, neighbours = nearest_neighbours(tree, scan_points[nearest], k=SURFACE_NEIGHBOURS,
                                               upper_bound_mm=radius_mm)
    distances, neighbours = distances.reshape(len(nearest), -1), neighbours.reshape(len(nearest), -1)
    valid = np.isfinite(distances)
    safe = np.where(valid, neighbours, 0)
    centroid = (scan_points[safe] * valid[:, :, None]).sum(axis=1) / valid.sum(axis=1, keepdims=True)
    height = np.einsum("na,na->n", centroid - vertices, normals)
    return vertices + height[:, None] * normals


def fit_nonrigid(template_vertices: np.ndarray, faces: np.ndarray, landmark_vertices: np.ndarray,
                 landmark_targets: np.ndarray, scan_points: np.ndarray, scan_normals: np.ndarray | None = None,
                 normals_oriented: bool = True, schedule: FitSchedule | None = None,
                 progress: Callable[[float], None] | None = None, cancelled: Callable[[], bool] | None = None,
                 on_iteration: Callable[[np.ndarray], None] | None = None, tree: cKDTree | None = None,
                 landmark_weights: np.ndarray | None = None) -> FitResult:
    """Deform the aligned template ``template_vertices (V,3)`` onto ``scan_points (N,3)`` (mm).

    ``landmark_vertices (L,)`` template vertex of each landmark, or ``(L,3)`` the corners of the triangle
    holding it with ``landmark_weights (L,3)`` its barycentric coordinates (a point inside a triangle, see
    :func:`core.calibration.align.anatomical_landmarks`); ``landmark_targets (L,3)`` its scan
    position; ``scan_normals (N,3)`` optional (oriented outwards unless ``normals_oriented`` is False).
    ``on_iteration(vertices)`` is called after every outer iteration (live display); ``cancelled()``
    is checked between iterations and raises :class:`CancelledError`.
    """
    schedule = schedule or FitSchedule()
    rest = np.asarray(template_vertices, dtype=np.float64)
    count = len(rest)
    landmark_vertices = np.asarray(landmark_vertices, dtype=np.int64)
    landmark_targets = np.asarray(landmark_targets, dtype=np.float64)
    if len(landmark_vertices) == 0 or landmark_targets.shape != (len(landmark_vertices), 3):
        raise InputError("the non-rigid fit needs landmark pairs (L,) and (L,3)")
    corners = landmark_vertices.reshape(len(landmark_vertices), -1)
    corner_weights = np.ones_like(corners, dtype=np.float64) if landmark_weights is None \
        else np.asarray(landmark_weights, dtype=np.float64).reshape(corners.shape)
    laplacian, rows, cols, weights = cotangent_laplacian(rest, faces)
    rest_laplacian = laplacian @ rest
    normal_matrix = (laplacian.T @ laplacian).tocsc()
    landmark_selector = sparse.coo_matrix((corner_weights.ravel(),
                                           (np.repeat(np.arange(len(corners)), corners.shape[1]), corners.ravel())),
                                          shape=(len(corners), count)).tocsr()
    landmark_selector.sum_duplicates()
    landmark_matrix = (landmark_selector.T @ landmark_selector).tocsc()
    landmark_rhs = landmark_selector.T @ landmark_targets
    tree = tree if tree is not None else cKDTree(scan_points)
    deformed = rest.copy()
    steps = schedule.steps()
    landmark_rms: list[float] = []
    n_pairs = 0
    w_lm = schedule.lambda_landmark / len(landmark_vertices)
    spacing = float(np.median(nearest_neighbours(tree, scan_points[:: max(1, len(scan_points) // 2000)], k=2)[0][:, 1]))
    tangential_mm = max(TANGENTIAL_REJECT_MM, 3.0 * spacing)
    landmark_solver = _LandmarkSolver(normal_matrix, landmark_selector, reference=w_lm * count)
    for step_index, (phase, reg) in enumerate(steps):
        if cancelled is not None and cancelled():
            raise CancelledError("the fit was cancelled; the scan and landmarks are unchanged")
        w_reg = reg / count
        fit_rhs = np.zeros((count, 3))
        solve: Callable[[np.ndarray], np.ndarray]
        if phase == "landmarks":
            solve = partial(_solve_landmarks, landmark_solver, w_reg, w_lm / w_reg)
        else:
            system = w_reg * normal_matrix + w_lm * landmark_matrix
            normals = mesh_vertex_normals(deformed, faces)
            pair_vertices, pair_points = closest_point_pairs(deformed, normals, tree, scan_points, scan_normals,
                                                             normals_oriented, tangential_mm=tangential_mm,
                                                             mutual_mm=MUTUAL_MM)
            n_pairs = len(pair_vertices)
            if n_pairs:
                w_fit = schedule.lambda_fit / n_pairs
                diagonal = np.bincount(pair_vertices, minlength=count).astype(np.float64)
                system = system + w_fit * sparse.diags(diagonal, format="csc")
                targets = _surface_targets(deformed[pair_vertices], normals[pair_vertices], pair_points, tree,
                                           scan_points, 2.0 * tangential_mm)
                for axis in range(3):
                    fit_rhs[:, axis] = w_fit * np.bincount(pair_vertices, weights=targets[:, axis], minlength=count)
            solve = _factorise(system).solve
        for _ in range(schedule.inner_iterations if phase == "landmarks" or FIT_ROTATIONS else 1):
            if phase == "landmarks" or FIT_ROTATIONS:
                rotations = best_rotations(rest, deformed, rows, cols, weights)
            target_laplacian = np.einsum("vab,vb->va", rotations, rest_laplacian)
            rhs = w_reg * (laplacian.T @ target_laplacian) + w_lm * landmark_rhs + fit_rhs
            deformed = solve(rhs)
        landmark_rms.append(float(np.sqrt(np.mean(np.sum((landmark_selector @ deformed - landmark_targets) ** 2,
                                                         axis=1)))))
        if on_iteration is not None:
            on_iteration(deformed.copy())
        if progress is not None:
            progress((step_index + 1) / len(steps))
    return FitResult(deformed, len(steps), n_pairs, landmark_rms)
