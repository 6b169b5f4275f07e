"""Fitting the hand model to a single depth frame without markers (depth and silhouette terms only), from a rough
start: the bounding box of the nearest object (the hand held towards the camera).

Start hypotheses: the hand centred on the box's 3D points, its fingers along the image axis of the segmented
region towards its nearer end, palm towards or away from the camera, fingers at the prior's mean posture. Each is
optimised in rounds, the observation (wrist cut at the model's wrist) renewed before each: a swarm on eq. 3 with
the silhouette term alone in the first round and the depth and silhouette terms after it, then articulated ICP
(depth points, silhouette, soft posture prior); the lowest energy (depth and silhouette terms) wins.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.camera.model import Camera
from core.errors import InputError
from core.fusion.energy import EnergyWeights, FrameEnergy
from core.fusion.hand_render import MIDDLE_MCP, HandRenderer
from core.fusion.icp import ArticulatedICP, ICPSettings
from core.fusion.observation import observe
from core.fusion.pso import SwarmSettings, particle_swarm
from core.fusion.silhouette import depth_silhouette
from core.model import HandModel, MarkerSet, load_layout, load_template, resolve_layout
from core.model.kinematics import vector_from_rotation
from core.model.skeleton import N_GLOBAL, N_PARAMS, default_joint_limits
from core.prior import PosturePrior, load_default_prior

#: wide initial spread of a rough start: wrist translation (mm), rotation (rad), finger angles (rad)
ROUGH_SPREAD = np.concatenate([np.full(3, 25.0), np.full(3, 0.25), np.full(20, 0.3)])
DEPTH_ONLY = EnergyWeights(marker=0.0, edge=0.0, smoothness=0.0)
#: the first round fits the outline alone: eq. 6 averages over the overlap, so from a rough start a fist that
#: overlaps little but well scores better than the open hand whose plane is not yet found
SILHOUETTE_ONLY = EnergyWeights(marker=0.0, depth=0.0, edge=0.0, smoothness=0.0)


@dataclass(frozen=True)
class DepthFitSettings:
    """Swarm per hypothesis and round, ICP, rounds, crop size."""

    swarm: SwarmSettings = field(default_factory=lambda: SwarmSettings(particles=24, generations=25))
    icp: ICPSettings = field(default_factory=lambda: ICPSettings(iterations=10, prior_weight=1.0, max_distance_mm=80.0))
    rounds: int = 2
    max_side: int = 80
    random_seed: int = 0


@dataclass
class DepthFit:
    """``theta (26,)``; ``depth_residual_mm``: Ed of eq. 6 at the fit; ``silhouette``: Es of eq. 5; ``box``
    (left, top, right, bottom) px of the rough start."""

    theta: np.ndarray
    depth_residual_mm: float
    silhouette: float
    box: tuple[int, int, int, int]


def hand_box(depth: np.ndarray) -> tuple[tuple[int, int, int, int], np.ndarray]:
    """Bounding box (left, top, right, bottom) px and mask (H,W) of the nearest object in a depth image (mm)."""
    mask = depth_silhouette(depth)
    rows, columns = np.nonzero(mask)
    if len(rows) == 0:
        raise InputError("the depth frame holds no depth")
    return (int(columns.min()), int(rows.min()), int(columns.max()), int(rows.max())), mask


def _orientation(model: HandModel, fingers: np.ndarray, back: np.ndarray) -> np.ndarray:
    """Rotation vector (3,) turning the rest hand's finger axis to ``fingers`` and its back normal to ``back``."""
    rest_axis = model.skeleton.rest_positions[MIDDLE_MCP] - model.skeleton.rest_positions[0]
    rest_back = np.asarray(model.back_direction, float)

    def frame(axis: np.ndarray, normal: np.ndarray) -> np.ndarray:
        axis = axis / np.linalg.norm(axis)
        normal = normal - (normal @ axis) * axis
        normal /= np.linalg.norm(normal)
        return np.column_stack([axis, normal, np.cross(axis, normal)])

    return vector_from_rotation(frame(fingers, back) @ frame(rest_axis, rest_back).T)


def start_poses(model: HandModel, camera: Camera, depth: np.ndarray, mask: np.ndarray,
                prior: PosturePrior) -> list[np.ndarray]:
    """The two rough start poses (palm towards and away from the camera) for the segmented ``mask`` of ``depth``:
    the fingers point along the region's image axis towards its nearer end (the arm reaches back to the body)."""
    rows, columns = np.nonzero(mask & (depth > 0))
    pixels = np.column_stack([columns, rows]).astype(float)
    values = depth[rows, columns].astype(float)
    points = camera.back_project(pixels, values)
    centre = np.median(points, axis=0)
    _, vectors = np.linalg.eigh(np.cov((pixels - pixels.mean(axis=0)).T))
    image_axis = vectors[:, 1]
    along_axis = (pixels - pixels.mean(axis=0)) @ image_axis
    low, high = np.percentile(along_axis, [25, 75])
    if values[along_axis >= high].mean() > values[along_axis <= low].mean():
        image_axis = -image_axis
    forward = camera.rotation.T @ np.array([0.0, 0.0, 1.0])
    along = camera.rotation.T @ np.array([image_axis[0], image_axis[1], 0.0])
    renderer = HandRenderer(model, camera)
    starts = []
    for back in (forward, -forward):
        theta = np.zeros(N_PARAMS)
        theta[N_GLOBAL:] = prior.mean
        theta[3:6] = _orientation(model, along, back)
        theta[0:3] = centre - renderer.vertices(theta).mean(axis=0)
        starts.append(theta)
    return starts


def fit_depth_frame(depth: np.ndarray, camera: Camera, settings: DepthFitSettings | None = None,
                    model: HandModel | None = None, prior: PosturePrior | None = None) -> DepthFit:
    """Fit the model to one depth frame (mm, ideal pinhole ``camera``) from the nearest object's bounding box."""
    settings = settings or DepthFitSettings()
    model = model or load_template()
    prior = prior or load_default_prior()
    box, mask = hand_box(depth)
    corners = np.array([[box[0], box[1]], [box[2], box[3]]], dtype=float)
    renderer = HandRenderer(model, camera)
    no_markers: MarkerSet = resolve_layout(model, load_layout("dense"))
    absent = np.full((len(no_markers.names), 3), np.nan)
    lower, upper = default_joint_limits()
    icp = ArticulatedICP(renderer, no_markers, lower, upper, settings.icp)
    rng = np.random.default_rng(settings.random_seed)
    all_digits = np.ones(5, dtype=bool)
    prior_matrix = np.eye(N_PARAMS - N_GLOBAL) - prior.components[:, :3] @ prior.components[:, :3].T
    best, best_energy = None, np.inf
    for start in start_poses(model, camera, depth, mask, prior):
        theta = start
        for round_index in range(settings.rounds):
            observation = observe(renderer, theta, depth, None, None, absent, max_side=settings.max_side,
                                  include=corners)
            weights = SILHOUETTE_ONLY if round_index == 0 else DEPTH_ONLY
            energy = FrameEnergy(renderer, observation, no_markers, None, weights)
            spread = ROUGH_SPREAD / (1 + 2 * round_index)
            theta, _ = particle_swarm(energy, theta, lower, upper, settings.swarm, rng, spread=spread)
            theta = icp.fit(theta, observation, prior_matrix, prior.mean, all_digits, None)
        observation = observe(renderer, theta, depth, None, None, absent, max_side=settings.max_side,
                              include=corners)
        value = FrameEnergy(renderer, observation, no_markers, None, DEPTH_ONLY)(theta)
        if value < best_energy:
            best, best_energy = theta, value
    if best is None:
        raise InputError("the depth fit failed: no start pose gave a finite energy")
    observation = observe(renderer, best, depth, None, None, absent, max_side=settings.max_side, include=corners)
    terms = FrameEnergy(renderer, observation, no_markers, None, DEPTH_ONLY).terms(best)
    return DepthFit(best, float(terms[2]), float(terms[1]), box)
