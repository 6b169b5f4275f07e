"""Articulated ICP (thesis Ch. 6) with the marker term: a fast local alternative to the swarm.

Per iteration, with correspondences fixed, a damped Gauss-Newton step on

    E = wm/M Σ‖x_i(θ) − m_i‖²                         labelled markers seen in the frame (mm²)
      + wd/N Σ ρ(nᵀ(y_j(θ) − t_j))                     depth points t_j ↔ closest front-facing model point y_j
                                                        (point-to-plane, ℓ1-like by IRLS, thesis eq. 6.2)
      + ws/R Σ (z/f)²‖π(x_k(θ)) − q_k‖²                rendered pixels outside the observed silhouette ↔ the
                                                        nearest observed silhouette pixel q_k (thesis eq. 6.3)
      + ωp ‖W A (θf − μ)‖²                              soft PCA prior (thesis §6.4.4) over the (adaptive)
                                                        subspace, on the digits whose markers are not all seen
      + ωt ‖θf − θf(t−1)‖²                              temporal prior on the finger angles
      (+ ωf/R Σ ρ(z_k(θ) − d_k)                          rendered pixels in front of the observed surface, pushed
                                                        back to it, and
       + ωc/S Σ (z/f)²‖π(x_k(θ)) − p_k‖²                 observed silhouette pixels the model leaves uncovered,
                                                        each pulling the nearest rendered pixel's vertex: the
                                                        two directions the thesis' one-sided terms leave open)

with the step halved until the energy (same correspondences) decreases; finger angles stay within the joint
limits. Residuals are in mm (pixel residuals scaled by depth / focal length), so weights are comparable.

The other terms of thesis eq. 6.1 are there when their weight is set (:mod:`core.fusion.kinematic_terms`):
``E_wrist`` (the wrist on the forearm's image axis, :class:`FitExtras`), ``E_collision`` (neighbouring fingers
do not pass through each other), ``E_temporal`` on the chain points (velocity and acceleration against the two
previous frames, instead of ωt above when :class:`FitExtras` gives them); the first ``rigid_iterations`` move the
wrist only (thesis "rigid bias"); ``prior_matrix`` may carry the pull to the mean (thesis eq. 6.6, see
:func:`core.prior.pca_prior.soft_prior_matrix`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from handmocap.core.camera.model import Camera
from handmocap.core.fusion.hand_render import HandRenderer, Rendering
from handmocap.core.fusion.kinematic_terms import BonePoints, CollisionTerm, chain_points, temporal_rows, wrist_rows
from handmocap.core.fusion.observation import Observation
from handmocap.core.fusion.pose import left_compose
from handmocap.core.model import MarkerSet, marker_jacobian
from handmocap.core.model.kinematics import ANCESTOR, points_and_jacobian_kernel
from handmocap.core.model.skeleton import N_GLOBAL, N_JOINTS, N_PARAMS


@dataclass(frozen=True)
class ICPSettings:
    """Weights (see the module docstring) and sizes of the articulated ICP."""

    iterations: int = 6
    depth_points: int = 300
    model_points: int = 1500
    max_distance_mm: float = 25.0
    marker_weight: float = 20.0
    depth_weight: float = 1.0
    silhouette_weight: float = 1.0
    prior_weight: float = 4.0
    temporal_weight: float = 1.0
    #: IRLS floor (mm) of the ℓ1-like depth residual weight 1 / max(|r|, floor)
    irls_floor_mm: float = 2.0
    #: first iterations that move the wrist only (thesis "rigid bias")
    rigid_iterations: int = 0
    #: ``E_wrist`` weight (per mm² of the wrist's distance to the forearm axis)
    wrist_weight: float = 0.0
    #: ``E_collision`` weight (per mm² of penetration)
    collision_weight: float = 0.0
    #: ``E_temporal`` weights (per mm² of a chain point's velocity / acceleration, mean over the points)
    velocity_weight: float = 0.0
    acceleration_weight: float = 0.0
    #: weight (per mm², mean over the assigned tips) of detected fingertips (:class:`FitExtras`)
    tip_weight: float = 0.0
    #: weight of the model-to-data depth term: rendered pixels of the model in front of the observed surface
    #: (inside the observed silhouette) are pushed back to it (ℓ1-like like the depth term). The data-to-model
    #: term alone leaves a finger bent towards the camera in place when its data points find other fingers closer
    front_weight: float = 0.0
    #: a rendered pixel counts as in front when it is nearer than the observed surface by more than this (mm)
    front_margin_mm: float = 5.0
    #: weight of the silhouette coverage term: observed silhouette pixels the rendered model leaves uncovered
    #: pull the nearest rendered pixel's vertex towards them (the converse of the silhouette term, which alone
    #: lets the model shrink its outline by tilting away from the camera)
    coverage_weight: float = 0.0


@dataclass
class FitExtras:
    """Data for the optional terms: the forearm's image axis ``wrist_line`` (point (2,), direction (2,) px) and
    the chain points (21,3) mm of the two previous frames ``history`` (t−1, t−2 or None)."""

    wrist_line: tuple[np.ndarray, np.ndarray] | None = None
    history: tuple[np.ndarray, np.ndarray | None] | None = None
    #: detected fingertips (5,3) mm per digit (NaN: none), the initialisation of Qian et al. the thesis uses
    tip_targets: np.ndarray | None = None


class _PointSet:
    """Skinning data of a subset of the model's vertices (for their positions and Jacobians)."""

    def __init__(self, renderer: HandRenderer, vertices: np.ndarray) -> None:
        self.vertices = vertices
        self.joints = np.ascontiguousarray(renderer.influence_joints[vertices])
        self.weights = np.ascontiguousarray(renderer.influence_weights[vertices])
        self.local = np.ascontiguousarray(renderer.local_points[vertices])
        self.rest_normals = renderer.model.vertex_normals[vertices]
        self.chain = renderer.model.chain

    def evaluate(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (P,3) mm and Jacobian (P,3,26)."""
        chain = self.chain
        return points_and_jacobian_kernel(np.ascontiguousarray(theta, float), chain.relative_rest, chain.offsets,
                                          chain.abduction_sign, ANCESTOR, self.joints, self.weights, self.local)

    def normals(self, theta: np.ndarray) -> np.ndarray:
        """Posed unit normals (P,3) (rest normals moved by the blended skinning rotations)."""
        linear, _ = self.chain.skinning_matrices(theta)
        moved = np.einsum("pk,pkab,pb->pa", self.weights, linear[self.joints], self.rest_normals)
        return moved / np.maximum(np.linalg.norm(moved, axis=1, keepdims=True), 1e-12)


class ArticulatedICP:
    """Fits the model to one observation from a start pose (see the module docstring)."""

    def __init__(self, renderer: HandRenderer, markers: MarkerSet, lower: np.ndarray, upper: np.ndarray,
                 settings: ICPSettings | None = None) -> None:
        self.renderer, self.markers = renderer, markers
        self.lower, self.upper = lower, upper
        self.settings = settings or ICPSettings()
        step = max(1, len(renderer.model.vertices) // self.settings.model_points)
        self.sample = _PointSet(renderer, np.arange(0, len(renderer.model.vertices), step))
        self._all = np.arange(len(renderer.model.vertices))
        self.camera: Camera = renderer.camera
        self._collisions: CollisionTerm | None = None
        self._chain: BonePoints | None = None

    def fit(self, start: np.ndarray, observation: Observation, prior_matrix: np.ndarray | None, prior_mean: np.ndarray,
            prior_digits: np.ndarray, previous: np.ndarray | None, extras: FitExtras | None = None) -> np.ndarray:
        """The fitted pose (26,) from ``start``. ``prior_matrix (20,20)`` (None: no posture prior) and
        ``prior_mean (20,)``; ``prior_digits (5,)`` bool: digits the prior holds; ``previous (26,)`` or None;
        ``extras``: the forearm axis and the chain points of the previous frames for the optional terms."""
        settings = self.settings
        extras = extras or FitExtras()
        theta = np.clip(start, self.lower, self.upper)
        targets = observation.depth_points(self.camera, settings.depth_points)
        seen = np.isfinite(observation.markers).all(axis=1)
        digit_weight = np.repeat(prior_digits.astype(float), 4)
        for iteration in range(settings.iterations):
            problem = self._linearise(theta, observation, targets, seen)
            terms = [problem[:3]]
            if prior_matrix is not None and settings.prior_weight > 0 and digit_weight.any():
                matrix = np.sqrt(settings.prior_weight) * digit_weight[:, None] * prior_matrix
                terms.append(_posture_rows(matrix, theta[N_GLOBAL:] - prior_mean))
            if previous is not None and settings.temporal_weight > 0 and extras.history is None:
                terms.append(_posture_rows(np.sqrt(settings.temporal_weight) * np.eye(N_PARAMS - N_GLOBAL),
                                           theta[N_GLOBAL:] - previous[N_GLOBAL:]))
            extra_terms = self._extra_terms(extras)
            terms.extend(_rows_system(*term(theta)) for term in extra_terms)
            hessian = sum(term[0] for term in terms)
            gradient = sum(term[1] for term in terms)
            energy = sum(term[2] for term in terms)
            damping = 1e-3 * np.diag(hessian) + 1e-6
            system = hessian + np.diag(damping)
            if iteration < settings.rigid_iterations:
                step = np.zeros(N_PARAMS)
                step[:N_GLOBAL] = -np.linalg.solve(system[:N_GLOBAL, :N_GLOBAL], gradient[:N_GLOBAL])
            else:
                step = -np.linalg.solve(system, gradient)
            for _ in range(5):
                candidate = np.clip(left_compose(theta, step), self.lower, self.upper)
                value = self._energy(candidate, problem, prior_matrix, prior_mean, digit_weight,
                                     previous if extras.history is None else None)
                value += sum(_squared(term(candidate)[0]) for term in extra_terms)
                if value < energy:
                    theta = candidate
                    break
                step = step / 2
            else:
                if iteration >= settings.rigid_iterations:
                    break
        return theta

    def _extra_terms(self, extras: FitExtras) -> list[Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]]:
        """The optional terms as functions ``theta -> (weighted residuals (K,), rows (K,26))``."""
        settings = self.settings
        terms: list[Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]] = []
        model = self.renderer.model
        if settings.wrist_weight > 0 and extras.wrist_line is not None:
            point, direction = extras.wrist_line
            weight = np.sqrt(settings.wrist_weight)

            def wrist(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                residual, rows = wrist_rows(model, self.camera, theta, point, direction)
                return weight * residual, weight * rows
            terms.append(wrist)
        if settings.collision_weight > 0:
            if self._collisions is None:
                self._collisions = CollisionTerm(model)
            collisions = self._collisions
            weight = np.sqrt(settings.collision_weight)

            def collision(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                residual, rows = collisions.rows(theta)
                return weight * residual, weight * rows
            terms.append(collision)
        if extras.history is not None and (settings.velocity_weight > 0 or settings.acceleration_weight > 0):
            if self._chain is None:
                self._chain = chain_points(model)
            chain = self._chain
            last, before = extras.history

            def temporal(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                return temporal_rows(chain, theta, last, before, settings.velocity_weight,
                                     settings.acceleration_weight)
            terms.append(temporal)
        if extras.tip_targets is not None and settings.tip_weight > 0:
            if self._chain is None:
                self._chain = chain_points(model)
            chain = self._chain
            assigned = np.nonzero(np.isfinite(extras.tip_targets).all(axis=1))[0]
            if len(assigned):
                targets = extras.tip_targets[assigned]
                weight = np.sqrt(settings.tip_weight / len(assigned))

                def tips(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                    positions, jacobian = chain.evaluate(theta)
                    rows = jacobian[N_JOINTS + assigned].reshape(-1, N_PARAMS)
                    return weight * (positions[N_JOINTS + assigned] - targets).reshape(-1), weight * rows
                terms.append(tips)
        return terms

    def _linearise(self, theta: np.ndarray, observation: Observation, targets: np.ndarray, seen: np.ndarray) -> tuple:
        """Normal equations of the data terms at ``theta``: ``(H (26,26), g (26,), E, correspondences)``."""
        settings = self.settings
        hessian, gradient, energy = np.zeros((N_PARAMS, N_PARAMS)), np.zeros(N_PARAMS), 0.0
        marker_rows = None
        if seen.any() and settings.marker_weight > 0:
            positions, jacobian = marker_jacobian(self.renderer.model, self.markers, theta)
            residual = (positions - observation.markers)[seen].reshape(-1)
            rows = jacobian[seen].reshape(-1, N_PARAMS)
            weight = settings.marker_weight / seen.sum()
            energy += _add_rows(hessian, gradient, weight, residual, rows)
            marker_rows = weight
        depth = self._depth_correspondences(theta, targets)
        if depth is not None:
            index, target, normal, weight = depth
            positions, jacobian = self.sample.evaluate(theta)
            residual = np.einsum("pa,pa->p", normal, positions[index] - target)
            rows = np.einsum("pa,pab->pb", normal, jacobian[index])
            energy += _add_weighted_rows(hessian, gradient, weight, residual, rows)
        rendering = None
        if (settings.silhouette_weight > 0 or settings.front_weight > 0 or settings.coverage_weight > 0) \
                and observation.silhouette.any():
            rendering = self.renderer.render(theta, observation.crop, with_edges=False)
        silhouette = self._silhouette_correspondences(observation, rendering)
        coverage = self._coverage_correspondences(observation, rendering)
        for pixels in (silhouette, coverage):
            if pixels is not None:
                vertex_set, goal, scale, weight = pixels
                residual, rows = self._projection_rows(theta, vertex_set, goal, scale)
                energy += _add_rows(hessian, gradient, weight, residual, rows)
        front = self._front_correspondences(observation, rendering)
        if front is not None:
            residual, rows = self._front_rows(theta, front)
            energy += _add_weighted_rows(hessian, gradient, front[2], residual, rows)
        return hessian, gradient, energy, (marker_rows, seen, observation.markers, depth, silhouette, front, coverage)

    def _energy(self, theta: np.ndarray, problem: tuple, prior_matrix: np.ndarray | None, prior_mean: np.ndarray,
                digit_weight: np.ndarray, previous: np.ndarray | None) -> float:
        """The energy at ``theta`` with the correspondences of ``problem`` kept."""
        marker_weight, seen, markers, depth, silhouette, front, coverage = problem[3]
        energy = 0.0
        if marker_weight is not None:
            positions, _ = marker_jacobian(self.renderer.model, self.markers, theta)
            residual = (positions - markers)[seen]
            energy += marker_weight * float((residual ** 2).sum())
        if depth is not None:
            index, target, normal, weight = depth
            positions, _ = self.sample.evaluate(theta)
            energy += float(weight @ np.einsum("pa,pa->p", normal, positions[index] - target) ** 2)
        if silhouette is not None:
            vertex_set, goal, scale, weight = silhouette
            residual, _ = self._projection_rows(theta, vertex_set, goal, scale)
            energy += weight * float(residual @ residual)
        if front is not None:
            residual, _ = self._front_rows(theta, front)
            energy += float(front[2] @ residual ** 2)
        if coverage is not None:
            vertex_set, goal, scale, weight = coverage
            residual, _ = self._projection_rows(theta, vertex_set, goal, scale)
            energy += weight * float(residual @ residual)
        if prior_matrix is not None and self.settings.prior_weight > 0:
            off = digit_weight * (prior_matrix @ (theta[N_GLOBAL:] - prior_mean))
            energy += self.settings.prior_weight * float(off @ off)
        if previous is not None and self.settings.temporal_weight > 0:
            energy += self.settings.temporal_weight * float(((theta - previous)[N_GLOBAL:] ** 2).sum())
        return energy

    def _depth_correspondences(self, theta: np.ndarray, targets: np.ndarray) -> tuple | None:
        """``(model point index (N,), target (N,3), normal (N,3), row weight (N,))`` or None: each depth point
        with its closest front-facing model point within ``max_distance_mm``."""
        settings = self.settings
        if len(targets) == 0 or settings.depth_weight <= 0:
            return None
        positions, _ = self.sample.evaluate(theta)
        normals = self.sample.normals(theta)
        facing = np.einsum("pa,pa->p", normals, positions - self.camera.centre) < 0
        if facing.sum() < 3:
            return None
        candidates = np.nonzero(facing)[0]
        from scipy.spatial import cKDTree  # imported when first needed (start-up)

        distance, nearest = cKDTree(positions[candidates]).query(targets)
        keep = np.asarray(distance < settings.max_distance_mm, dtype=bool)
        if not keep.any():
            return None
        index = candidates[np.asarray(nearest)[keep]]
        target = targets[keep]
        normal = normals[index]
        residual = np.abs(np.einsum("pa,pa->p", normal, positions[index] - target))
        weight = settings.depth_weight / keep.sum() * settings.irls_floor_mm / np.maximum(residual,
                                                                                           settings.irls_floor_mm)
        return index, target, normal, weight

    def _coverage_correspondences(self, observation: Observation, rendering: Rendering | None) -> tuple | None:
        """``(_PointSet of the vertices, goal pixels (K,2) image px, mm per px (K,), weight)`` for the observed
        silhouette pixels outside the rendered model: each pulls the vertex of the nearest rendered pixel."""
        if self.settings.coverage_weight <= 0 or rendering is None or not rendering.silhouette.any():
            return None
        missed = observation.silhouette & ~rendering.silhouette
        if not missed.any():
            return None
        _, (near_rows, near_columns) = _nearest_pixels(~rendering.silhouette)
        rows, columns = np.nonzero(missed)
        vertices = self.renderer.faces[rendering.face[near_rows[rows, columns], near_columns[rows, columns]], 0]
        crop = observation.crop
        goal = np.column_stack([crop.left + crop.stride * columns, crop.top + crop.stride * rows]).astype(float)
        scale = rendering.points[vertices, 2] / self.camera.focal[0]
        weight = self.settings.coverage_weight / max(int(observation.silhouette.sum()), 1)
        return _PointSet(self.renderer, vertices), goal, scale, weight

    def _front_correspondences(self, observation: Observation, rendering: Rendering | None) -> tuple | None:
        """``(_PointSet of the vertices, goal camera z (K,) mm, row weight (K,))`` for the rendered pixels inside the
        observed silhouette where the model is in front of the observed surface, or None."""
        settings = self.settings
        if settings.front_weight <= 0 or rendering is None:
            return None
        observed = observation.depth
        front = (rendering.silhouette & observation.silhouette & (observed > 0)
                 & (rendering.depth < observed - settings.front_margin_mm))
        if not front.any():
            return None
        rows, columns = np.nonzero(front)
        vertices = self.renderer.faces[rendering.face[rows, columns], 0]
        # the vertex moves back by as much as its pixel is in front
        gap = rendering.depth[rows, columns].astype(float) - observed[rows, columns]
        goal = rendering.points[vertices, 2] - gap
        weight = (settings.front_weight / max(int(rendering.silhouette.sum()), 1) * settings.irls_floor_mm
                  / np.maximum(np.abs(gap), settings.irls_floor_mm))
        return _PointSet(self.renderer, vertices), goal, weight

    def _front_rows(self, theta: np.ndarray, front: tuple) -> tuple[np.ndarray, np.ndarray]:
        """Camera-z residuals (K,) mm of the in-front vertices to their goals and their rows (K,26)."""
        vertex_set, goal, _ = front
        positions, jacobian = vertex_set.evaluate(theta)
        depth_axis = self.camera.rotation[2]
        z = positions @ depth_axis + self.camera.translation[2]
        return z - goal, np.einsum("a,kab->kb", depth_axis, jacobian)

    def _silhouette_correspondences(self, observation: Observation, rendering: Rendering | None) -> tuple | None:
        """``(_PointSet of the vertices, goal pixels (K,2) image px, mm per px (K,), weight)`` for the rendered
        pixels outside the observed silhouette, or None."""
        if self.settings.silhouette_weight <= 0 or rendering is None:
            return None
        outside = rendering.silhouette & ~observation.silhouette
        if not outside.any():
            return None
        _, (near_rows, near_columns) = _nearest_pixels(~observation.silhouette)
        rows, columns = np.nonzero(outside)
        vertices = self.renderer.faces[rendering.face[rows, columns], 0]
        crop = observation.crop
        goal = np.column_stack([crop.left + crop.stride * near_columns[rows, columns],
                                crop.top + crop.stride * near_rows[rows, columns]]).astype(float)
        depth = rendering.points[vertices, 2]
        scale = depth / self.camera.focal[0]
        weight = self.settings.silhouette_weight / max(int(rendering.silhouette.sum()), 1)
        return _PointSet(self.renderer, vertices), goal, scale, weight

    def _projection_rows(self, theta: np.ndarray, vertex_set: _PointSet, goal: np.ndarray, scale: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Scaled pixel residuals (2K,) mm and their Jacobian (2K,26) of the vertices' projections to ``goal``."""
        positions, jacobian = vertex_set.evaluate(theta)
        camera = self.camera
        points = camera.to_camera(positions)
        (fx, fy), (cx, cy) = camera.focal, camera.principal_point
        z = points[:, 2]
        pixels = np.column_stack([fx * points[:, 0] / z + cx, fy * points[:, 1] / z + cy])
        residual = ((pixels - goal) * scale[:, None]).reshape(-1)
        perspective = np.zeros((len(z), 2, 3))
        perspective[:, 0, 0] = fx / z
        perspective[:, 0, 2] = -fx * points[:, 0] / z ** 2
        perspective[:, 1, 1] = fy / z
        perspective[:, 1, 2] = -fy * points[:, 1] / z ** 2
        rows = np.einsum("kij,jl,klp->kip", perspective, camera.rotation, jacobian) * scale[:, None, None]
        return residual, rows.reshape(-1, N_PARAMS)


def _add_rows(hessian: np.ndarray, gradient: np.ndarray, weight: float, residual: np.ndarray, rows: np.ndarray
              ) -> float:
    """Adds a term of linearised ``residual`` (n,) and ``rows`` (n,26) with one ``weight`` to the normal
    equations ``hessian``, ``gradient`` (in place); returns its energy."""
    hessian += weight * rows.T @ rows
    gradient += weight * rows.T @ residual
    return weight * residual @ residual


def _add_weighted_rows(hessian: np.ndarray, gradient: np.ndarray, weight: np.ndarray, residual: np.ndarray,
                       rows: np.ndarray) -> float:
    """As :func:`_add_rows` with a weight (n,) per residual."""
    hessian += (weight[:, None] * rows).T @ rows
    gradient += (weight * residual) @ rows
    return float(weight @ residual ** 2)


def _posture_rows(matrix: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Normal equations of ``‖matrix · value‖²`` over the finger angles, padded to 26 parameters."""
    residual = matrix @ value
    hessian, gradient = np.zeros((N_PARAMS, N_PARAMS)), np.zeros(N_PARAMS)
    hessian[N_GLOBAL:, N_GLOBAL:] = matrix.T @ matrix
    gradient[N_GLOBAL:] = matrix.T @ residual
    return hessian, gradient, float(residual @ residual)


def _rows_system(residual: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Normal equations ``(rowsᵀ rows, rowsᵀ residual, ‖residual‖²)`` of linearised residuals."""
    return rows.T @ rows, rows.T @ residual, float(residual @ residual)


def _squared(residual: np.ndarray) -> float:
    return float(residual @ residual)


def _nearest_pixels(background: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Euclidean distance (px) from each pixel of ``background (H,W)`` bool to the nearest False pixel, and
    that pixel's (rows, columns) index arrays (scipy's exact distance transform)."""
    from scipy.ndimage import distance_transform_edt  # imported when first needed (start-up)

    return distance_transform_edt(background, return_indices=True)
