"""Forward kinematics, linear blend skinning and analytic Jacobians of the 26-parameter hand.

The hot kernels are compiled with numba (one frame costs a few microseconds), so the IK can run
thousands of frames per second on one core. Kernels take plain arrays; :class:`KinematicChain`
bundles the arrays of one skeleton.

Jacobian convention: columns 0..2 are d/d(wrist translation); columns 3..5 are the derivative with
respect to a small world-frame rotation ``δ`` composed on the left of the wrist rotation,
``R ← exp([δ]×) R`` (the exponential-map update of DESIGN.md), not with respect to the rotation
vector itself; columns 6..25 are d/d(finger angle).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from handmocap.core.model.skeleton import JOINT_PARENTS, N_JOINTS, N_PARAMS, PARAM_JOINT, Skeleton


@njit(cache=True)
def rotation_from_vector(rotation_vector: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation vector (3,) (axis × angle, rad) -> rotation matrix (3, 3)."""
    angle = np.sqrt(rotation_vector[0] ** 2 + rotation_vector[1] ** 2 + rotation_vector[2] ** 2)
    result = np.eye(3)
    if angle < 1e-12:
        result[0, 1] = -rotation_vector[2]
        result[0, 2] = rotation_vector[1]
        result[1, 0] = rotation_vector[2]
        result[1, 2] = -rotation_vector[0]
        result[2, 0] = -rotation_vector[1]
        result[2, 1] = rotation_vector[0]
        return result
    x, y, z = rotation_vector[0] / angle, rotation_vector[1] / angle, rotation_vector[2] / angle
    c, s = np.cos(angle), np.sin(angle)
    t = 1.0 - c
    result[0, 0] = c + x * x * t
    result[0, 1] = x * y * t - z * s
    result[0, 2] = x * z * t + y * s
    result[1, 0] = y * x * t + z * s
    result[1, 1] = c + y * y * t
    result[1, 2] = y * z * t - x * s
    result[2, 0] = z * x * t - y * s
    result[2, 1] = z * y * t + x * s
    result[2, 2] = c + z * z * t
    return result


@njit(cache=True)
def vector_from_rotation(rotation: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rotation_from_vector`: rotation matrix (3, 3) -> rotation vector (3,)."""
    cos_angle = min(1.0, max(-1.0, (rotation[0, 0] + rotation[1, 1] + rotation[2, 2] - 1.0) * 0.5))
    angle = np.arccos(cos_angle)
    axis = np.array([rotation[2, 1] - rotation[1, 2], rotation[0, 2] - rotation[2, 0],
                     rotation[1, 0] - rotation[0, 1]])
    if angle < 1e-6:
        return 0.5 * axis
    if np.pi - angle < 1e-4:
        # near 180°: axis from the largest diagonal entry of (R + I) / 2
        symmetric = (rotation + np.eye(3)) * 0.5
        k = np.argmax(np.diag(symmetric))
        column = symmetric[:, k] / np.sqrt(max(symmetric[k, k], 1e-12))
        return column * angle
    return axis * (angle / (2.0 * np.sin(angle)))


@njit(cache=True, inline="always")
def _matmul3_into(a, b, out):
    """out = a @ b for 3×3 arrays, without a BLAS call or an allocation (hot path)."""
    for r in range(3):
        for c in range(3):
            out[r, c] = a[r, 0] * b[0, c] + a[r, 1] * b[1, c] + a[r, 2] * b[2, c]


@njit(cache=True)
def matmul3(a, b):
    """a @ b for 3×3 arrays."""
    out = np.empty((3, 3))
    _matmul3_into(a, b, out)
    return out


@njit(cache=True, inline="always")
def _rotate_z_into(a, angle, out):
    """out = a @ Rz(angle)."""
    c, s = np.cos(angle), np.sin(angle)
    for r in range(3):
        out[r, 0] = c * a[r, 0] + s * a[r, 1]
        out[r, 1] = -s * a[r, 0] + c * a[r, 1]
        out[r, 2] = a[r, 2]


@njit(cache=True, inline="always")
def _rotate_x_into(a, angle, out):
    """out = a @ Rx(angle)."""
    c, s = np.cos(angle), np.sin(angle)
    for r in range(3):
        out[r, 0] = a[r, 0]
        out[r, 1] = c * a[r, 1] + s * a[r, 2]
        out[r, 2] = -s * a[r, 1] + c * a[r, 2]


@njit(cache=True)
def forward_kinematics_kernel(theta, relative_rest, offsets, abduction_sign):
    """Joint world rotations (16,3,3), positions (16,3), DoF axes (26,3) and centres (26,3)."""
    rotations = np.empty((N_JOINTS, 3, 3))
    positions = np.empty((N_JOINTS, 3))
    axes = np.zeros((N_PARAMS, 3))
    centres = np.zeros((N_PARAMS, 3))
    pre = np.empty((3, 3))
    abducted = np.empty((3, 3))
    rotations[0] = rotation_from_vector(theta[3:6])
    positions[0] = theta[0:3]
    for k in range(3):
        axes[k, k] = 1.0
        axes[3 + k, k] = 1.0
        centres[3 + k] = positions[0]
    for joint in range(1, N_JOINTS):
        digit = (joint - 1) // 3
        segment = (joint - 1) % 3
        parent = 0 if segment == 0 else joint - 1
        parent_rotation = rotations[parent]
        _matmul3_into(parent_rotation, relative_rest[joint], pre)
        for r in range(3):
            positions[joint, r] = positions[parent, r] + (parent_rotation[r, 0] * offsets[joint, 0]
                                                          + parent_rotation[r, 1] * offsets[joint, 1]
                                                          + parent_rotation[r, 2] * offsets[joint, 2])
        base = 6 + 4 * digit
        if segment == 0:
            _rotate_z_into(pre, abduction_sign * theta[base], abducted)
            for r in range(3):
                axes[base, r] = abduction_sign * pre[r, 2]
                axes[base + 1, r] = abducted[r, 0]
                centres[base, r] = positions[joint, r]
                centres[base + 1, r] = positions[joint, r]
            _rotate_x_into(abducted, theta[base + 1], rotations[joint])
        else:
            for r in range(3):
                axes[base + 1 + segment, r] = pre[r, 0]
                centres[base + 1 + segment, r] = positions[joint, r]
            _rotate_x_into(pre, theta[base + 1 + segment], rotations[joint])
    return rotations, positions, axes, centres


@njit(cache=True, inline="always")
def _moved_point(rotation, position, local):
    """``rotation @ local + position`` as three scalars (no allocation)."""
    return (rotation[0, 0] * local[0] + rotation[0, 1] * local[1] + rotation[0, 2] * local[2] + position[0],
            rotation[1, 0] * local[0] + rotation[1, 1] * local[1] + rotation[1, 2] * local[2] + position[1],
            rotation[2, 0] * local[0] + rotation[2, 1] * local[1] + rotation[2, 2] * local[2] + position[2])


@njit(cache=True)
def skinned_points_kernel(rotations, positions, influence_joints, influence_weights, local_points):
    """Positions (P,3) of skinned points from their per-influence local coordinates (P,4,3)."""
    count = influence_joints.shape[0]
    result = np.zeros((count, 3))
    for i in range(count):
        for k in range(influence_joints.shape[1]):
            weight = influence_weights[i, k]
            if weight != 0.0:
                joint = influence_joints[i, k]
                px, py, pz = _moved_point(rotations[joint], positions[joint], local_points[i, k])
                result[i, 0] += weight * px
                result[i, 1] += weight * py
                result[i, 2] += weight * pz
    return result


@njit(cache=True)
def points_and_jacobian_kernel(theta, relative_rest, offsets, abduction_sign, ancestor,
                               influence_joints, influence_weights, local_points):
    """Skinned point positions (P,3) and their Jacobian (P,3,26) at ``theta``.

    ``ancestor (26,16)``: True where parameter d moves joint j (its joint is j or an ancestor of j).
    """
    rotations, positions, axes, centres = forward_kinematics_kernel(theta, relative_rest, offsets,
                                                                    abduction_sign)
    count = influence_joints.shape[0]
    points = np.zeros((count, 3))
    jacobian = np.zeros((count, 3, N_PARAMS))
    for i in range(count):
        for k in range(influence_joints.shape[1]):
            weight = influence_weights[i, k]
            if weight == 0.0:
                continue
            joint = influence_joints[i, k]
            px, py, pz = _moved_point(rotations[joint], positions[joint], local_points[i, k])
            points[i, 0] += weight * px
            points[i, 1] += weight * py
            points[i, 2] += weight * pz
            for d in range(3, N_PARAMS):
                if ancestor[d, joint]:
                    ax, ay, az = axes[d, 0], axes[d, 1], axes[d, 2]
                    rx, ry, rz = px - centres[d, 0], py - centres[d, 1], pz - centres[d, 2]
                    jacobian[i, 0, d] += weight * (ay * rz - az * ry)
                    jacobian[i, 1, d] += weight * (az * rx - ax * rz)
                    jacobian[i, 2, d] += weight * (ax * ry - ay * rx)
        for c in range(3):
            jacobian[i, c, c] = 1.0
    return points, jacobian


def _ancestor_matrix() -> np.ndarray:
    """(26, 16) bool: parameter d moves joint j."""
    ancestor = np.zeros((N_PARAMS, N_JOINTS), dtype=np.bool_)
    ancestor[:6, :] = True
    for d in range(6, N_PARAMS):
        for joint in range(N_JOINTS):
            walk = joint
            while walk >= 0:
                if walk == PARAM_JOINT[d]:
                    ancestor[d, joint] = True
                    break
                walk = JOINT_PARENTS[walk]
    return ancestor


ANCESTOR = _ancestor_matrix()


@dataclass(frozen=True)
class KinematicChain:
    """The arrays of one skeleton the kernels need; build with :meth:`from_skeleton`."""

    skeleton: Skeleton
    relative_rest: np.ndarray   # (16, 3, 3)
    offsets: np.ndarray         # (16, 3)
    abduction_sign: float

    @classmethod
    def from_skeleton(cls, skeleton: Skeleton) -> KinematicChain:
        return cls(skeleton, np.ascontiguousarray(skeleton.relative_rest_rotations()),
                   np.ascontiguousarray(skeleton.local_offsets()), skeleton.abduction_sign)

    def joint_transforms(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World joint rotations (16,3,3) and positions (16,3) for ``theta (26,)``."""
        rotations, positions, _, _ = forward_kinematics_kernel(
            np.ascontiguousarray(theta, dtype=np.float64), self.relative_rest, self.offsets,
            self.abduction_sign)
        return rotations, positions

    def skinning_matrices(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """LBS transforms from rest to posed: rotations (16,3,3) and translations (16,3), so that a
        rest point ``p`` moved rigidly with joint j goes to ``A[j] @ p + b[j]``."""
        rotations, positions = self.joint_transforms(theta)
        rest_rotations = self.skeleton.rest_rotations
        linear = rotations @ np.transpose(rest_rotations, (0, 2, 1))
        translation = positions - np.einsum("jab,jb->ja", linear, self.skeleton.rest_positions)
        return linear, translation

    def local_coordinates(self, rest_points: np.ndarray, influence_joints: np.ndarray) -> np.ndarray:
        """Rest points (P,3) in the rest frames of their influence joints (P,4): returns (P,4,3)."""
        rest_rotations = self.skeleton.rest_rotations[influence_joints]          # (P,4,3,3)
        delta = rest_points[:, None, :] - self.skeleton.rest_positions[influence_joints]
        return np.ascontiguousarray(np.einsum("pkba,pkb->pka", rest_rotations, delta))
