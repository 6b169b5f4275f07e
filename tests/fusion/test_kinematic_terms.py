"""The thesis Ch. 6 terms added to the articulated ICP (issue 27, item 3): finger collisions, the wrist on the
forearm's axis, the temporal terms on the chain's points, the rigid-only first iteration, the posture prior's
pull to the mean; and the hand segmentation on synthetic depth."""

from __future__ import annotations

import numpy as np

from handmocap.core.camera.model import Camera
from handmocap.core.fusion.depth_fit import DepthFitter, palm_centre, scaled_model
from handmocap.core.fusion.hand_render import Crop
from handmocap.core.fusion.hand_segment import find_hands
from handmocap.core.fusion.icp import ArticulatedICP, FitExtras, ICPSettings
from handmocap.core.fusion.kinematic_terms import CollisionTerm, chain_points, temporal_rows, wrist_rows
from handmocap.core.prior import load_default_prior
from handmocap.core.prior.pca_prior import soft_prior_matrix

CAMERA = Camera(np.array([[476.0, 0.0, 320.0], [0.0, 476.0, 240.0], [0.0, 0.0, 1.0]]), np.zeros(5), (640, 480),
                registered=True)


def _numeric_rows(function, theta: np.ndarray, step: float = 1e-6) -> np.ndarray:
    base = function(theta)
    rows = np.zeros((len(base), len(theta)))
    for index in range(len(theta)):
        moved = theta.copy()
        moved[index] += step
        rows[:, index] = (function(moved) - base) / step
    return rows


def test_collision_term_rest_and_mean_are_free_and_its_rows_are_the_derivative(template):
    collisions = CollisionTerm(template)
    theta = np.zeros(26)
    assert len(collisions.rows(theta)[0]) == 0                   # the rest hand does not collide
    theta[6:] = load_default_prior().mean
    assert len(collisions.rows(theta)[0]) == 0                   # nor the prior's mean posture
    theta = np.zeros(26)
    theta[10] = 0.25                                              # the index abducted into the middle finger
    residual, rows = collisions.rows(theta)
    assert len(residual) >= 3 and (residual < 0).all()
    numeric = _numeric_rows(lambda t: collisions.rows(t)[0], theta)
    assert np.allclose(numeric[:, 6:], rows[:, 6:], atol=1e-3)
    theta[10] = 0.35                                              # further: two segments' axes cross
    residual, rows = collisions.rows(theta)
    assert (np.abs(rows).sum(axis=1) > 0).all()                  # even there, a direction to part them


def test_wrist_and_temporal_rows_are_the_derivative(template):
    theta = np.zeros(26)
    theta[2] = 500.0
    theta[3:6] = [0.2, -0.1, 0.3]
    point, direction = np.array([300.0, 250.0]), np.array([0.6, 0.8])
    residual, rows = wrist_rows(template, CAMERA, theta, point, direction)
    numeric = _numeric_rows(lambda t: wrist_rows(template, CAMERA, t, point, direction)[0], theta)
    assert np.allclose(numeric, rows, atol=1e-4)
    chain = chain_points(template)
    last = chain.evaluate(theta)[0] + 3.0
    before = last + 2.0
    residual, rows = temporal_rows(chain, theta, last, before, 0.5, 0.25)
    assert residual.shape == (2 * 21 * 3,)
    numeric = _numeric_rows(lambda t: temporal_rows(chain, t, last, before, 0.5, 0.25)[0], theta)
    assert np.allclose(numeric[:, :3], rows[:, :3], atol=1e-4) and np.allclose(numeric[:, 6:], rows[:, 6:],
                                                                                atol=1e-3)


def test_prior_pull_to_the_mean_shrinks_within_the_subspace():
    prior = load_default_prior()
    projector = soft_prior_matrix(prior, 5, 1.0, 0.0)
    pulled = soft_prior_matrix(prior, 5, 1.0, 0.05)
    inside = prior.components[:, 0]                               # along the first component: no cost without ω5
    assert np.linalg.norm(projector @ inside) < 1e-9 < np.linalg.norm(pulled @ inside)


def _flat_hand(fitter: DepthFitter, distance_mm: float = 500.0) -> tuple[np.ndarray, np.ndarray]:
    """A rendered depth frame (H,W) mm of the open hand facing the camera and its pose (26,)."""
    theta = np.zeros(26)
    theta[3:6] = [np.pi, 0.0, 0.0]                                # fingers up the image, palm to the camera
    theta[0:3] = np.array([0.0, 0.0, distance_mm]) - palm_centre(fitter.model, theta)
    rendering = fitter.renderer.render(theta, Crop(0, 0, 480, 640, 1), with_edges=False)
    return np.where(rendering.silhouette, rendering.depth, 0.0).astype(np.float32), theta


def test_rigid_first_iteration_moves_the_wrist_only_and_the_fit_recovers_a_shifted_hand():
    fitter = DepthFitter(CAMERA)
    depth, truth = _flat_hand(fitter)
    candidate = find_hands(depth, CAMERA)[0]
    assert candidate.fingers >= 4 and not candidate.problems
    start = truth.copy()
    start[0:3] += [12.0, -8.0, 10.0]
    start[7] = 0.3
    rigid = ArticulatedICP(fitter.renderer, fitter.no_markers, fitter.lower, fitter.upper,
                           ICPSettings(iterations=1, rigid_iterations=1))
    observation = fitter.observe(start, depth, candidate.mask)
    moved = rigid.fit(start, observation, None, fitter.prior.mean, np.ones(5, bool), None, FitExtras())
    assert np.allclose(moved[6:], np.clip(start[6:], fitter.lower[6:], fitter.upper[6:]))
    assert not np.allclose(moved[:3], start[:3])
    fitted = fitter.refine(start, depth, candidate.mask, FitExtras(), candidate=candidate)
    assert np.linalg.norm(palm_centre(fitter.model, fitted) - palm_centre(fitter.model, truth)) < 6.0
    assert abs(fitted[7] - truth[7]) < 0.2


def test_segmentation_finds_the_rendered_hand_by_its_size_not_its_nearness(template):
    fitter = DepthFitter(CAMERA)
    depth, _ = _flat_hand(fitter, 600.0)
    depth[:, :140] = 350.0                                        # a large board nearer than the hand, at the side
    candidates = find_hands(depth, CAMERA)
    assert np.hypot(*(candidates[0].palm_px - [320, 240])) < 40
    assert scaled_model(template, 1.1).hand_length > template.hand_length
