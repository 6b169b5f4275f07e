"""The thesis Ch. 6 terms of the articulated registration beyond depth and silhouette, each as residuals and
their Jacobian rows for the Gauss-Newton step of :class:`core.fusion.icp.ArticulatedICP`:

- ``E_wrist`` (eq. 6.4): the wrist joint's projection on the forearm's image axis (the thesis finds the axis
  from a wristband; here from the forearm the segmentation sees leaving the hand), in mm at the wrist's depth;
- ``E_collision`` (eq. 6.7): ``(d(c_i, c_j) − r)²`` for every colliding pair of finger segments of neighbouring
  digits (segments as capsules: the bone axis and a radius measured on the model's mesh);
- ``E_temporal`` (eq. 6.9): velocity and acceleration of points on the kinematic chain (the joints and the
  tips) against the two previous frames, ``‖k − k(t−1)‖²`` and ``‖k − 2k(t−1) + k(t−2)‖²``.

Positions are in the mocap frame (mm); Jacobians (·, 26) follow :mod:`core.model.kinematics` (the rotation
columns rotate about world axes through the wrist, as :func:`core.fusion.pose.left_compose` applies them).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from handmocap.core.camera.model import Camera
from handmocap.core.model import HandModel
from handmocap.core.model.kinematics import ANCESTOR, points_and_jacobian_kernel
from handmocap.core.model.skeleton import N_JOINTS, N_PARAMS

#: collision radius = this share of the sum of the two segments' mesh radii: neighbouring fingers may touch
#: (their flesh yields) but not pass through each other
COLLISION_SHARE = 0.8
#: digit pairs whose segments are tested for collisions (thumb–index and the neighbouring fingers)
NEIGHBOUR_DIGITS = ((0, 1), (1, 2), (2, 3), (3, 4))


class BonePoints:
    """Points carried rigidly by one joint each: ``joints (P,)`` and their rest-frame coordinates ``local (P,3)``."""

    def __init__(self, model: HandModel, joints: np.ndarray, local: np.ndarray) -> None:
        self.chain = model.chain
        count = len(joints)
        self.joints = np.zeros((count, 4), dtype=np.int64)
        self.joints[:, 0] = joints
        self.weights = np.zeros((count, 4))
        self.weights[:, 0] = 1.0
        self.local = np.zeros((count, 4, 3))
        self.local[:, 0] = local

    def evaluate(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (P,3) mm and Jacobian (P,3,26)."""
        chain = self.chain
        return points_and_jacobian_kernel(np.ascontiguousarray(theta, float), chain.relative_rest, chain.offsets,
                                          chain.abduction_sign, ANCESTOR, self.joints, self.weights, self.local)


def chain_points(model: HandModel) -> BonePoints:
    """The 16 joints and the 5 digit tips (21 points) as :class:`BonePoints`."""
    skeleton = model.skeleton
    joints = list(range(N_JOINTS)) + [3 + 3 * digit for digit in range(5)]
    local = np.zeros((len(joints), 3))
    for digit in range(5):
        distal = 3 + 3 * digit
        local[N_JOINTS + digit] = skeleton.rest_rotations[distal].T @ (skeleton.tip_positions[digit]
                                                                       - skeleton.rest_positions[distal])
    return BonePoints(model, np.array(joints), local)


@lru_cache(maxsize=4)
def segment_capsules(model: HandModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 15 digit segments as capsules: ``(joint (15,), end (15,3) in the joint's rest frame, radius (15,) mm)``;
    the radius is the median distance to the bone axis of the mesh vertices the segment alone moves."""
    skeleton = model.skeleton
    joints = np.arange(1, N_JOINTS)
    ends = np.zeros((15, 3))
    radii = np.zeros(15)
    vertices = np.asarray(model.vertices, float)
    single = np.asarray(model.skin_weights)[:, 0] > 0.999
    owner = np.asarray(model.skin_joints)[:, 0]
    for index, joint in enumerate(joints):
        start = skeleton.rest_positions[joint]
        digit, segment = (joint - 1) // 3, (joint - 1) % 3
        end = skeleton.rest_positions[joint + 1] if segment < 2 else skeleton.tip_positions[digit]
        ends[index] = skeleton.rest_rotations[joint].T @ (end - start)
        mine = vertices[single & (owner == joint)]
        axis = (end - start) / np.linalg.norm(end - start)
        if len(mine):
            offset = mine - start
            along = np.clip(offset @ axis, 0.0, np.linalg.norm(end - start))
            radii[index] = float(np.median(np.linalg.norm(offset - along[:, None] * axis, axis=1)))
        else:
            radii[index] = 8.0
    return joints, ends, radii


def _closest_on_segments(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``(s (K,), t (K,))`` in [0, 1] of the closest points of segments a0–a1 and b0–b1 (K,3) each."""
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a = np.einsum("ka,ka->k", d1, d1)
    e = np.einsum("ka,ka->k", d2, d2)
    f = np.einsum("ka,ka->k", d2, r)
    c = np.einsum("ka,ka->k", d1, r)
    b = np.einsum("ka,ka->k", d1, d2)
    denominator = a * e - b * b
    s = np.where(denominator > 1e-9, np.clip((b * f - c * e) / np.maximum(denominator, 1e-9), 0.0, 1.0), 0.0)
    t = (b * s + f) / np.maximum(e, 1e-9)
    below, above = t < 0.0, t > 1.0
    t = np.clip(t, 0.0, 1.0)
    s = np.where(below, np.clip(-c / np.maximum(a, 1e-9), 0.0, 1.0), s)
    s = np.where(above, np.clip((b - c) / np.maximum(a, 1e-9), 0.0, 1.0), s)
    return s, t


class CollisionTerm:
    """``E_collision`` (thesis eq. 6.7) between the segments of neighbouring digits."""

    def __init__(self, model: HandModel, share: float = COLLISION_SHARE) -> None:
        self.model = model
        joints, ends, radii = segment_capsules(model)
        pairs = [(i, j) for i in range(15) for j in range(15)
                 if ((joints[i] - 1) // 3, (joints[j] - 1) // 3) in NEIGHBOUR_DIGITS]
        self.first = np.array([p[0] for p in pairs])
        self.second = np.array([p[1] for p in pairs])
        self.joints, self.ends = joints, ends
        self.reach = share * (radii[self.first] + radii[self.second])

    def rows(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals ``d − r`` (K,) mm (negative: penetration) of the colliding pairs and their rows (K,26)."""
        rotations, positions = self.model.chain.joint_transforms(theta)
        starts = positions[self.joints]
        ends = starts + np.einsum("kab,kb->ka", rotations[self.joints], self.ends)
        s, t = _closest_on_segments(starts[self.first], ends[self.first], starts[self.second], ends[self.second])
        on_first = starts[self.first] + s[:, None] * (ends[self.first] - starts[self.first])
        on_second = starts[self.second] + t[:, None] * (ends[self.second] - starts[self.second])
        gap = on_first - on_second
        distance = np.linalg.norm(gap, axis=1)
        colliding = distance < self.reach
        if not colliding.any():
            return np.zeros(0), np.zeros((0, N_PARAMS))
        first, second = self.first[colliding], self.second[colliding]
        local = np.vstack([s[colliding, None] * self.ends[first], t[colliding, None] * self.ends[second]])
        points = BonePoints(self.model, np.concatenate([self.joints[first], self.joints[second]]), local)
        _, jacobian = points.evaluate(theta)
        count = int(colliding.sum())
        normal = gap[colliding] / np.maximum(distance[colliding], 1e-9)[:, None]
        # axes that cross: no gap to read a direction from; part them across both axes
        crossing = distance[colliding] < 1e-6
        if crossing.any():
            across = np.cross(ends[self.first[colliding]] - starts[self.first[colliding]],
                              ends[self.second[colliding]] - starts[self.second[colliding]])[crossing]
            normal[crossing] = across / np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-9)
        rows = np.einsum("ka,kab->kb", normal, jacobian[:count] - jacobian[count:])
        return distance[colliding] - self.reach[colliding], rows

    def energy(self, theta: np.ndarray) -> float:
        residual, _ = self.rows(theta)
        return float(residual @ residual)


def wrist_rows(model: HandModel, camera: Camera, theta: np.ndarray, line_point: np.ndarray,
               line_direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``E_wrist`` (thesis eq. 6.4): the wrist joint's image distance (1,) to the line through ``line_point (2,)``
    px along ``line_direction (2,)``, in mm at the wrist's depth, and its row (1,26)."""
    wrist = theta[0:3]
    point = camera.to_camera(wrist)[0]
    (fx, fy), (cx, cy) = camera.focal, camera.principal_point
    z = max(float(point[2]), 1.0)
    pixel = np.array([fx * point[0] / z + cx, fy * point[1] / z + cy])
    direction = line_direction / max(float(np.linalg.norm(line_direction)), 1e-9)
    normal = np.array([-direction[1], direction[0]])
    scale = z / fx
    offset = float(normal @ (pixel - line_point))
    residual = np.array([offset * scale])
    perspective = np.array([[fx / z, 0.0, -fx * point[0] / z ** 2], [0.0, fy / z, -fy * point[1] / z ** 2]])
    derivative = normal @ perspective * scale + np.array([0.0, 0.0, offset / fx])   # the px → mm scale moves too
    row = np.zeros((1, N_PARAMS))
    row[0, 0:3] = derivative @ camera.rotation                   # the wrist moves with the translation only
    return residual, row


def temporal_rows(points: BonePoints, theta: np.ndarray, previous: np.ndarray, before: np.ndarray | None,
                  velocity_weight: float, acceleration_weight: float) -> tuple[np.ndarray, np.ndarray]:
    """``E_temporal`` (thesis eq. 6.9) on the chain points: weighted residuals (3P or 6P,) mm and rows (·,26),
    each weight divided by the number of points (so the term is a mean, like the data terms)."""
    positions, jacobian = points.evaluate(theta)
    count = len(positions)
    residuals = [np.sqrt(velocity_weight / count) * (positions - previous).reshape(-1)]
    rows = [np.sqrt(velocity_weight / count) * jacobian.reshape(-1, N_PARAMS)]
    if before is not None and acceleration_weight > 0:
        residuals.append(np.sqrt(acceleration_weight / count) * (positions - 2 * previous + before).reshape(-1))
        rows.append(np.sqrt(acceleration_weight / count) * jacobian.reshape(-1, N_PARAMS))
    return np.concatenate(residuals), np.vstack(rows)
