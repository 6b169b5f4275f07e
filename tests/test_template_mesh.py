"""The generated template hand: closed mesh, skin weights, landmarks, stored file, posing."""

import numpy as np
import pytest

from core.model import TEMPLATE_PATH, HandModel, load_template, skin_vertices
from core.model.skeleton import PARAM_NAMES, HandProportions
from core.model.template_mesh import LANDMARK_NAMES, build_template, edge_face_counts, signed_volume


@pytest.fixture(scope="module")
def model() -> HandModel:
    return load_template()


def test_mesh_is_closed_outward_and_about_12k_vertices(model):
    assert 10_000 <= len(model.vertices) <= 14_000
    assert np.all(edge_face_counts(model.faces) == 2)
    assert len(model.vertices) - len(np.unique(np.sort(
        np.vstack([model.faces[:, [0, 1]], model.faces[:, [1, 2]], model.faces[:, [2, 0]]]), axis=1),
        axis=0)) + len(model.faces) == 2   # Euler characteristic of a sphere
    assert signed_volume(model.vertices, model.faces) > 0


def test_skin_weights(model):
    weights = model.skin_weights
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-9)
    assert (weights > 0).sum(axis=1).max() <= 4
    assert np.mean(weights.max(axis=1) == 1.0) > 0.5


def test_landmarks_back_direction_and_length(model):
    assert tuple(model.landmarks) == LANDMARK_NAMES and len(set(model.landmarks.values())) == 20
    tip = model.vertices[model.landmarks["middle_tip"]]
    assert tip[1] >= model.vertices[:, 1].max() - 1.0
    dorsal = model.vertex_normals @ model.back_direction > 0.9
    assert dorsal.mean() > 0.1
    assert 170.0 <= model.hand_length <= 210.0


def test_stored_template_matches_a_fresh_build(model):
    fresh = build_template()
    assert TEMPLATE_PATH.exists()
    assert len(fresh.vertices) == len(model.vertices)
    np.testing.assert_allclose(fresh.vertices, model.vertices, atol=1e-6)
    np.testing.assert_array_equal(fresh.faces, model.faces)


def test_reproportioned_subject():
    subject = build_template(HandProportions().scaled(finger_scale=[1.15, 0.85, 1.1, 1.0, 0.9],
                                                      palm_width_scale=1.1))
    subject.validate()
    assert np.all(edge_face_counts(subject.faces) == 2)
    assert len(subject.landmarks) == 20


def test_fist_keeps_rigid_cores_rigid(model):
    theta = np.zeros(26)
    for index, name in enumerate(PARAM_NAMES):
        if "flexion" in name and not name.startswith("thumb"):
            theta[index] = 1.2
    posed = skin_vertices(model, theta)
    rigid = model.skin_weights.max(axis=1) == 1.0
    joint = model.skin_joints[np.arange(len(model.vertices)), model.skin_weights.argmax(axis=1)]
    edges = np.vstack([model.faces[:, [0, 1]], model.faces[:, [1, 2]]])
    same = rigid[edges[:, 0]] & rigid[edges[:, 1]] & (joint[edges[:, 0]] == joint[edges[:, 1]])
    rest_length = np.linalg.norm(model.vertices[edges[same, 0]] - model.vertices[edges[same, 1]], axis=1)
    posed_length = np.linalg.norm(posed[edges[same, 0]] - posed[edges[same, 1]], axis=1)
    np.testing.assert_allclose(posed_length, rest_length, atol=1e-6)


def test_left_hand_is_the_mirror_image(model):
    left = load_template("left")
    np.testing.assert_allclose(left.vertices, model.vertices * [-1.0, 1.0, 1.0])
    assert signed_volume(left.vertices, left.faces) > 0
