"""Forward kinematics, analytic Jacobians against finite differences, mirroring, limits."""

import numpy as np
import pytest

from handmocap.core.model.kinematics import (
    ANCESTOR,
    KinematicChain,
    points_and_jacobian_kernel,
    rotation_from_vector,
    vector_from_rotation,
)
from handmocap.core.model.markers import MarkerSet
from handmocap.core.model.skeleton import (
    JOINT_NAMES,
    N_PARAMS,
    PARAM_NAMES,
    HandProportions,
    build_skeleton,
    default_joint_limits,
)


def skinned_points(chain: KinematicChain, rng: np.random.Generator, count: int = 40) -> MarkerSet:
    """Random points near the bones, blended over up to two joints (parent and child)."""
    skeleton = chain.skeleton
    joints = rng.integers(1, 16, size=count)
    along = rng.uniform(0.0, 1.0, size=count)
    child = np.array([skeleton.rest_positions[j + 1] if (j - 1) % 3 < 2 else
                      skeleton.tip_positions[(j - 1) // 3] for j in joints])
    rest = (1 - along[:, None]) * skeleton.rest_positions[joints] + along[:, None] * child
    rest += rng.normal(scale=6.0, size=rest.shape)
    influence = np.zeros((count, 4), dtype=np.int64)
    weights = np.zeros((count, 4))
    influence[:, 0] = joints
    influence[:, 1] = np.where((joints - 1) % 3 == 0, 0, joints - 1)
    blend = np.clip(1.0 - along / 0.3, 0.0, 0.5)
    weights[:, 0], weights[:, 1] = 1.0 - blend, blend
    return MarkerSet([f"p{i}" for i in range(count)], np.zeros(count, dtype=np.int64), rest, influence,
                     weights, chain.local_coordinates(rest, influence), np.zeros(count))


def evaluate(chain, markers, theta):
    return points_and_jacobian_kernel(theta, chain.relative_rest, chain.offsets, chain.abduction_sign,
                                      ANCESTOR, markers.influence_joints, markers.influence_weights,
                                      markers.local_points)


def random_theta(rng):
    lower, upper = default_joint_limits()
    theta = np.zeros(N_PARAMS)
    theta[:3] = rng.normal(scale=100.0, size=3)
    theta[3:6] = rng.normal(scale=0.8, size=3)
    theta[6:] = rng.uniform(lower[6:], upper[6:])
    return theta


def test_names_and_layout():
    assert len(JOINT_NAMES) == 16 and len(PARAM_NAMES) == 26
    assert JOINT_NAMES[1:4] == ("thumb_cmc", "thumb_mcp", "thumb_ip")
    lower, upper = default_joint_limits()
    assert np.all(lower[6:] < upper[6:]) and np.all(np.isinf(lower[:6]))


def test_rest_pose_reproduces_rest_geometry():
    chain = KinematicChain.from_skeleton(build_skeleton())
    rotations, positions = chain.joint_transforms(np.zeros(N_PARAMS))
    np.testing.assert_allclose(positions, chain.skeleton.rest_positions, atol=1e-9)
    np.testing.assert_allclose(rotations, chain.skeleton.rest_rotations, atol=1e-9)


def test_rotation_vector_round_trip():
    rng = np.random.default_rng(3)
    for _ in range(50):
        vector = rng.normal(size=3)
        vector *= rng.uniform(0, 3.1) / np.linalg.norm(vector)
        np.testing.assert_allclose(vector_from_rotation(rotation_from_vector(vector)), vector, atol=1e-7)


@pytest.mark.parametrize("side", ["right", "left"])
def test_jacobian_matches_finite_differences(side):
    rng = np.random.default_rng(0)
    skeleton = build_skeleton(HandProportions().scaled(finger_scale=1.1, palm_width_scale=0.95))
    chain = KinematicChain.from_skeleton(skeleton if side == "right" else skeleton.mirrored())
    markers = skinned_points(chain, rng)
    for _ in range(5):
        theta = random_theta(rng)
        points, jacobian = evaluate(chain, markers, theta)
        step = 1e-6
        for d in range(N_PARAMS):
            moved = theta.copy()
            if 3 <= d < 6:
                increment = np.zeros(3)
                increment[d - 3] = step
                rotation = rotation_from_vector(increment) @ rotation_from_vector(theta[3:6])
                moved[3:6] = vector_from_rotation(rotation)
            else:
                moved[d] += step
            numeric = (evaluate(chain, markers, moved)[0] - points) / step
            np.testing.assert_allclose(jacobian[:, :, d], numeric, atol=2e-3, err_msg=PARAM_NAMES[d])


def test_left_hand_mirrors_right_hand():
    rng = np.random.default_rng(1)
    right = KinematicChain.from_skeleton(build_skeleton())
    left = KinematicChain.from_skeleton(right.skeleton.mirrored())
    markers = skinned_points(right, rng)
    mirrored_rest = markers.rest_positions * np.array([-1.0, 1.0, 1.0])
    left_markers = MarkerSet(markers.names, markers.vertex, mirrored_rest, markers.influence_joints,
                             markers.influence_weights,
                             left.local_coordinates(mirrored_rest, markers.influence_joints), markers.offsets_mm)
    theta = random_theta(rng)
    theta[:6] = 0.0
    right_points = evaluate(right, markers, theta)[0]
    left_points = evaluate(left, left_markers, theta)[0]
    np.testing.assert_allclose(left_points, right_points * np.array([-1.0, 1.0, 1.0]), atol=1e-9)


def test_flexion_curls_towards_the_palm_and_abduction_is_ulnar():
    chain = KinematicChain.from_skeleton(build_skeleton())
    index_flexion = PARAM_NAMES.index("index_mcp_flexion")
    index_abduction = PARAM_NAMES.index("index_mcp_abduction")
    theta = np.zeros(N_PARAMS)
    theta[index_flexion] = 0.5
    _, positions = chain.joint_transforms(theta)
    pip = JOINT_NAMES.index("index_pip")
    assert positions[pip, 2] < chain.skeleton.rest_positions[pip, 2] - 5.0   # palm faces -Z
    theta[:] = 0.0
    theta[index_abduction] = 0.3
    _, positions = chain.joint_transforms(theta)
    assert positions[pip, 0] > chain.skeleton.rest_positions[pip, 0] + 5.0   # ulnar is +X
