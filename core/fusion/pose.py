"""Small pose helpers of the fusion: the composed wrist-rotation update and the joint positions (with the tips)
the evaluation compares."""

from __future__ import annotations

import numpy as np

from handmocap.core.model import HandModel
from handmocap.core.model.kinematics import rotation_from_vector, vector_from_rotation


def left_compose(theta: np.ndarray, step: np.ndarray) -> np.ndarray:
    """``theta + step`` (26,) with the wrist rotation updated as ``exp(step[3:6]) · R(theta[3:6])`` — the update
    the kinematic Jacobians' rotation columns describe (world axes through the wrist)."""
    result = theta + step
    result[3:6] = vector_from_rotation(rotation_from_vector(step[3:6]) @ rotation_from_vector(theta[3:6]))
    return result


def digit_points(model: HandModel, theta: np.ndarray) -> np.ndarray:
    """Positions (5,3,3) mm of each digit's middle joint, distal joint and tip at ``theta (26,)``."""
    skeleton = model.skeleton
    rotations, positions = model.chain.joint_transforms(theta)
    points = np.empty((5, 3, 3))
    for digit in range(5):
        distal = 3 + 3 * digit
        points[digit, 0] = positions[distal - 1]
        points[digit, 1] = positions[distal]
        rest_offset = skeleton.tip_positions[digit] - skeleton.rest_positions[distal]
        local_tip = skeleton.rest_rotations[distal].T @ rest_offset
        points[digit, 2] = rotations[distal] @ local_tip + positions[distal]
    return points
