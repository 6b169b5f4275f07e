"""Fusion building blocks (issue 15): crop rendering, silhouettes, energy terms, swarm, adaptive subspace, lifting."""

from __future__ import annotations

import numpy as np
import pytest

from handmocap.core.camera.model import Camera
from handmocap.core.camera.render import render_mesh
from handmocap.core.fusion.energy import TERMS, EnergyWeights, FrameEnergy
from handmocap.core.fusion.hand_render import HandRenderer, crop_around, distance_to, edge_map
from handmocap.core.fusion.lifting import interpolate_poses, lift
from handmocap.core.fusion.observation import ideal_image, observe
from handmocap.core.fusion.pso import SwarmSettings, particle_swarm
from handmocap.core.fusion.silhouette import cut_at_wrist, depth_silhouette, grabcut, wristband_line
from handmocap.core.fusion.subspace import AdaptiveSubspace
from handmocap.core.model import load_layout, load_template, marker_positions, resolve_layout
from handmocap.core.model.skeleton import default_joint_limits
from handmocap.core.prior import load_default_prior
from handmocap.core.simulate.camera import render_scene, simulate_camera_take


@pytest.fixture(scope="module")
def scene():
    simulated = simulate_camera_take(seed=3, n_frames=120)
    camera = simulated.camera
    model = load_template()
    renderer = HandRenderer(model, camera)
    background, _ = render_scene(camera, None, None, np.zeros((0, 3)), 3.0, np.random.default_rng(1), False)
    index = 10
    theta, _ = simulated.pose_at(float(camera.clock.mocap_time(simulated.camera_times[index])))
    colour, depth = simulated.render(index)
    markers = resolve_layout(model, load_layout("dense"))
    observed_markers = marker_positions(model, markers, theta)
    return dict(camera=camera, renderer=renderer, theta=theta, colour=ideal_image(colour, camera),
                depth=ideal_image(depth, camera, nearest=True), background=ideal_image(background, camera),
                markers=markers, observed_markers=observed_markers)


def test_fusion_crop_render_matches_full_render(scene):
    renderer, theta, camera = scene["renderer"], scene["theta"], scene["camera"]
    crop = crop_around(renderer.pixels(theta), camera, max_side=400)
    assert crop.stride == 1
    cropped = renderer.render(theta, crop)
    vertices = renderer.vertices(theta)
    full = render_mesh(Camera(camera.matrix, np.zeros(5), camera.size, camera.rotation, camera.translation),
                       vertices, renderer.faces)[0]
    window = crop.take(full)
    both = np.isfinite(window) & np.isfinite(cropped.depth)
    assert both.sum() > 500 and (np.isfinite(window) == cropped.silhouette).mean() > 0.999
    assert np.abs(window[both] - cropped.depth[both]).max() < 1e-3
    assert cropped.edges.any() and not (cropped.edges & ~cropped.silhouette).any()


def test_fusion_edges_and_distance_transform():
    silhouette = np.zeros((20, 20), bool)
    silhouette[5:15, 5:15] = True
    depth = np.where(silhouette, 500.0, np.inf)
    depth[5:15, 10:15] = 540.0                       # a step of 40 mm inside: an occluding contour
    edges = edge_map(depth, silhouette)
    assert edges[5, 7] and edges[10, 10] and not edges[10, 7]
    distance = distance_to(edges)
    assert distance[10, 7] == pytest.approx(2.0) and distance[0, 0] > 5


def test_fusion_colour_silhouette_matches_the_hand(scene):
    observation = observe(scene["renderer"], scene["theta"] + np.r_[4.0, -3.0, 2.0, np.zeros(23)], scene["depth"],
                          scene["colour"], scene["background"], scene["observed_markers"])
    assert observation.source == "colour"
    truth = scene["renderer"].render(scene["theta"], observation.crop).silhouette
    union = (truth | observation.silhouette).sum()
    assert (truth & observation.silhouette).sum() / union > 0.8


def test_fusion_depth_silhouette_and_wrist_cuts():
    depth = np.full((60, 80), 1500.0, np.float32)
    depth[20:40, 10:70] = 600.0                      # a near bar (arm + hand) before a far wall
    nearest = depth_silhouette(depth)
    assert nearest.sum() == 20 * 60
    cut = cut_at_wrist(nearest, np.array([40.0, 30.0]), np.array([1.0, 0.0]))
    assert cut[:, :40].sum() == 0 and cut[:, 40:].sum() == 20 * 30
    colour = np.zeros((60, 80, 3), np.uint8)
    colour[18:42, 38:42] = (0, 0, 220)               # a red band across the bar (BGR)
    line = wristband_line(colour, (170, 10), np.ones((60, 80), bool))
    assert line is not None and abs(line[1][1]) > 0.99   # the band runs down the image
    assert wristband_line(colour, (50, 70), np.ones((60, 80), bool)) is None


def test_fusion_grabcut_without_background_returns_initial_mask():
    colour = np.full((30, 30, 3), 120, np.uint8)
    everything = np.ones((30, 30), bool)
    assert grabcut(colour, everything, everything, everything).all()


def test_fusion_energy_terms_prefer_the_truth_and_switch_off(scene):
    observation = observe(scene["renderer"], scene["theta"], scene["depth"], scene["colour"], scene["background"],
                          scene["observed_markers"])
    truth = scene["theta"]
    energy = FrameEnergy(scene["renderer"], observation, scene["markers"], truth, EnergyWeights())
    at_truth = energy.terms(truth)
    assert len(at_truth) == len(TERMS) and at_truth[0] < 0.1 and at_truth[4] == 0.0
    moved = truth.copy()
    moved[0] += 12.0
    moved[6 + 4 * 2 + 2] += 0.6                      # middle finger PIP
    at_moved = energy.terms(moved)
    assert (at_moved[:4] > at_truth[:4]).all()
    assert at_moved[0] == pytest.approx(8.0, abs=0.5)  # every marker beyond the 8 mm cut-off
    markers_only = FrameEnergy(scene["renderer"], observation, scene["markers"], None,
                               EnergyWeights(silhouette=0, depth=0, edge=0, smoothness=0))
    terms = markers_only.terms(moved)
    assert terms[0] > 0 and (terms[1:] == 0).all()


def test_fusion_swarm_minimises_and_keeps_bounds():
    settings = SwarmSettings(particles=20, generations=60)
    assert settings.constriction == pytest.approx(0.7298, abs=1e-4)
    target = np.linspace(-0.5, 0.5, 26)
    lower, upper = np.full(26, -1.0), np.full(26, 0.3)
    best, value = particle_swarm(lambda x: float(((x - target) ** 2).sum()), np.zeros(26), lower, upper, settings,
                                 np.random.default_rng(0), spread=np.full(26, 0.2))
    minimum = float(((np.clip(target, lower, upper) - target) ** 2).sum())
    assert value - minimum < 0.1 * (float((target ** 2).sum()) - minimum)       # 90 % of the way from the start
    assert (best <= upper).all() and (best >= lower).all()


def test_fusion_adaptive_subspace_incremental_covariance():
    prior = load_default_prior()
    subspace = AdaptiveSubspace(prior, anchor_dims=3, corrective_dims=2, buffer=10, residual_range=(0.0, 10.0))
    rng = np.random.default_rng(4)
    direction = rng.normal(size=20)
    postures = prior.mean + np.outer(rng.normal(size=25), direction) * 0.3 + rng.normal(size=(25, 20)) * 0.01
    for posture in postures:
        assert subspace.offer(posture)
    residuals = np.array([subspace.residual(posture) for posture in postures[-10:]])
    centred = residuals - residuals.mean(axis=0)
    assert np.allclose(subspace._covariance, centred.T @ centred / 10, atol=1e-10)
    assert np.abs(subspace.anchor.T @ subspace.corrective).max() < 1e-8
    learnt = subspace.residual(prior.mean + direction)
    assert abs(subspace.corrective[:, 0] @ learnt) / np.linalg.norm(learnt) > 0.99
    before = np.linalg.norm(AdaptiveSubspace(prior).prior_matrix() @ (0.3 * direction))
    assert np.linalg.norm(subspace.prior_matrix() @ (0.3 * direction)) < 0.2 * before
    assert subspace.report()["corrective_updates"] == 16


def test_fusion_lifting_follows_markers_and_keeps_hidden_fingers():
    model = load_template()
    markers = resolve_layout(model, load_layout("dense"))
    lower, upper = default_joint_limits()
    frames = 13
    truth = np.zeros((frames, 26))
    truth[:, 0] = np.linspace(0, 30, frames)
    truth[:, 6:] = load_default_prior().mean
    truth[:, 6 + 4 + 1] += np.linspace(0, 0.6, frames)         # index flexes
    targets = np.array([marker_positions(model, markers, theta) for theta in truth])
    key_frames = np.array([0.0, 6.0, 12.0])
    assert np.allclose(interpolate_poses(key_frames, truth[[0, 6, 12]], frames)[6], truth[6])
    thumb = [markers.names.index(name) for name in ("thumb_distal", "thumb_proximal")]
    targets[:, thumb] = np.nan
    keys = truth[[0, 6, 12]].copy()
    lifted = lift(model, markers, targets, key_frames, keys, lower, upper)
    assert np.abs(lifted[:, 0] - truth[:, 0]).max() < 0.5
    assert np.abs(lifted[:, 11] - truth[:, 11]).max() < 0.03
    assert np.abs(lifted[:, 6:10] - truth[:, 6:10]).max() < 0.05
