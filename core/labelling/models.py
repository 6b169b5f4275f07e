"""The models a scene tracks: articulated hands (IK) and rigid objects (Kabsch), one common interface.

A track holds the last two states (hand: ``theta (26,)``; object: pose ``(4,4)``), predicts the
next one by constant velocity, solves a frame's targets ``(K,3)`` (NaN = not assigned) from the
prediction, and keeps the recent residuals for the adaptive acceptance threshold
``clip(mean + k·std, floor, ceiling)`` (Maycock et al. 2015 §III-C: "the average error from 3D motion
capture points to effector points on the model plus a small term").
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections import deque
from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from handmocap.core.ik import IKSettings, IKSolver
from handmocap.core.ik.horn import horn_rotation
from handmocap.core.ik.solver import LOST_TRACK_MM
from handmocap.core.labelling.take_statistics import SECOND_DIFFERENCE_VARIANCE, TakeStatistics
from handmocap.core.model import N_PARAMS, HandModel, MarkerSet, marker_positions
from handmocap.core.model.objects import ObjectSpec


@njit(cache=True)
def kabsch_kernel(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (3,3) and translation (3,) best mapping ``source (N,3)`` onto ``target (N,3)``
    (Horn's unit quaternion method; compiled, no LAPACK)."""
    count = source.shape[0]
    source_centre = np.zeros(3)
    target_centre = np.zeros(3)
    for i in range(count):
        source_centre += source[i]
        target_centre += target[i]
    source_centre /= count
    target_centre /= count
    m = np.zeros((3, 3))
    for i in range(count):
        for r in range(3):
            for c in range(3):
                m[r, c] += (source[i, r] - source_centre[r]) * (target[i, c] - target_centre[c])
    rotation = np.empty((3, 3))
    horn_rotation(m, rotation)
    return rotation, target_centre - rotation @ source_centre


@dataclass(frozen=True)
class SceneSettings:
    """Tuning of the scene labelling; distances in mm.

    ``gate_mm``: cost of the "missing" option when assigning against the prediction (a point farther
    than this from a predicted effector is never taken by it); ``reappear_gate_mm``: the same for a
    marker missing in the previous frame; ``threshold_k``, ``threshold_floor_mm``,
    ``threshold_ceiling_mm``: adaptive threshold of the IK residuals of the last ``history_frames``
    frames, for a marker that had a point in the previous frame (continuing trajectory);
    ``reappear_floor_mm``: the lower floor of the same threshold for a marker missing in the previous
    frame (a reappearing marker or a ghost: the strict test keeps ghosts out), whose threshold is also
    at most ``reappear_mean_factor`` × the recent mean residual; ``continuity_mm``: a marker seen in the
    previous frame whose new point lies farther than this from the extrapolation of its own last two
    points is missing in that frame and then held to the reappearing threshold (a ghost appearing as
    the marker vanishes, or a neighbouring digit's marker);
    ``cluster_cut_mm``: smallest single-linkage cut of the initial clustering;
    ``icp_iterations``: rigid ICP steps per PCA alignment candidate; ``alpha``: weight of the marker
    count difference D in Maycock eq. 2 (``E + αD``); ``init_max_residual_mm``: largest mean residual
    E of an accepted initial fit; ``init_completion_gate_mm``: after the first fit, cluster points
    this close to an unmatched marker are tried on it (kept when eq. 2 improves);
    ``init_min_share``: share of a model's markers an initial fit must
    match; ``retry_every``: frames between initialisation attempts for a model not found yet;
    ``ik_iterations``, ``ik_tolerance``: Gauss-Newton steps per IK solve and the relative energy
    decrease that ends them early; ``calibrate``: subject calibration (Zhao eq. 2) of the hands
    after initialisation over up to ``calibration_frames`` tracked frames;
    ``reacquire_fit_mm``: largest residual of a rigid object's marker in a fit that re-acquires the
    object (a frame where it has fewer than 3 labelled markers, or a labelled marker farther than this
    from the fit), the pair distances of the tried correspondences agreeing within twice this;
    ``reacquire_reach_mm``, ``reacquire_growth_mm``: see :meth:`RigidTrack.search_radius`;
    ``hypothesis_frames``: frames over which competing initial fits of a hand are tracked before one is
    kept (offline);
    ``self_tuning``: derive the millimetre gates from the noise and speed measured on the take
    (:meth:`adapted`), the values here being their floors.
    """

    gate_mm: float = 20.0
    reappear_gate_mm: float = 20.0
    threshold_k: float = 4.0
    threshold_floor_mm: float = 4.0
    reappear_floor_mm: float = 1.5
    reappear_mean_factor: float = 3.0
    continuity_mm: float = 8.0
    threshold_ceiling_mm: float = 10.0
    history_frames: int = 30
    cluster_cut_mm: float = 40.0
    icp_iterations: int = 10
    alpha: float = 1.0
    init_max_residual_mm: float = 8.0
    init_min_share: float = 0.5
    init_completion_gate_mm: float = 60.0
    retry_every: int = 5
    link_mm: float = 4.0
    fragment_min_frames: int = 20
    verify_frames: int = 100
    hypothesis_frames: int = 50
    rescue_reach_mm: float = 150.0
    ik_iterations: int = 10
    ik_tolerance: float = 1e-4
    calibrate: bool = True
    calibration_frames: int = 150
    reacquire_fit_mm: float = 2.0
    reacquire_reach_mm: float = 150.0
    reacquire_growth_mm: float = 2.0
    self_tuning: bool = True

    def adapted(self, statistics: TakeStatistics) -> SceneSettings:
        """These settings with the millimetre gates raised to what the take's measured ``statistics`` need
        (unchanged when nothing could be measured, or when the take is as quiet and slow as the floors
        assume). With σ the noise per axis, ``noise_radius`` = 4.03 σ bounds 99.9 % of a point's 3D
        noise (χ with 3 degrees of freedom), and ``noise_extrapolation`` = 4.03 √6 σ the noise part of
        a constant-velocity extrapolation error:

        - IK residual floors and ceiling (``threshold_floor_mm``, ``reappear_floor_mm``,
          ``threshold_ceiling_mm``, ``reacquire_fit_mm``, ``init_max_residual_mm``) grow by the noise
          radius: a marker cannot fit its point better than the point's own noise;
        - ``continuity_mm``: at least 1.25 × the 99.9th percentile of the extrapolation error measured
          on linked raw points (noise plus the true acceleration of the fastest markers);
        - ``link_mm``: at least the noise part of the extrapolation error (its floor covers the motion);
        - ``gate_mm``, ``reappear_gate_mm``: at least twice the continuity gate.
        """
        if not self.self_tuning or not statistics.measured:
            return self
        noise_radius = CHI3_999 * statistics.noise_mm
        noise_extrapolation = noise_radius * np.sqrt(SECOND_DIFFERENCE_VARIANCE)
        continuity = max(self.continuity_mm, CONTINUITY_MARGIN * statistics.extrapolation_mm)
        gate = max(self.gate_mm, 2.0 * continuity)
        return replace(
            self,
            threshold_floor_mm=max(self.threshold_floor_mm, noise_radius),
            reappear_floor_mm=max(self.reappear_floor_mm, noise_radius),
            threshold_ceiling_mm=max(self.threshold_ceiling_mm, self.threshold_ceiling_mm - self.threshold_floor_mm
                                     + 2.0 * noise_radius),
            reacquire_fit_mm=max(self.reacquire_fit_mm, noise_radius),
            init_max_residual_mm=max(self.init_max_residual_mm, 2.0 * noise_radius),
            continuity_mm=continuity,
            link_mm=max(self.link_mm, noise_extrapolation),
            gate_mm=gate,
            reappear_gate_mm=max(self.reappear_gate_mm, gate))


CHI3_999 = 4.03
"""99.9th percentile of the norm of a 3D vector of unit Gaussian components (χ, 3 degrees of freedom)."""
CONTINUITY_MARGIN = 1.25
"""The continuity gate is this times the 99.9th percentile of the measured extrapolation error."""


class Track(ABC):
    """Common state of a tracked model: previous states, seen markers, recent residuals."""

    kind = "object"

    def __init__(self, name: str, marker_names: list[str], settings: SceneSettings):
        self.name, self.marker_names, self.settings = name, list(marker_names), settings
        self.count = len(marker_names)
        self.history: list[np.ndarray] = []
        self.seen = np.zeros(self.count, dtype=bool)
        self.recent: deque[tuple[float, float, int]] = deque()
        self._sums = np.zeros(3)
        self.points = [np.full((self.count, 3), np.nan)] * 2

    @property
    def active(self) -> bool:
        return bool(self.history)

    def start(self, state: np.ndarray, seen: np.ndarray | None = None) -> None:
        """(Re)start tracking from ``state`` (the previous frame's solution)."""
        self.history = [state]
        self.seen = np.ones(self.count, dtype=bool) if seen is None else seen.copy()
        self.recent.clear()
        self._sums = np.zeros(3)
        self.points = [np.full((self.count, 3), np.nan)] * 2

    def remember(self, residuals: np.ndarray) -> None:
        """Add one frame's residuals (mm) of the accepted markers to the recent history."""
        entry = (float(residuals.sum()), float((residuals * residuals).sum()), len(residuals))
        self.recent.append(entry)
        self._sums += entry
        if len(self.recent) > self.settings.history_frames:
            self._sums -= self.recent.popleft()

    def thresholds(self) -> np.ndarray:
        """Per marker (K,) mm: the adaptive threshold (at least ``threshold_floor_mm``) for markers seen in
        the previous frame; for the others
        the smaller of the adaptive value and ``reappear_mean_factor`` × the recent mean residual, at
        least ``reappear_floor_mm`` (a reappearing marker must fit as well as the markers already
        tracked; a ghost next to a hidden marker, which the IK can reach only by bending the digit
        away from where the other markers hold it, does not)."""
        adaptive = self.adaptive()
        settings = self.settings
        total, _, count = self._sums
        strict = min(adaptive, settings.reappear_mean_factor * total / count) if count >= 1 else adaptive
        return np.where(self.seen, max(adaptive, settings.threshold_floor_mm), max(strict, settings.reappear_floor_mm))

    def adaptive(self) -> float:
        """``min(mean + k·std, ceiling)`` of the recent residuals (mm); the ceiling before any."""
        settings = self.settings
        total, squares, count = self._sums
        if count < 1:
            return settings.threshold_ceiling_mm
        mean = total / count
        deviation = np.sqrt(max(squares / count - mean * mean, 0.0))
        return float(min(mean + settings.threshold_k * deviation, settings.threshold_ceiling_mm))

    def commit(self, state: np.ndarray, residuals: np.ndarray, seen: np.ndarray,
               points: np.ndarray | None = None) -> None:
        """Accept a frame's solution; ``points (K,3)`` the points the markers took (NaN missing)."""
        self.history = [self.history[-1], state] if self.history else [state]
        self.seen = seen
        self.remember(residuals[seen])
        if points is not None:
            self.points = [self.points[-1], points]

    def jumped(self, points: np.ndarray) -> np.ndarray:
        """(K,) True where the point a marker takes ``points (K,3)`` (NaN none) lies farther than
        ``continuity_mm`` from the constant-velocity extrapolation of its own last two points."""
        last, previous = self.points[-1], self.points[0]
        expected = np.where(np.isfinite(previous), 2.0 * last - previous, last)
        distance = np.sqrt(((points - expected) ** 2).sum(axis=1))
        return distance > self.settings.continuity_mm

    # interface of the concrete tracks
    @abstractmethod
    def predict(self) -> np.ndarray:
        """The state expected in the next frame (constant velocity from the last two)."""

    @abstractmethod
    def effectors(self, state: np.ndarray) -> np.ndarray:
        """Marker positions ``(K,3)`` mm of the model in ``state``."""

    @abstractmethod
    def solve(self, targets: np.ndarray, observed: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The state fitting ``targets (K,3)`` mm where ``observed (K,)``, from ``start``; and its markers."""


class HandTracker(Track):
    """The labeller's tracking state of one hand (a review's hand is :class:`core.review.HandTrack`), tracked
    by IK: warm-started full IK with the soft posture prior on the digits whose
    three segments are not all observed (the refinement step of layered IK), falling back to the
    complete layered solve from a rigid alignment when the warm start lost track."""

    def __init__(self, name: str, kind: str, model: HandModel, markers: MarkerSet, settings: SceneSettings,
                 marker_names: list[str] | None = None):
        super().__init__(name, marker_names or list(markers.names), settings)
        self.kind = kind
        self.set_model(model, markers)

    def set_model(self, model: HandModel, markers: MarkerSet) -> None:
        self.model, self.markers = model, markers
        self.solver = IKSolver(model, markers, settings=IKSettings(max_iterations=self.settings.ik_iterations,
                                                                   tolerance=self.settings.ik_tolerance))
        self.mean_theta = np.zeros(N_PARAMS)
        self.mean_theta[6:] = np.clip(self.solver.prior.mean, self.solver.angle_lower, self.solver.angle_upper)

    def predict(self) -> np.ndarray:
        if len(self.history) < 2:
            return self.history[-1]
        predicted = 2.0 * self.history[-1] - self.history[-2]
        predicted[6:] = np.clip(predicted[6:], self.solver.angle_lower, self.solver.angle_upper)
        return predicted

    def effectors(self, state: np.ndarray) -> np.ndarray:
        return marker_positions(self.model, self.markers, state)

    def solve(self, targets: np.ndarray, observed: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """θ (26,) and effectors (K,3) mm for ``targets (K,3)`` where ``observed (K,)``."""
        if not observed.any():
            return start, self.effectors(start)
        clean = np.where(observed[:, None], targets, 0.0)
        theta, energy, points = self.solver.refine(start, clean, observed)
        if energy > LOST_TRACK_MM ** 2 * observed.sum():
            restart = self.solver.solve_from_alignment(clean, observed)
            if restart[1] < energy:
                theta, energy, points = restart
        return theta, points


COAST_DECAY = 0.9
"""Per frame without any marker of a rigid object, its predicted translation velocity shrinks by this."""


class RigidTrack(Track):
    """A rigid object tracked by Kabsch on its assigned markers; with 2 markers the rotation turns the
    predicted marker axis onto the seen one (the turn about that axis is kept), with 1 translation only."""

    def __init__(self, spec: ObjectSpec, settings: SceneSettings):
        super().__init__(spec.name, list(spec.marker_names), settings)
        self.spec = spec
        self.local = np.asarray(spec.marker_positions, dtype=float)
        #: markers observed in the frames of ``history``; frames since the last fit to 3 or more markers
        self.counts = [0, 0]
        self.lost = 0
        self.extent = float(np.linalg.norm(self.local - self.local.mean(axis=0), axis=1).max())

    def start(self, state: np.ndarray, seen: np.ndarray | None = None) -> None:
        super().start(state, seen)
        self.counts = [0, int(self.seen.sum())]
        self.lost = 0

    def commit(self, state: np.ndarray, residuals: np.ndarray, seen: np.ndarray,
               points: np.ndarray | None = None) -> None:
        super().commit(state, residuals, seen, points)
        self.counts = [self.counts[-1], int(seen.sum())]
        self.lost = self.lost + 1 if self.counts[-1] < min(3, self.count) else 0

    def search_radius(self) -> float:
        """Radius (mm) around the predicted centroid within which points are tried for re-acquisition:
        the object's extent plus ``reacquire_reach_mm``, growing by ``reacquire_growth_mm`` per frame the
        object has had fewer than 3 markers (it may have moved away from where it was last fitted)."""
        settings = self.settings
        return self.extent + settings.reacquire_reach_mm + settings.reacquire_growth_mm * min(self.lost, 1000)

    def predict(self) -> np.ndarray:
        """Constant velocity; the rotation keeps its angular velocity only when both last poses were
        fitted to 3 or more markers (with fewer, part of the rotation is unobserved and extrapolating
        it lets the pose drift), and the translation velocity decays while no marker is seen."""
        if len(self.history) < 2:
            return self.history[-1]
        previous, last = self.history
        predicted = np.eye(4)
        if min(self.counts) >= 3:
            predicted[:3, :3] = last[:3, :3] @ previous[:3, :3].T @ last[:3, :3]
        else:
            predicted[:3, :3] = last[:3, :3]
        velocity = last[:3, 3] - previous[:3, 3]
        if self.counts[-1] == 0:
            velocity = COAST_DECAY * velocity
        predicted[:3, 3] = last[:3, 3] + velocity
        return predicted

    def restart(self, state: np.ndarray, seen: np.ndarray, points: np.ndarray) -> None:
        """Continue from a re-acquired pose (no velocity: the previous pose was wrong)."""
        self.history = [state]
        self.seen = seen.copy()
        self.counts = [0, int(seen.sum())]
        self.lost = 0
        self.points = [np.full((self.count, 3), np.nan), points]

    def effectors(self, state: np.ndarray) -> np.ndarray:
        return self.local @ state[:3, :3].T + state[:3, 3]

    def solve(self, targets: np.ndarray, observed: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pose (4,4) and effectors (K,3) mm for ``targets (K,3)`` where ``observed (K,)``."""
        count = int(observed.sum())
        pose = start.copy()
        if count >= 3:
            rotation, translation = kabsch_kernel(self.local[observed], targets[observed])
            pose[:3, :3], pose[:3, 3] = rotation, translation
        elif count:
            if count == 2:
                # the rotation the two markers determine (all but the turn about their axis, which keeps
                # the prediction's): the smallest rotation bringing the predicted direction onto the seen one
                first, second = self.local[observed]
                seen_first, seen_second = targets[observed]
                pose[:3, :3] = _aligning_rotation(start[:3, :3] @ (second - first), seen_second - seen_first) \
                    @ start[:3, :3]
            moved = self.local[observed] @ pose[:3, :3].T
            pose[:3, 3] = (targets[observed] - moved).mean(axis=0)
        return pose, self.effectors(pose)


def _aligning_rotation(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The smallest rotation (3,3) turning the direction of ``source (3,)`` onto that of ``target (3,)``
    (identity when either is degenerate or they are opposite)."""
    a_norm, b_norm = np.linalg.norm(source), np.linalg.norm(target)
    if a_norm < 1e-9 or b_norm < 1e-9:
        return np.eye(3)
    a, b = source / a_norm, target / b_norm
    axis = np.cross(a, b)
    cosine = float(a @ b)
    if cosine <= -1.0 + 1e-9:
        return np.eye(3)
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + cross + cross @ cross / (1.0 + cosine)


def pose_matrix(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """4×4 homogeneous pose from ``rotation (3,3)`` and ``translation (3,)``."""
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = rotation, translation
    return pose
