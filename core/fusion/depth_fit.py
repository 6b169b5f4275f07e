"""Fitting the hand model to a single depth frame without markers (thesis Ch. 6 on one frame), with a verdict.

1. **Where is the hand**: :func:`core.fusion.hand_segment.find_hands` scores hand-sized objects (palm size,
   physical area, fingers, how the object leaves a hand's reach, the image border, the distance band); the best
   candidates are fitted in turn until one fit is trusted.
2. **Several starts** per candidate: the model's palm centre on the observed palm centre, its palm plane on the
   plane of the observed palm (back towards and away from the camera), the fingers pointing away from the
   forearm (both ways along the hand's image axis when no forearm is seen), open or at the prior's mean
   posture. Each start is fitted by the articulated ICP in rounds (the observation, cut at the model's wrist,
   renewed before each): a rigid-only first iteration, then depth points (ℓ1-like, front-facing
   correspondences), silhouette, the soft PCA prior with its pull to the mean, the wrist on the forearm's axis
   and the finger collisions. The lowest energy (eq. 3 of Zhao et al.: silhouette and depth terms) is kept.
3. **Trusted** only when the object is hand-like and the fit explains it: the model covers the observed hand,
   stays inside it, its depth agrees, nothing of it floats in front of the observed surface, and the hand is
   not cut by the image border. Every failed check is a reason in plain words.

Everything is in the depth camera's frame (a camera without extrinsics: mocap frame = camera frame), mm.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from handmocap.core.camera.model import Camera
from handmocap.core.errors import CancelledError, InputError
from handmocap.core.fusion.energy import EnergyWeights, FrameEnergy
from handmocap.core.fusion.hand_render import MIDDLE_MCP, Crop, HandRenderer
from handmocap.core.fusion.hand_segment import HandCandidate, SegmentSettings, find_hands
from handmocap.core.fusion.icp import ArticulatedICP, FitExtras, ICPSettings
from handmocap.core.fusion.kinematic_terms import chain_points
from handmocap.core.fusion.observation import Observation, observe
from handmocap.core.model import HandModel, MarkerSet, load_layout, load_template, resolve_layout
from handmocap.core.model.kinematics import vector_from_rotation
from handmocap.core.model.skeleton import (
    JOINT_NAMES,
    N_GLOBAL,
    N_JOINTS,
    N_PARAMS,
    PARAM_NAMES,
    Skeleton,
    default_joint_limits,
)
from handmocap.core.prior import PosturePrior, load_default_prior
from handmocap.core.prior.pca_prior import soft_prior_matrix

DEPTH_ONLY = EnergyWeights(marker=0.0, edge=0.0, smoothness=0.0)
#: the "spread" start posture: thumb abducted away from the palm, fingers apart, every joint straight (rad)
SPREAD_POSTURE = np.radians(np.array([-25.0, 0, 0, 0, -10.0, 0, 0, 0, 0, 0, 0, 0, 8.0, 0, 0, 0, 15.0, 0, 0, 0]))
#: energy added per detected finger end the fitted model does not cover: a mirrored hypothesis (the palm for the
#: back) can match the silhouette and the depth as well as the right one but leaves the thumb or a finger bare
ENDS_WEIGHT = 2.0
#: sizes of a subject's hand against the template the fit accepts
SCALE_RANGE = (0.8, 1.3)
#: the palm centre: half-way between the wrist and the mean of the four finger knuckles
KNUCKLES = [JOINT_NAMES.index(f"{digit}_mcp") for digit in ("index", "middle", "ring", "little")]


@dataclass(frozen=True)
class TrustSettings:
    """When a fit is trusted: shares of the observed hand the model misses and of the model outside the observed
    hand, the mean depth difference (mm) over their overlap, the share of the model in front of the observed
    surface by more than ``float_mm``."""

    max_missed: float = 0.25
    max_outside: float = 0.25
    max_depth_mm: float = 9.0
    float_mm: float = 25.0
    max_floating: float = 0.10


@dataclass(frozen=True)
class DepthFitSettings:
    """Segmentation, candidates fitted, ICP, rounds per start, crop size, the posture prior's subspace and pull to
    the mean (thesis ω4, ω5), the verdict."""

    segment: SegmentSettings = field(default_factory=SegmentSettings)
    #: candidates fitted at most (the next one only when the previous fit is not trusted)
    candidates: int = 3
    icp: ICPSettings = field(default_factory=lambda: ICPSettings(
        iterations=8, depth_points=1200, prior_weight=0.5, max_distance_mm=60.0, rigid_iterations=1,
        wrist_weight=0.02, collision_weight=0.05, tip_weight=0.5, front_weight=1.0, coverage_weight=1.0))
    rounds: int = 3
    #: first rounds that also pull the model's tips to the detected finger ends, and their gate (mm)
    tip_rounds: int = 2
    tip_gate_mm: float = 100.0
    max_side: int = 96
    prior_dims: int = 5
    omega4: float = 1.0
    omega5: float = 0.05
    #: start postures: "open" (every angle 0) and "mean" (the prior's mean)
    postures: tuple[str, ...] = ("open", "spread", "mean")
    #: the start's finger direction is also turned by these angles in the image (deg)
    turns_deg: tuple[float, ...] = ()
    trust: TrustSettings = field(default_factory=TrustSettings)
    #: the model's size against the template; None: estimated from the observed palm of an open hand
    scale: float | None = None


@dataclass
class DepthFit:
    """The fit of one depth frame: ``theta (26,)`` (camera frame, mm and rad), ``side``; residuals:
    ``depth_residual_mm`` (Ed, mean |observed − model depth| over the overlap), ``silhouette`` (Es), ``missed``
    share of the observed hand the model leaves uncovered, ``outside`` share of the model outside it,
    ``floating`` share of the model in front of the observed surface, ``energy`` (22 Es + 0.8 Ed + 2 per detected
    finger end off the model, ``ends_missed``: the selection energy of the starts);
    ``palm_uv (2,)`` px and ``palm_depth_mm`` of the palm centre; ``trusted`` and ``reasons`` (why not);
    ``candidate`` the object fitted, ``starts`` energies of every start, ``seconds``."""

    theta: np.ndarray
    side: str
    depth_residual_mm: float
    silhouette: float
    missed: float
    outside: float
    floating: float
    energy: float
    palm_uv: np.ndarray
    palm_depth_mm: float
    trusted: bool
    reasons: list[str]
    candidate: HandCandidate | None
    starts: list[float] = field(default_factory=list)
    candidates_tried: int = 1
    seconds: float = 0.0
    mask: np.ndarray | None = None
    scale: float = 1.0
    ends_missed: int = 0

    @property
    def box(self) -> tuple[int, int, int, int]:
        """(left, top, right, bottom) px of the fitted object (or of the whole image when none)."""
        if self.candidate is None:
            return (0, 0, 0, 0)
        return self.candidate.box()

    def to_dict(self) -> dict:
        """Plain values for a JSON report."""
        return {
            "trusted": self.trusted, "why_not": list(self.reasons), "side": self.side,
            "palm_uv": [round(float(v), 2) for v in self.palm_uv], "palm_depth_mm": round(self.palm_depth_mm, 1),
            "residuals": {"depth_mm": round(self.depth_residual_mm, 3), "silhouette": round(self.silhouette, 4),
                          "missed_share": round(self.missed, 4), "outside_share": round(self.outside, 4),
                          "floating_share": round(self.floating, 4), "energy": round(self.energy, 4),
                          "fingers_seen_off_model": self.ends_missed},
            "pose": {name: round(float(value if index < 3 else np.degrees(value)), 3)
                     for index, (name, value) in enumerate(zip(PARAM_NAMES, self.theta, strict=True))},
            "pose_units": "wrist_tx..tz mm (camera frame), wrist_rx..rz rotation vector in degrees, joints degrees",
            "theta": [float(value) for value in self.theta],
            "object": None if self.candidate is None else self.candidate.summary(),
            "starts_energy": [round(value, 4) for value in self.starts],
            "candidates_tried": self.candidates_tried, "seconds": round(self.seconds, 2),
            "scale": round(self.scale, 3),
        }


def scaled_model(model: HandModel, scale: float) -> HandModel:
    """``model`` uniformly scaled about its wrist by ``scale`` (a subject's hand larger or smaller than the
    template; the thesis adapts its model to the user by a global scale)."""
    skeleton = model.skeleton
    wrist = skeleton.rest_positions[0]
    resized = Skeleton(wrist + scale * (skeleton.rest_positions - wrist), skeleton.rest_rotations.copy(),
                       wrist + scale * (skeleton.tip_positions - wrist), skeleton.side)
    return replace(model, skeleton=resized, vertices=wrist + scale * (np.asarray(model.vertices) - wrist),
                   faces=np.asarray(model.faces).copy(), skin_joints=np.asarray(model.skin_joints).copy(),
                   skin_weights=np.asarray(model.skin_weights).copy(), hand_length=model.hand_length * scale,
                   name=f"{model.name} × {scale:.3f}")


def palm_centre(model: HandModel, theta: np.ndarray) -> np.ndarray:
    """The palm centre (3,) mm at ``theta``: half-way between the wrist and the mean of the finger knuckles."""
    _, positions = model.chain.joint_transforms(theta)
    return 0.5 * (positions[0] + positions[KNUCKLES].mean(axis=0))


def _rest_frame(model: HandModel) -> np.ndarray:
    """Columns: the rest hand's finger axis (wrist → middle knuckle), its back normal, their cross product."""
    axis = model.skeleton.rest_positions[MIDDLE_MCP] - model.skeleton.rest_positions[0]
    return _frame(axis, np.asarray(model.back_direction, float))


def _frame(axis: np.ndarray, normal: np.ndarray) -> np.ndarray:
    axis = axis / np.linalg.norm(axis)
    normal = normal - (normal @ axis) * axis
    normal = normal / np.linalg.norm(normal)
    return np.column_stack([axis, normal, np.cross(axis, normal)])


def _palm_plane(depth: np.ndarray, camera: Camera, candidate: HandCandidate) -> tuple[np.ndarray, np.ndarray]:
    """``(centre (3,), normal (3,))`` of the observed palm: the candidate's points within its palm radius of the
    palm centre; the normal points towards the camera."""
    focal = float(np.mean(camera.focal))
    radius_px = candidate.palm_radius_mm * focal / candidate.palm_depth_mm
    rows, columns = np.nonzero(candidate.mask)
    near = np.hypot(columns - candidate.palm_px[0], rows - candidate.palm_px[1]) <= radius_px
    pixels = np.column_stack([columns[near], rows[near]]).astype(float)
    points = camera.back_project(pixels, depth[rows[near], columns[near]])
    centre = np.median(points, axis=0)
    if len(points) < 10:
        return centre, -camera.rotation.T @ np.array([0.0, 0.0, 1.0])
    _, vectors = np.linalg.eigh(np.cov((points - centre).T))
    normal = vectors[:, 0]
    towards_camera = camera.centre - centre
    return centre, normal if normal @ towards_camera > 0 else -normal


def _image_directions(candidate: HandCandidate, turns_deg: tuple[float, ...]) -> list[np.ndarray]:
    """Image directions (2,) of the fingers to start from: towards the mean of the finger ends when two or more
    fingers are seen, away from the forearm when it is seen, else both ways along the candidate's image axis;
    each also turned by ``turns_deg``; directions closer than 15° to an earlier one are dropped."""
    bases = []
    if candidate.fingers >= 2:
        towards = candidate.finger_px - candidate.palm_px
        towards = towards / np.maximum(np.linalg.norm(towards, axis=1, keepdims=True), 1e-9)
        mean = towards.mean(axis=0)
        if np.linalg.norm(mean) > 0.3:
            bases.append(mean / np.linalg.norm(mean))
    if candidate.arm_direction_px is not None:
        bases.append(-candidate.arm_direction_px)
    if not bases:
        rows, columns = np.nonzero(candidate.mask)
        pixels = np.column_stack([columns, rows]).astype(float)
        _, vectors = np.linalg.eigh(np.cov((pixels - pixels.mean(axis=0)).T))
        bases = [vectors[:, 1], -vectors[:, 1]]
    directions: list[np.ndarray] = []
    for base in bases:
        for turn in (0.0,) + tuple(turns_deg):
            angle = np.radians(turn)
            turned = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]) @ base
            if all(float(turned @ other) < np.cos(np.radians(15.0)) for other in directions):
                directions.append(turned)
    return directions


def _finger_directions(camera: Camera, candidate: HandCandidate, centre: np.ndarray, normal: np.ndarray,
                       turns_deg: tuple[float, ...]) -> list[np.ndarray]:
    """3D finger directions (in the observed palm plane) of :func:`_image_directions`."""
    directions = []
    for image_direction in _image_directions(candidate, turns_deg):
        target_pixel = candidate.palm_px + 40.0 * image_direction
        ray = camera.rays(target_pixel[None])[0]
        ray_world = camera.rotation.T @ ray
        origin = camera.centre
        denominator = float(ray_world @ normal)
        if abs(denominator) < 1e-6:
            continue
        point = origin + ray_world * float((centre - origin) @ normal) / denominator
        direction = point - centre
        direction -= (direction @ normal) * normal
        if np.linalg.norm(direction) > 1e-6:
            directions.append(direction / np.linalg.norm(direction))
    return directions


def start_poses(model: HandModel, camera: Camera, depth: np.ndarray, candidate: HandCandidate,
                prior: PosturePrior, postures: tuple[str, ...] = ("open", "mean"),
                turns_deg: tuple[float, ...] = ()) -> list[np.ndarray]:
    """Start poses (26,) for ``candidate``: every finger direction × back of the hand towards / away from the
    camera × posture ("open": zeros, "spread": :data:`SPREAD_POSTURE`, "mean": the prior's mean). The model's
    palm centre sits half a palm's thickness behind the observed palm surface."""
    centre, normal = _palm_plane(depth, camera, candidate)
    rest = _rest_frame(model)
    starts = []
    for fingers in _finger_directions(camera, candidate, centre, normal, turns_deg):
        for back in (normal, -normal):
            rotation = vector_from_rotation(_frame(fingers, back) @ rest.T)
            for posture in postures:
                theta = np.zeros(N_PARAMS)
                theta[3:6] = rotation
                if posture == "mean":
                    theta[N_GLOBAL:] = prior.mean
                elif posture == "spread":
                    theta[N_GLOBAL:] = SPREAD_POSTURE
                behind = centre - 15.0 * normal
                theta[0:3] = behind - palm_centre(model, theta)
                starts.append(theta)
    return starts


def forearm_line(candidate: HandCandidate) -> tuple[np.ndarray, np.ndarray] | None:
    """The forearm's image axis ``(point (2,), direction (2,))`` px of the segmentation, or None."""
    return candidate.arm_line_px


class DepthFitter:
    """Fits one hand side's model into one depth camera (see the module docstring); reused across frames.
    ``scale``: the model's size against the template (None: estimated per frame from the observed palm)."""

    def __init__(self, camera: Camera, side: str = "right", settings: DepthFitSettings | None = None,
                 model: HandModel | None = None, prior: PosturePrior | None = None, scale: float = 1.0) -> None:
        self.camera = camera
        self.settings = settings or DepthFitSettings()
        self.base_model = model or load_template(side)
        self.scale = float(scale)
        self.model = self.base_model if self.scale == 1.0 else scaled_model(self.base_model, self.scale)
        self.side = self.model.side
        self.prior = prior or load_default_prior()
        self.renderer = HandRenderer(self.model, camera)
        self.no_markers: MarkerSet = resolve_layout(self.model, load_layout("dense"))
        self.absent = np.full((len(self.no_markers.names), 3), np.nan)
        self.lower, self.upper = default_joint_limits()
        self.icp = ArticulatedICP(self.renderer, self.no_markers, self.lower, self.upper, self.settings.icp)
        self.prior_matrix = soft_prior_matrix(self.prior, self.settings.prior_dims, self.settings.omega4,
                                              self.settings.omega5)
        self.chain = chain_points(self.model)
        self._scaled: dict[float, DepthFitter] = {self.scale: self}
        self._palm_radius_mm: float | None = None

    def for_scale(self, scale: float) -> DepthFitter:
        """The fitter of the same hand at ``scale`` (rounded to 0.02; built once)."""
        scale = round(float(np.clip(scale, *SCALE_RANGE)) / 0.02) * 0.02
        if scale not in self._scaled:
            fitter = DepthFitter(self.camera, self.side, self.settings, self.base_model, self.prior, scale)
            fitter._scaled = self._scaled
            self._scaled[scale] = fitter
        return self._scaled[scale]

    def model_palm_radius_mm(self) -> float:
        """The palm radius the segmentation measures on the base model held open and flat 500 mm from the
        camera (the scale's reference)."""
        if self._palm_radius_mm is None:
            reference = self._scaled.get(1.0) or self.for_scale(1.0)
            theta = np.zeros(N_PARAMS)
            rest = _rest_frame(reference.model)
            theta[3:6] = vector_from_rotation(_frame(self.camera.rotation.T @ np.array([0.0, -1.0, 0.0]),
                                                     self.camera.rotation.T @ np.array([0.0, 0.0, -1.0])) @ rest.T)
            ahead = self.camera.centre + self.camera.rotation.T @ np.array([0.0, 0.0, 500.0])
            theta[0:3] = ahead - palm_centre(reference.model, theta)
            crop = Crop(0, 0, self.camera.height, self.camera.width, 1)
            rendering = reference.renderer.render(theta, crop, with_edges=False)
            found = find_hands(np.where(rendering.silhouette, rendering.depth, 0.0).astype(np.float32), self.camera,
                               self.settings.segment)
            self._palm_radius_mm = found[0].palm_radius_mm if found else 40.0
            for fitter in self._scaled.values():
                fitter._palm_radius_mm = self._palm_radius_mm
        return self._palm_radius_mm

    def renderer_for(self, fit: DepthFit) -> HandRenderer:
        """The renderer of the model a fit was made with (its scale)."""
        return self.for_scale(fit.scale).renderer

    def estimate_scale(self, candidate: HandCandidate) -> float:
        """The hand's size against the template from the observed palm radius (an open hand, three fingers or
        more seen), else the fitter's own scale."""
        if self.settings.scale is not None:
            return self.settings.scale
        if candidate.fingers < 3:
            return self.scale
        return float(np.clip(candidate.palm_radius_mm / self.model_palm_radius_mm(), *SCALE_RANGE))

    def observe(self, theta: np.ndarray, depth: np.ndarray, mask: np.ndarray) -> Observation:
        """The observation of the segmented ``mask`` cut at the wrist of ``theta``."""
        return observe(self.renderer, theta, depth, None, None, self.absent, max_side=self.settings.max_side,
                       segmented=mask)

    def refine(self, theta: np.ndarray, depth: np.ndarray, mask: np.ndarray, extras: FitExtras,
               rounds: int | None = None, previous: np.ndarray | None = None,
               candidate: HandCandidate | None = None) -> np.ndarray:
        """ICP rounds from ``theta`` on the segmented ``mask`` (the observation renewed before each round); in the
        first ``tip_rounds`` the model's tips are also pulled to the ``candidate``'s detected finger ends."""
        all_digits = np.ones(5, dtype=bool)
        rounds = self.settings.rounds if rounds is None else rounds
        for round_index in range(rounds):
            observation = self.observe(theta, depth, mask)
            round_extras = extras
            if candidate is not None and round_index < min(self.settings.tip_rounds, rounds - 1):
                round_extras = replace(extras, tip_targets=self.tip_targets(theta, candidate))
            theta = self.icp.fit(theta, observation, self.prior_matrix, self.prior.mean, all_digits, previous,
                                 round_extras)
        return theta

    def tip_targets(self, theta: np.ndarray, candidate: HandCandidate) -> np.ndarray | None:
        """Detected finger ends (5,3) mm assigned to the model's digits at ``theta`` (Hungarian on the distance to
        the model's tips, gated at ``tip_gate_mm``; NaN: none), half a finger's thickness behind the surface."""
        if candidate.fingers == 0:
            return None
        ends = self.camera.to_mocap(candidate.finger_mm)
        rays = ends - self.camera.centre
        ends = ends + 8.0 * rays / np.maximum(np.linalg.norm(rays, axis=1, keepdims=True), 1e-9)
        tips = self.chain.evaluate(theta)[0][N_JOINTS:]
        cost = np.linalg.norm(tips[:, None, :] - ends[None, :, :], axis=2)
        gate = self.settings.tip_gate_mm
        padded = np.full((5, len(ends) + 5), gate)
        padded[:, :len(ends)] = np.minimum(cost, 10 * gate)
        rows, columns = linear_sum_assignment(padded)
        targets = np.full((5, 3), np.nan)
        for digit, column in zip(rows, columns, strict=True):
            if column < len(ends) and cost[digit, column] < gate:
                targets[digit] = ends[column]
        return targets

    def energy(self, theta: np.ndarray, depth: np.ndarray, mask: np.ndarray) -> float:
        observation = self.observe(theta, depth, mask)
        return FrameEnergy(self.renderer, observation, self.no_markers, None, DEPTH_ONLY)(theta)

    def judge(self, theta: np.ndarray, depth: np.ndarray, candidate: HandCandidate | None, mask: np.ndarray
              ) -> DepthFit:
        """Residuals and the verdict of the pose ``theta`` on the segmented ``mask`` (the object ``candidate``)."""
        trust = self.settings.trust
        observation = self.observe(theta, depth, mask)
        energy = FrameEnergy(self.renderer, observation, self.no_markers, None, DEPTH_ONLY)
        terms = energy.terms(theta)
        rendering = self.renderer.render(theta, observation.crop, with_edges=False)
        observed, rendered = observation.silhouette, rendering.silhouette
        missed = float((observed & ~rendered).sum()) / max(int(observed.sum()), 1)
        outside = float((rendered & ~observed).sum()) / max(int(rendered.sum()), 1)
        crop_depth = observation.crop.take(depth).astype(float)
        seen = rendered & (crop_depth > 0)
        floating = float((seen & (rendering.depth < crop_depth - trust.float_mm)).sum()) / max(int(rendered.sum()), 1)
        reasons = [] if candidate is None else list(candidate.problems)
        if candidate is None:
            reasons.append("no hand-sized object in the frame")
        if missed > trust.max_missed:
            reasons.append(f"the model leaves {100 * missed:.0f} % of the object uncovered "
                           f"(≤ {100 * trust.max_missed:.0f} % expected)")
        if outside > trust.max_outside:
            reasons.append(f"{100 * outside:.0f} % of the model lies outside the object's silhouette "
                           f"(≤ {100 * trust.max_outside:.0f} % expected)")
        if terms[2] > trust.max_depth_mm:
            reasons.append(f"depth residual {terms[2]:.1f} mm (≤ {trust.max_depth_mm:.0f} mm expected)")
        if floating > trust.max_floating:
            reasons.append(f"{100 * floating:.0f} % of the model floats in front of the observed surface")
        ends_missed = 0 if candidate is None else _ends_missed(candidate.finger_px, rendered, observation.crop)
        if ends_missed >= 2:
            reasons.append(f"{ends_missed} of the {candidate.fingers if candidate else 0} fingers seen are not on the "
                           "model")
        centre = palm_centre(self.model, theta)
        pixel = self.camera.project(centre[None])[0]
        value = float(DEPTH_ONLY.vector() @ terms) + ENDS_WEIGHT * ends_missed
        return DepthFit(theta, self.side, float(terms[2]), float(terms[1]), missed, outside, floating, value,
                        pixel, float(self.camera.to_camera(centre[None])[0, 2]), not reasons, reasons, candidate,
                        mask=mask, scale=self.scale, ends_missed=ends_missed)

    def fit_candidate(self, depth: np.ndarray, candidate: HandCandidate,
                      cancelled: Callable[[], bool] | None = None) -> DepthFit:
        """Every start on one candidate; the lowest energy kept and judged."""
        extras = FitExtras(wrist_line=forearm_line(candidate))
        best, best_energy, energies = None, np.inf, []
        for start in start_poses(self.model, self.camera, depth, candidate, self.prior, self.settings.postures,
                                 self.settings.turns_deg):
            if cancelled is not None and cancelled():
                raise CancelledError("depth fit cancelled")
            theta = self.refine(start, depth, candidate.mask, extras, candidate=candidate)
            judged = self.judge(theta, depth, candidate, candidate.mask)
            energies.append(judged.energy)
            if judged.energy < best_energy:
                best, best_energy = judged, judged.energy
        if best is None:
            raise InputError("the depth fit failed: no start pose gave a finite energy")
        best.starts = energies
        return best

    def fit(self, depth: np.ndarray, cancelled: Callable[[], bool] | None = None, scale: float | None = None
            ) -> DepthFit:
        """Find the hand in ``depth (H,W)`` mm and fit it (see the module docstring); ``scale``: the hand's size
        against the template when known (a track's), else estimated per candidate."""
        started = time.perf_counter()
        depth = _checked_depth(depth, self.camera)
        candidates = find_hands(depth, self.camera, self.settings.segment)
        if not candidates:
            theta = np.zeros(N_PARAMS)
            theta[2] = 500.0
            fit = DepthFit(theta, self.side, np.nan, np.nan, 1.0, 1.0, 0.0, np.inf, np.full(2, np.nan), np.nan,
                           False, ["no hand-sized object in the frame (nothing at a palm's size within "
                                   f"{self.settings.segment.near_mm:.0f}–{self.settings.segment.far_mm:.0f} mm)"],
                           None)
            fit.candidates_tried = 0
            fit.seconds = time.perf_counter() - started
            return fit
        fits = []
        for candidate in candidates[:max(1, self.settings.candidates)]:
            fitter = self.for_scale(scale if scale is not None else self.estimate_scale(candidate))
            fits.append(fitter.fit_candidate(depth, candidate, cancelled))
            if fits[-1].trusted:
                break
        trusted = [fit for fit in fits if fit.trusted]
        chosen = trusted[0] if trusted else fits[0]
        chosen.candidates_tried = len(fits)
        chosen.seconds = time.perf_counter() - started
        return chosen


def _ends_missed(ends: np.ndarray, rendered: np.ndarray, crop: Crop) -> int:
    """How many detected finger ends ``ends (F,2)`` px fall outside the rendered model ``rendered`` (crop samples,
    one sample of tolerance)."""
    if len(ends) == 0:
        return 0
    grown = cv2.dilate(rendered.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    columns = np.round((ends[:, 0] - crop.left) / crop.stride).astype(int)
    rows = np.round((ends[:, 1] - crop.top) / crop.stride).astype(int)
    inside = (rows >= 0) & (rows < crop.rows) & (columns >= 0) & (columns < crop.columns)
    covered = np.zeros(len(ends), dtype=bool)
    covered[inside] = grown[rows[inside], columns[inside]]
    return int((~covered).sum())


def _checked_depth(depth: np.ndarray, camera: Camera) -> np.ndarray:
    depth = np.asarray(depth, dtype=np.float32)
    if depth.ndim != 2:
        raise InputError(f"a depth frame must be one channel, got an array of shape {depth.shape}")
    if depth.shape != (camera.height, camera.width):
        raise InputError(f"the depth frame is {depth.shape[1]}×{depth.shape[0]} px but the intrinsics are for "
                         f"{camera.width}×{camera.height}")
    if not np.isfinite(depth).all():
        depth = np.where(np.isfinite(depth), depth, 0.0).astype(np.float32)
    if not (depth > 0).any():
        raise InputError("the depth frame holds no depth (every pixel is 0)")
    return depth


def fit_depth_frame(depth: np.ndarray, camera: Camera, settings: DepthFitSettings | None = None,
                    model: HandModel | None = None, prior: PosturePrior | None = None, side: str = "right",
                    cancelled: Callable[[], bool] | None = None) -> DepthFit:
    """Fit the model to one depth frame (mm, 0 = none; ideal pinhole ``camera``): see the module docstring."""
    return DepthFitter(camera, side, settings, model, prior).fit(depth, cancelled)
