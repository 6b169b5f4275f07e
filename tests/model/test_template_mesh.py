"""The generated template hand: closed oriented mesh, skin weights, landmarks, stored file, posing."""

import hashlib

import numpy as np
import pytest
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from handmocap.core.model import TEMPLATE_PATH, load_template
from handmocap.core.model.hand_model import HandModel, mesh_vertex_normals, skin_vertices
from handmocap.core.model.skeleton import JOINT_PARENTS, PARAM_NAMES, HandProportions
from handmocap.core.model.template_mesh import (
    DEFAULT_TEMPLATE_PATH,
    LANDMARK_DESCRIPTIONS,
    LANDMARK_NAMES,
    build_template,
    edge_face_counts,
    signed_volume,
)

RESHAPED = {
    "mixed": HandProportions().scaled(finger_scale=[1.1, 0.9, 1.15, 1.0, 0.95], palm_width_scale=1.08),
    "small": HandProportions().scaled(finger_scale=0.85, palm_width_scale=0.9),
    "large": HandProportions().scaled(finger_scale=1.15, palm_width_scale=1.1),
}


@pytest.fixture(scope="module")
def model() -> HandModel:
    return build_template()


@pytest.fixture(scope="module", params=sorted(RESHAPED))
def reshaped(request) -> HandModel:
    return build_template(RESHAPED[request.param])


def checksum(model: HandModel) -> str:
    """Digest of the topology and of the geometry rounded to 0.1 µm."""
    digest = hashlib.sha256(model.faces.astype(np.int64).tobytes())
    digest.update(np.round(model.vertices, 4).tobytes())
    digest.update(model.skin_joints.astype(np.int64).tobytes())
    digest.update(np.round(model.skin_weights, 6).tobytes())
    return digest.hexdigest()


def assert_closed_manifold(model: HandModel) -> None:
    vertices, faces = model.vertices, model.faces
    counts = edge_face_counts(faces)
    assert np.all(counts == 2)
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    assert len(np.unique(directed, axis=0)) == len(directed)        # consistently oriented
    assert len(vertices) - len(counts) + len(faces) == 2             # Euler characteristic of a sphere
    graph = sparse.coo_matrix((np.ones(len(directed)), (directed[:, 0], directed[:, 1])),
                              shape=(len(vertices), len(vertices)))
    assert connected_components(graph, directed=False)[0] == 1
    assert signed_volume(vertices, faces) > 0                        # outward normals


def assert_valid_weights(model: HandModel) -> None:
    weights = model.skin_weights
    assert weights.shape == (len(model.vertices), 4) and model.skin_joints.shape == weights.shape
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(weights >= 0) and np.all((weights > 0).sum(axis=1) <= 4)
    assert np.mean(weights[:, 0] == 1.0) > 0.5


def segment_ends(model: HandModel, joint: int) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (3,) of the segment owned by a digit joint."""
    skeleton = model.skeleton
    start = skeleton.rest_positions[joint]
    end = skeleton.rest_positions[joint + 1] if (joint - 1) % 3 < 2 else skeleton.tip_positions[(joint - 1) // 3]
    return start, end


def test_closed_oriented_manifold(model: HandModel) -> None:
    assert 10_000 <= len(model.vertices) <= 14_000
    assert_closed_manifold(model)
    normals = mesh_vertex_normals(model.vertices, model.faces)
    outward = (model.vertices - model.vertices.mean(axis=0))
    assert np.mean(np.einsum("ij,ij->i", normals, outward) > 0) > 0.8


def test_skin_weights(model: HandModel) -> None:
    assert_valid_weights(model)
    # only parent/child pairs blend: every second influence is the parent or a child of the first
    blended = model.skin_weights[:, 1] > 0
    first, second = model.skin_joints[blended, 0], model.skin_joints[blended, 1]
    related = (JOINT_PARENTS[first] == second) | (JOINT_PARENTS[second] == first)
    assert np.mean(related) > 0.9


def test_mid_segment_vertices_are_rigid(model: HandModel) -> None:
    """Vertices nearest to a digit segment, within its middle fifth, have weight 1 for its joint."""
    skeleton = model.skeleton
    owners = list(range(1, 16)) + [0] * 5                  # digit segments, four metacarpals, forearm
    starts, ends = zip(*(segment_ends(model, joint) for joint in range(1, 16)), strict=True)
    starts = np.vstack([starts, np.zeros((5, 3))])
    ends = np.vstack([ends, skeleton.rest_positions[[4, 7, 10, 13]], [[0.0, -50.0, 0.0]]])
    axes = ends - starts
    relative = model.vertices[:, None, :] - starts[None]
    along = np.einsum("vjk,jk->vj", relative, axes) / np.einsum("jk,jk->j", axes, axes)
    closest = starts[None] + np.clip(along, 0.0, 1.0)[..., None] * axes[None]
    nearest = np.linalg.norm(model.vertices[:, None, :] - closest, axis=2).argmin(axis=1)
    rows = np.arange(len(model.vertices))
    middle = (along[rows, nearest] > 0.4) & (along[rows, nearest] < 0.6) & (nearest < 15)
    joint_of = np.array(owners)[nearest]
    single = (model.skin_weights[:, 0] == 1.0) & (model.skin_joints[:, 0] == joint_of)
    for joint in range(1, 16):
        selected = middle & (joint_of == joint)
        assert selected.sum() > 20, joint
        assert np.mean(single[selected]) > 0.9, joint
    assert np.mean(single[middle]) > 0.98


def test_landmarks(model: HandModel) -> None:
    assert tuple(model.landmarks) == LANDMARK_NAMES
    assert set(LANDMARK_DESCRIPTIONS) == set(LANDMARK_NAMES)
    indices = np.array(list(model.landmarks.values()))
    assert len(set(indices.tolist())) == 20 and indices.min() >= 0 and indices.max() < len(model.vertices)
    skeleton = model.skeleton
    for digit, name in enumerate(("thumb", "index", "middle", "ring", "little")):
        distal = 3 + 3 * digit
        direction = skeleton.rest_rotations[distal][:, 1]
        tip = model.vertices[model.landmarks[f"{name}_tip"]]
        assert np.linalg.norm(tip - skeleton.tip_positions[digit]) < 3.0
        owned = model.skin_joints[:, 0] == distal
        assert tip @ direction >= (model.vertices[owned] @ direction).max() - 1e-9
    # joint landmarks lie on the dorsal side, over the joint centre
    joint_names = {"thumb": ("mcp", "ip"), "index": ("mcp", "pip", "dip"), "middle": ("mcp", "pip", "dip"),
                   "ring": ("mcp", "pip", "dip"), "little": ("mcp", "pip", "dip")}
    for digit, (name, joints) in enumerate(joint_names.items()):
        for joint_name in joints:
            joint = 1 + 3 * digit + (("cmc", "mcp", "ip") if digit == 0 else ("mcp", "pip", "dip")).index(joint_name)
            offset = model.vertices[model.landmarks[f"{name}_{joint_name}"]] - skeleton.rest_positions[joint]
            dorsal = -skeleton.rest_rotations[joint][:, 2]
            assert offset @ dorsal > 4.0
            assert np.linalg.norm(offset - (offset @ dorsal) * dorsal) < 3.0
    wrist = model.vertices[model.landmarks["wrist"]]
    assert wrist[2] > 10.0 and np.hypot(wrist[0], wrist[1]) < 3.0


def test_back_direction_and_hand_length(model: HandModel) -> None:
    np.testing.assert_allclose(model.back_direction, [0.0, 0.0, 1.0], atol=1e-12)
    assert 170.0 <= model.hand_length <= 210.0
    normals = mesh_vertex_normals(model.vertices, model.faces)
    v = model.vertices
    dorsal_palm = (np.abs(v[:, 0]) < 20) & (v[:, 1] > 10) & (v[:, 1] < 70) & (v[:, 2] > 0)
    assert dorsal_palm.sum() > 200
    assert np.mean(normals[dorsal_palm] @ model.back_direction > 0.9) > 0.8


def test_fingers_are_separate(model: HandModel) -> None:
    """Beyond the web, vertices of adjacent fingers stay apart at rest."""
    dominant = model.skin_joints[:, 0]
    for a, b in ((4, 7), (7, 10), (10, 13)):
        finger_a = model.vertices[np.isin(dominant, [a + 1, a + 2])]        # middle and distal phalanges
        finger_b = model.vertices[np.isin(dominant, [b, b + 1, b + 2])]
        gaps = np.linalg.norm(finger_a[:, None, :] - finger_b[None, :, :], axis=2)
        assert gaps.min() > 2.0, (a, b)


def test_reproportioned_subjects(reshaped: HandModel) -> None:
    assert 9_000 <= len(reshaped.vertices) <= 15_000
    assert_closed_manifold(reshaped)
    assert_valid_weights(reshaped)
    assert tuple(reshaped.landmarks) == LANDMARK_NAMES and len(set(reshaped.landmarks.values())) == 20
    assert 160.0 <= reshaped.hand_length <= 225.0


def test_stored_template_matches_a_fresh_build(model: HandModel) -> None:
    stored = HandModel.load(DEFAULT_TEMPLATE_PATH)
    assert DEFAULT_TEMPLATE_PATH.stat().st_size < 1.5e6
    assert len(stored.vertices) == len(model.vertices) and len(stored.faces) == len(model.faces)
    assert stored.landmarks == model.landmarks
    assert checksum(stored) == checksum(model)


def test_fist_keeps_rigid_cores(model: HandModel) -> None:
    theta = np.zeros(26)
    theta[[i for i, name in enumerate(PARAM_NAMES) if name.endswith("flexion")]] = 1.2
    posed = skin_vertices(model, theta)
    assert np.all(np.isfinite(posed))
    edges = np.unique(np.sort(np.concatenate([model.faces[:, [0, 1]], model.faces[:, [1, 2]],
                                              model.faces[:, [2, 0]]]), axis=1), axis=0)
    rigid = model.skin_weights[:, 0] == 1.0
    joints = model.skin_joints[:, 0]
    core = rigid[edges[:, 0]] & rigid[edges[:, 1]] & (joints[edges[:, 0]] == joints[edges[:, 1]])
    finger_core = core & (joints[edges[:, 0]] > 0)
    assert finger_core.sum() > 3000
    rest_length = np.linalg.norm(np.diff(model.vertices[edges[core]], axis=1)[:, 0], axis=1)
    posed_length = np.linalg.norm(np.diff(posed[edges[core]], axis=1)[:, 0], axis=1)
    np.testing.assert_allclose(posed_length, rest_length, rtol=1e-9, atol=1e-9)
    # the fingertips curl towards the palm
    tip = model.landmarks["middle_tip"]
    assert posed[tip, 1] < model.vertices[tip, 1] - 60.0 and posed[tip, 2] < -20.0


def test_left_hand_is_the_mirror_image() -> None:
    assert TEMPLATE_PATH == DEFAULT_TEMPLATE_PATH
    right, left = load_template("right"), load_template("left")
    np.testing.assert_allclose(left.vertices, right.vertices * [-1.0, 1.0, 1.0])
    assert signed_volume(left.vertices, left.faces) > 0


def test_compiled_skinning_and_normals_match_their_numpy_definition(model: HandModel) -> None:
    """The per-vertex kernels give the blend of ``A_j v + b_j`` over the influences and the area-weighted
    normals, as the vectorised numpy definitions do, for random poses."""
    rng = np.random.default_rng(7)
    for _ in range(3):
        theta = np.concatenate([rng.normal(0.0, 50.0, 3), rng.normal(0.0, 1.0, 3), rng.normal(0.0, 0.4, 20)])
        linear, translation = model.chain.skinning_matrices(theta)
        expected = np.zeros_like(model.vertices)
        for k in range(model.skin_joints.shape[1]):
            joints = model.skin_joints[:, k]
            moved = np.einsum("vab,vb->va", linear[joints], model.vertices) + translation[joints]
            expected += model.skin_weights[:, k:k + 1] * moved
        posed = skin_vertices(model, theta)
        np.testing.assert_allclose(posed, expected, atol=1e-9)
        corners = posed[model.faces]
        face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        summed = np.zeros_like(posed)
        for k in range(3):
            np.add.at(summed, model.faces[:, k], face_normals)
        np.testing.assert_allclose(mesh_vertex_normals(posed, model.faces),
                                   summed / np.linalg.norm(summed, axis=1, keepdims=True), atol=1e-12)
