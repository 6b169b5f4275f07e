"""Initial alignment of the template to a scan: alternate rigid ICP with scale and posture IK.

Journal "Hand model generation": based on the 20 landmark pairs and closest-point correspondences the
model's pose (translation, rotation, scale) and posture (joint angles) are optimised alternately by
rigid ICP (Umeyama similarity) and IK (the compiled damped Gauss-Newton of :mod:`core.ik.kernel`,
full 26-parameter space, default joint limits). The template is scaled about its wrist joint, so the
posed template is ``skin(scaled template, θ)``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree

from handmocap.core.calibration.nonrigid import closest_point_pairs
from handmocap.core.calibration.rigid import similarity_transform
from handmocap.core.errors import CancelledError, InputError
from handmocap.core.ik.kernel import solve_frame_kernel
from handmocap.core.model import HandModel, MarkerSet, skin_vertices
from handmocap.core.model.hand_model import mesh_vertex_normals
from handmocap.core.model.kinematics import ANCESTOR, rotation_from_vector, vector_from_rotation
from handmocap.core.model.skeleton import DIGITS, N_PARAMS, Skeleton, default_joint_limits
from handmocap.core.model.template_mesh import ray_surface_point

LANDMARK_WEIGHT = 20          # a landmark counts as this many closest-point pairs
SAMPLE_VERTICES = 1500        # template vertices used for closest points in the alignment
IK_DAMPING = 5.0              # mm/rad
LANDMARK_REFINE_MM = 3.0      # a landmark vertex farther than this from its anatomical surface point is kept as is


def scaled_model(model: HandModel, scale: float) -> HandModel:
    """``model`` uniformly scaled by ``scale`` about the rest origin (its wrist joint)."""
    skeleton = Skeleton(model.skeleton.rest_positions * scale, model.skeleton.rest_rotations.copy(),
                        model.skeleton.tip_positions * scale, model.skeleton.side)
    return replace(model, skeleton=skeleton, vertices=model.vertices * scale,
                   hand_length=model.hand_length * scale)


@dataclass
class Alignment:
    """Result of :func:`align_template`: scale (template about its wrist), pose/posture ``theta (26,)``,
    the posed template ``vertices (V,3)`` in the scan frame (mm), landmark RMS (mm) per round."""

    scale: float
    theta: np.ndarray
    vertices: np.ndarray
    landmark_rms_mm: list[float]

    def model(self, template: HandModel) -> HandModel:
        """The scaled template whose ``skin(·, theta)`` gives :attr:`vertices`."""
        return scaled_model(template, self.scale)


def landmark_pairs(model: HandModel, landmarks: dict[str, np.ndarray | None]) -> tuple[list[str], np.ndarray,
                                                                                     np.ndarray]:
    """Names, template vertex indices ``(L,)`` and scan positions ``(L,3)`` of the given landmarks."""
    names = [name for name, value in landmarks.items() if value is not None and name in model.landmarks]
    if len(names) < 3:
        raise InputError(f"only {len(names)} landmarks match the template; at least 3 are needed to align")
    vertices = np.array([model.landmarks[name] for name in names], dtype=np.int64)
    targets = np.array([landmarks[name] for name in names], dtype=np.float64)
    return names, vertices, targets


def anatomical_ray(model: HandModel, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Origin and unit direction (rest frame, mm) of the ray that defines landmark ``name`` on ``model``
    (``LANDMARK_DESCRIPTIONS``): dorsal from a knuckle joint, dorsal (+z) from the wrist joint, along the
    distal bone from the distal joint for a tip."""
    positions, rotations = model.skeleton.rest_positions, model.skeleton.rest_rotations
    if name == "wrist":
        return positions[0], np.array([0.0, 0.0, 1.0])
    digit_name, joint_name = name.split("_")
    digit = DIGITS.index(digit_name)
    if joint_name == "tip":
        distal = 3 + 3 * digit
        return positions[distal], rotations[distal][:, 1]
    names = ("cmc", "mcp", "ip") if digit == 0 else ("mcp", "pip", "dip")
    joint = 1 + 3 * digit + names.index(joint_name)
    return positions[joint], -rotations[joint][:, 2]


def anatomical_landmarks(model: HandModel, names: list[str] | tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Exact surface points of the landmarks ``names`` on the rest ``model``: corner vertices ``(L,3)`` and
    barycentric weights ``(L,3)``. A stored landmark is a mesh vertex, i.e. its anatomical point rounded to
    the mesh (up to half an edge, 1–1.5 mm on the shipped template, enough to shift a relocated joint by
    as much); the point where the landmark's defining ray leaves the skin removes that rounding. Landmarks
    whose ray misses or lands more than :data:`LANDMARK_REFINE_MM` from the stored vertex (a template whose
    landmarks were placed otherwise) keep the vertex."""
    corners = np.zeros((len(names), 3), dtype=np.int64)
    weights = np.zeros((len(names), 3))
    for row, name in enumerate(names):
        vertex = model.landmarks[name]
        corners[row], weights[row] = vertex, (1.0, 0.0, 0.0)
        try:
            origin, direction = anatomical_ray(model, name)
        except ValueError:          # not one of LANDMARK_NAMES
            continue
        hit = ray_surface_point(model.vertices, model.faces, origin, direction)
        if hit is None:
            continue
        face, barycentric = hit
        point = barycentric @ model.vertices[model.faces[face]]
        if np.linalg.norm(point - model.vertices[vertex]) <= LANDMARK_REFINE_MM:
            corners[row], weights[row] = model.faces[face], barycentric
    return corners, weights


def initial_similarity(model: HandModel, landmark_vertices: np.ndarray, targets: np.ndarray
                       ) -> tuple[float, np.ndarray, np.ndarray]:
    """Umeyama similarity ``(s, R, t)`` of the rest template's landmarks onto the scan landmarks."""
    return similarity_transform(model.vertices[landmark_vertices], targets)


def mirror_check(model: HandModel, landmark_vertices: np.ndarray, targets: np.ndarray) -> tuple[float, float]:
    """RMS landmark residual (mm) of the best similarity with the template and with its mirror image."""
    residuals = []
    for source in (model.vertices[landmark_vertices], model.vertices[landmark_vertices] * [-1.0, 1.0, 1.0]):
        scale, rotation, translation = similarity_transform(source, targets)
        moved = scale * source @ rotation.T + translation
        residuals.append(float(np.sqrt(np.mean(np.sum((moved - targets) ** 2, axis=1)))))
    return residuals[0], residuals[1]


def _vertex_markers(model: HandModel, vertices: np.ndarray) -> MarkerSet:
    """A marker set with one effector on each given vertex (no offset)."""
    joints = np.ascontiguousarray(model.skin_joints[vertices])
    weights = np.ascontiguousarray(model.skin_weights[vertices], dtype=np.float64)
    rest = model.vertices[vertices]
    return MarkerSet([str(v) for v in vertices], vertices, rest, joints, weights,
                     model.chain.local_coordinates(rest, joints), np.zeros(len(vertices)))


def posture_ik(model: HandModel, theta: np.ndarray, effector_vertices: np.ndarray, targets: np.ndarray,
               iterations: int = 15) -> np.ndarray:
    """Joint angles ``(26,)`` (pose and posture) moving ``effector_vertices`` towards ``targets (K,3)``."""
    markers = _vertex_markers(model, effector_vertices)
    lower, upper = default_joint_limits()
    chain = model.chain
    solution, _, _ = solve_frame_kernel(
        np.ascontiguousarray(theta, dtype=np.float64), np.ascontiguousarray(targets, dtype=np.float64),
        np.ones(len(targets), dtype=np.bool_), chain.relative_rest, chain.offsets, chain.abduction_sign, ANCESTOR,
        markers.influence_joints, markers.influence_weights, markers.local_points, np.eye(20), np.zeros(20),
        lower[6:], upper[6:], IK_DAMPING, np.zeros((20, 20)), np.zeros(20), np.zeros(20), lower[6:], upper[6:],
        iterations, 1e-7, True)
    return solution


def align_template(template: HandModel, landmark_vertices: np.ndarray, landmark_targets: np.ndarray,
                   scan_points: np.ndarray, scan_normals: np.ndarray | None = None, normals_oriented: bool = True,
                   rounds: int = 6, tree: cKDTree | None = None,
                   progress: Callable[[float], None] | None = None, cancelled: Callable[[], bool] | None = None,
                   on_iteration: Callable[[np.ndarray], None] | None = None) -> Alignment:
    """Align the template (rest pose) to a scan: Umeyama on the landmarks, then ``rounds`` of
    (similarity ICP step, posture IK step) on landmarks + closest points. All positions in mm."""
    tree = tree if tree is not None else cKDTree(scan_points)
    scale, rotation, translation = initial_similarity(template, landmark_vertices, landmark_targets)
    theta = np.zeros(N_PARAMS)
    theta[0:3], theta[3:6] = translation, vector_from_rotation(rotation)
    step = max(1, len(template.vertices) // SAMPLE_VERTICES)
    candidates = np.arange(0, len(template.vertices), step)
    history: list[float] = []
    model = scaled_model(template, scale)
    vertices = skin_vertices(model, theta)
    for round_index in range(rounds):
        if cancelled is not None and cancelled():
            raise CancelledError("the alignment was cancelled; the scan and landmarks are unchanged")
        normals = mesh_vertex_normals(vertices, template.faces)
        pair_vertices, pair_points = closest_point_pairs(vertices, normals, tree, scan_points, scan_normals,
                                                         normals_oriented, candidates)
        # (a) similarity ICP step on landmarks (weighted) and closest points
        source = np.vstack([vertices[landmark_vertices], vertices[pair_vertices]])
        target = np.vstack([landmark_targets, scan_points[pair_points]])
        weights = np.concatenate([np.full(len(landmark_vertices), float(LANDMARK_WEIGHT)),
                                  np.ones(len(pair_vertices))])
        s_step, r_step, t_step = similarity_transform(source, target, weights)
        scale *= s_step
        rotation = r_step @ rotation_from_vector(theta[3:6])
        theta[0:3] = s_step * r_step @ theta[0:3] + t_step
        theta[3:6] = vector_from_rotation(rotation)
        model = scaled_model(template, scale)
        vertices = skin_vertices(model, theta)
        # (b) posture IK on the same correspondences (re-paired after the rigid step)
        normals = mesh_vertex_normals(vertices, template.faces)
        pair_vertices, pair_points = closest_point_pairs(vertices, normals, tree, scan_points, scan_normals,
                                                         normals_oriented, candidates)
        effectors = np.concatenate([np.repeat(landmark_vertices, LANDMARK_WEIGHT), pair_vertices])
        targets = np.vstack([np.repeat(landmark_targets, LANDMARK_WEIGHT, axis=0), scan_points[pair_points]])
        theta = posture_ik(model, theta, effectors, targets)
        vertices = skin_vertices(model, theta)
        history.append(float(np.sqrt(np.mean(np.sum((vertices[landmark_vertices] - landmark_targets) ** 2,
                                                     axis=1)))))
        if on_iteration is not None:
            on_iteration(vertices.copy())
        if progress is not None:
            progress((round_index + 1) / rounds)
    return Alignment(scale, theta, vertices, history)
