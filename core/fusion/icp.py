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

with the step halved until the energy (same correspondences) decreases; finger angles stay within the joint
limits. Residuals are in mm (pixel residuals scaled by depth / focal length), so weights are comparable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_edt
from scipy.spatial import cKDTree

from core.camera.model import Camera
from core.fusion.hand_render import HandRenderer
from core.fusion.observation import Observation
from core.fusion.pose import left_compose
from core.model import MarkerSet, marker_jacobian
from core.model.kinematics import ANCESTOR, points_and_jacobian_kernel
from core.model.skeleton import N_GLOBAL, N_PARAMS


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

    def fit(self, start: np.ndarray, observation: Observation, prior_matrix: np.ndarray | None, prior_mean: np.ndarray,
            prior_digits: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
        """The fitted pose (26,) from ``start``. ``prior_matrix (20,20)`` (None: no posture prior) and
        ``prior_mean (20,)``; ``prior_digits (5,)`` bool: digits the prior holds; ``previous (26,)`` or None."""
        settings = self.settings
        theta = np.clip(start, self.lower, self.upper)
        targets = observation.depth_points(self.camera, settings.depth_points)
        seen = np.isfinite(observation.markers).all(axis=1)
        digit_weight = np.repeat(prior_digits.astype(float), 4)
        for _ in range(settings.iterations):
            problem = self._linearise(theta, observation, targets, seen)
            terms = [problem]
            if prior_matrix is not None and settings.prior_weight > 0 and digit_weight.any():
                matrix = np.sqrt(settings.prior_weight) * digit_weight[:, None] * prior_matrix
                terms.append(_posture_rows(matrix, theta[N_GLOBAL:] - prior_mean))
            if previous is not None and settings.temporal_weight > 0:
                terms.append(_posture_rows(np.sqrt(settings.temporal_weight) * np.eye(N_PARAMS - N_GLOBAL),
                                           theta[N_GLOBAL:] - previous[N_GLOBAL:]))
            hessian = sum(term[0] for term in terms)
            gradient = sum(term[1] for term in terms)
            energy = sum(term[2] for term in terms)
            damping = 1e-3 * np.diag(hessian) + 1e-6
            step = -np.linalg.solve(hessian + np.diag(damping), gradient)
            for _ in range(5):
                candidate = np.clip(left_compose(theta, step), self.lower, self.upper)
                if self._energy(candidate, problem, prior_matrix, prior_mean, digit_weight, previous) < energy:
                    theta = candidate
                    break
                step = step / 2
            else:
                break
        return theta

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
            hessian += weight * rows.T @ rows
            gradient += weight * rows.T @ residual
            energy += weight * residual @ residual
            marker_rows = weight
        depth = self._depth_correspondences(theta, targets)
        if depth is not None:
            index, target, normal, weight = depth
            positions, jacobian = self.sample.evaluate(theta)
            residual = np.einsum("pa,pa->p", normal, positions[index] - target)
            rows = np.einsum("pa,pab->pb", normal, jacobian[index])
            hessian += (weight[:, None] * rows).T @ rows
            gradient += (weight * residual) @ rows
            energy += float(weight @ residual ** 2)
        silhouette = self._silhouette_correspondences(theta, observation)
        if silhouette is not None:
            vertex_set, goal, scale, weight = silhouette
            residual, rows = self._projection_rows(theta, vertex_set, goal, scale)
            hessian += weight * rows.T @ rows
            gradient += weight * rows.T @ residual
            energy += weight * residual @ residual
        return hessian, gradient, energy, (marker_rows, seen, observation.markers, depth, silhouette)

    def _energy(self, theta: np.ndarray, problem: tuple, prior_matrix: np.ndarray | None, prior_mean: np.ndarray,
                digit_weight: np.ndarray, previous: np.ndarray | None) -> float:
        """The energy at ``theta`` with the correspondences of ``problem`` kept."""
        marker_weight, seen, markers, depth, silhouette = problem[3]
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

    def _silhouette_correspondences(self, theta: np.ndarray, observation: Observation) -> tuple | None:
        """``(_PointSet of the vertices, goal pixels (K,2) image px, mm per px (K,), weight)`` for the rendered
        pixels outside the observed silhouette, or None."""
        if self.settings.silhouette_weight <= 0 or not observation.silhouette.any():
            return None
        rendering = self.renderer.render(theta, observation.crop, with_edges=False)
        outside = rendering.silhouette & ~observation.silhouette
        if not outside.any():
            return None
        _, (near_rows, near_columns) = distance_transform_edt(~observation.silhouette, return_indices=True)
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


def _posture_rows(matrix: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Normal equations of ``‖matrix · value‖²`` over the finger angles, padded to 26 parameters."""
    residual = matrix @ value
    hessian, gradient = np.zeros((N_PARAMS, N_PARAMS)), np.zeros(N_PARAMS)
    hessian[N_GLOBAL:, N_GLOBAL:] = matrix.T @ matrix
    gradient[N_GLOBAL:] = matrix.T @ residual
    return hessian, gradient, float(residual @ residual)
