"""Per-frame automatic labelling of one right hand (Maycock et al. 2015, §III-B).

Each frame: predict the posture from the two previous solutions (constant velocity on θ), assign
the frame's points to the predicted effectors by the Hungarian method with a "missing" option at
the gating cost, solve IK with the assigned points, reject assignments whose IK residual exceeds
the adaptive threshold (mean + k·std of recent residuals, clipped to a floor and a ceiling), then
re-assign against the solved effectors. A marker that was missing in the previous frame is accepted
only if the IK that includes it reaches it below the threshold. Points left unassigned are ghosts.

The automatic initialisation (:func:`initial_pose_from_points`) assumes what the paper asks of the
first frame: the hand is a spatially separate cluster (nothing within ~40 mm of it), most markers
are visible and few ghosts sit in the cluster, and the hand is not far from the mean posture of the
prior (a flat-ish or relaxed hand). The model is not scaled to the subject (no OBB scaling, no
subject calibration), so hands of very different size from the template may fail to initialise.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import product

import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.optimize import linear_sum_assignment

from core.errors import CancelledError, InputError
from core.ik import IKSolver, kabsch
from core.io import Take
from core.model import N_PARAMS, HandModel, MarkerLayout, MarkerSet, load_layout, marker_positions, resolve_layout
from core.model.kinematics import rotation_from_vector, vector_from_rotation

FORBIDDEN_COST = 1e6
"""Cost of an impossible pairing in the augmented assignment matrix (mm)."""

LINK_MARGIN = 1.2
"""The clustering cut is at least this times the layout's own largest single-linkage gap (mean posture)."""


@dataclass(frozen=True)
class TrackerSettings:
    """Tuning of the per-frame tracker; distances in mm.

    ``gate_mm``: cost of the "missing" option when assigning against the prediction (a point farther
    than this from a predicted effector is never taken by it); ``threshold_k``, ``threshold_floor_mm``,
    ``threshold_ceiling_mm``: adaptive threshold ``clip(mean + k·std, floor, ceiling)`` of the IK
    residuals of the last ``history_frames`` frames; ``cluster_cut_mm``: smallest single-linkage cut
    of the initial clustering (raised for sparse layouts, see ``LINK_MARGIN``); ``icp_iterations``:
    rigid ICP steps per PCA alignment candidate.
    """

    gate_mm: float = 20.0
    threshold_k: float = 4.0
    threshold_floor_mm: float = 4.0
    threshold_ceiling_mm: float = 10.0
    history_frames: int = 30
    cluster_cut_mm: float = 40.0
    icp_iterations: int = 10


@dataclass
class LabelingResult:
    """Labelling of a take with M layout markers over F frames.

    ``assignment (F,M)`` point column of the take taken by each marker (-1 missing);
    ``confidence (F,M)`` mm: margin between the chosen and the next-best option of the marker in the
    final assignment (0 when the marker did not get its nearest option, NaN when nothing was solved);
    ``joint_angles (F,26)``; ``residuals_mm (F,M)`` distance from the solved effector to the taken
    point (NaN when missing); ``ghost_points (F,P)`` True for a measured point no marker took;
    ``marker_names`` the layout's markers.
    """

    assignment: np.ndarray
    confidence: np.ndarray
    joint_angles: np.ndarray
    residuals_mm: np.ndarray
    ghost_points: np.ndarray
    marker_names: list[str]


def _assign(effectors: np.ndarray, points: np.ndarray, gate_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Hungarian assignment of ``points (N,3)`` to ``effectors (M,3)`` with a "missing" option at
    ``gate_mm``. Returns the point index per effector (-1 missing) (M,) and the confidence margin
    (M,) mm."""
    markers, count = len(effectors), len(points)
    distances = np.linalg.norm(effectors[:, None, :] - points[None, :, :], axis=2)
    missing = np.full((markers, markers), FORBIDDEN_COST)
    np.fill_diagonal(missing, gate_mm)
    cost = np.concatenate([np.minimum(distances, FORBIDDEN_COST), missing], axis=1)
    rows, columns = linear_sum_assignment(cost)
    chosen = np.full(markers, -1, dtype=np.int64)
    chosen[rows] = columns
    options = np.concatenate([distances, np.full((markers, 1), gate_mm)], axis=1)
    chosen_option = np.where(chosen < count, chosen, count)
    ordered = np.sort(options, axis=1)
    best = options.argmin(axis=1) == chosen_option
    margin = np.where(best, ordered[:, 1] - ordered[:, 0], 0.0) if count else np.zeros(markers)
    return np.where(chosen < count, chosen, -1), margin


def _targets(points: np.ndarray, point_index: np.ndarray) -> np.ndarray:
    """Targets (M,3) mm for the IK: the assigned point per marker, NaN where ``point_index`` is -1."""
    return np.where((point_index >= 0)[:, None], points[np.maximum(point_index, 0)], np.nan)


class _Tracker:
    """State of the per-frame tracker: IK solver, previous solutions, recent residuals."""

    def __init__(self, model: HandModel, markers: MarkerSet, settings: TrackerSettings,
                 initial_theta: np.ndarray):
        self.model, self.markers, self.settings = model, markers, settings
        self.solver = IKSolver(model, markers)
        self.previous = [np.asarray(initial_theta, dtype=float)]
        self.previous_seen = np.ones(len(markers.names), dtype=bool)
        self.recent_residuals: list[np.ndarray] = []
        self.solved_this_frame = False

    def threshold(self) -> float:
        """Adaptive acceptance threshold (mm) from the residuals of the recent frames."""
        settings = self.settings
        if not self.recent_residuals:
            return settings.threshold_ceiling_mm
        residuals = np.concatenate(self.recent_residuals)
        value = residuals.mean() + settings.threshold_k * residuals.std() if residuals.size else np.inf
        return float(np.clip(value, settings.threshold_floor_mm, settings.threshold_ceiling_mm))

    def _solve(self, points: np.ndarray, point_index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """θ (26,) and effectors (M,3) mm of this frame's IK with the points ``point_index`` (M,).
        A repeated call in the same frame replaces the frame's solution instead of adding a frame."""
        theta, effectors = self.solver.solve_frame(_targets(points, point_index),
                                                   replace_last=self.solved_this_frame)
        self.solved_this_frame = True
        if not np.isfinite(theta).all():
            return self.previous[-1], marker_positions(self.model, self.markers, self.previous[-1])
        return theta, effectors

    def track(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Label one frame of ``points (N,3)`` mm (finite rows only). Returns the point index per
        marker (M,) (-1 missing), the confidence (M,) mm, θ (26,) and the residuals (M,) mm."""
        settings = self.settings
        self.solved_this_frame = False
        predicted_theta = (2.0 * self.previous[-1] - self.previous[-2] if len(self.previous) > 1
                           else self.previous[-1])
        predicted = marker_positions(self.model, self.markers, predicted_theta)
        threshold = self.threshold()
        point_index, _ = _assign(predicted, points, settings.gate_mm)
        theta, effectors = self._solve(points, point_index)
        residuals = np.linalg.norm(effectors - _targets(points, point_index), axis=1)
        if np.any(residuals > threshold):
            point_index = np.where(residuals > threshold, -1, point_index)
            theta, effectors = self._solve(points, point_index)
        second, confidence = _assign(effectors, points, threshold)
        if not np.array_equal(second, point_index):
            theta, effectors = self._solve(points, second)
            residuals = np.linalg.norm(effectors - _targets(points, second), axis=1)
            unreached = (residuals > threshold) & ~self.previous_seen
            if unreached.any():
                second = np.where(unreached, -1, second)
                theta, effectors = self._solve(points, second)
        point_index = second
        residuals = np.linalg.norm(effectors - _targets(points, point_index), axis=1)
        seen = point_index >= 0
        self.previous = [self.previous[-1], theta]
        self.previous_seen = seen
        self.recent_residuals = (self.recent_residuals + [residuals[seen]])[-settings.history_frames:]
        return point_index, confidence, theta, residuals


def _hand_cluster(points: np.ndarray, marker_count: int, cut_mm: float) -> np.ndarray:
    """Points (K,3) of the cluster taken as the hand: among single-linkage clusters cut at
    ``cut_mm``, those of at least half the layout's size; the densest (smallest mean nearest-
    neighbour distance); the largest cluster when none is big enough."""
    if len(points) < 2:
        return points
    labels = fcluster(linkage(points, method="single"), t=cut_mm, criterion="distance")
    clusters = [points[labels == label] for label in np.unique(labels)]
    large = [cluster for cluster in clusters if len(cluster) >= max(3, marker_count // 2)]
    if not large:
        return max(clusters, key=len)

    def spacing(cluster: np.ndarray) -> float:
        distances = np.linalg.norm(cluster[:, None] - cluster[None], axis=2)
        np.fill_diagonal(distances, np.inf)
        return float(distances.min(axis=1).mean())

    return min(large, key=spacing)


def _principal_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid (3,) and principal axes as columns (3,3), by decreasing variance."""
    centre = points.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((points - centre).T))
    return centre, vectors[:, ::-1]


def _rigid_icp(source: np.ndarray, target: np.ndarray, rotation: np.ndarray, translation: np.ndarray,
               iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Refine the rigid map of ``source (M,3)`` onto ``target (N,3)`` by Kabsch on Hungarian matches."""
    for _ in range(iterations):
        moved = source @ rotation.T + translation
        rows, columns = linear_sum_assignment(np.linalg.norm(moved[:, None] - target[None], axis=2))
        if len(rows) < 3:
            break
        rotation, translation = kabsch(source[rows], target[columns])
    return rotation, translation


def initial_pose_from_points(points: np.ndarray, model: HandModel, markers: MarkerSet,
                             settings: TrackerSettings | None = None) -> np.ndarray:
    """θ (26,) of the hand in the first frame's ``points (N,3)`` mm (NaN rows ignored).

    Clusters the points, aligns the template markers (mean posture of the prior) to the hand cluster
    by PCA frames with the four proper sign combinations of the axes, rigid ICP, Hungarian
    assignment and IK, and keeps the candidate of least ``E + D`` (Maycock eq. 2: mean residual in
    mm plus the number of markers left unmatched). Raises InputError with fewer than 3 points.
    """
    settings = settings or TrackerSettings()
    points = points[np.isfinite(points).all(axis=1)]
    if len(points) < 3:
        raise InputError(f"the first frame has {len(points)} point(s); automatic labelling needs at "
                         "least 3 to find the hand (give an initial posture instead)")
    solver = IKSolver(model, markers)
    mean_theta = np.zeros(N_PARAMS)
    mean_theta[6:] = np.clip(solver.prior.mean, solver.angle_lower, solver.angle_upper)
    model_points = marker_positions(model, markers, mean_theta)
    layout_link = linkage(model_points, method="single")[:, 2].max()
    cut = max(settings.cluster_cut_mm, LINK_MARGIN * layout_link)
    cluster = _hand_cluster(points, len(markers.names), cut)
    if len(cluster) < 3:
        raise InputError("no cluster of at least 3 points in the first frame; automatic labelling "
                         "cannot find the hand (give an initial posture instead)")
    model_centre, model_axes = _principal_frame(model_points)
    cluster_centre, cluster_axes = _principal_frame(cluster)
    best_theta, best_score = mean_theta, np.inf
    for signs in product((1.0, -1.0), repeat=2):
        flips = np.diag([signs[0], signs[1], 1.0])
        flips[2, 2] = np.linalg.det(cluster_axes @ flips @ model_axes.T)
        rotation = cluster_axes @ flips @ model_axes.T
        translation = cluster_centre - rotation @ model_centre
        rotation, translation = _rigid_icp(model_points, cluster, rotation, translation,
                                           settings.icp_iterations)
        start = mean_theta.copy()
        start[3:6] = vector_from_rotation(rotation @ rotation_from_vector(mean_theta[3:6]))
        start[0:3] = rotation @ mean_theta[0:3] + translation
        point_index, _ = _assign(marker_positions(model, markers, start), cluster, settings.gate_mm)
        if (point_index >= 0).sum() < 3:
            continue
        solver.reset()
        for _ in range(3):
            theta, effectors = solver.solve_frame(_targets(cluster, point_index))
            point_index, _ = _assign(effectors, cluster, settings.gate_mm)
            if (point_index >= 0).sum() < 3:
                break
        matched = point_index >= 0
        if matched.sum() < 3:
            continue
        residual = np.linalg.norm(effectors[matched] - cluster[point_index[matched]], axis=1).mean()
        score = residual + (len(markers.names) - matched.sum())
        if score < best_score:
            best_theta, best_score = theta, score
    return best_theta


def label_take(take: Take, model: HandModel, layout: MarkerLayout | str,
               initial_theta: np.ndarray | None = None,
               progress: Callable[[float], None] | None = None,
               cancelled: Callable[[], bool] | None = None,
               settings: TrackerSettings | None = None) -> LabelingResult:
    """Label the unlabelled points of ``take`` (``marker_positions (F,P,3)`` mm) with the markers of
    ``layout`` on one hand ``model``. ``initial_theta (26,)``: posture in the first frame (e.g. from
    a labelled first frame); None finds it automatically (:func:`initial_pose_from_points`).
    Raises InputError (empty take, too few points) and CancelledError (``cancelled()`` true)."""
    settings = settings or TrackerSettings()
    layout = load_layout(layout) if isinstance(layout, str) else layout
    markers = resolve_layout(model, layout)
    positions = np.asarray(take.marker_positions, dtype=float)
    frames, marker_count = len(positions), len(markers.names)
    if frames == 0:
        raise InputError("the take has no frames; nothing to label")
    if initial_theta is None:
        initial_theta = initial_pose_from_points(positions[0], model, markers, settings)
    elif np.shape(initial_theta) != (N_PARAMS,):
        raise InputError(f"the initial posture must have {N_PARAMS} parameters, got {np.shape(initial_theta)}")
    tracker = _Tracker(model, markers, settings, initial_theta)
    assignment = np.full((frames, marker_count), -1, dtype=np.int64)
    confidence = np.full((frames, marker_count), np.nan)
    joint_angles = np.full((frames, N_PARAMS), np.nan)
    residuals = np.full((frames, marker_count), np.nan)
    present = np.isfinite(positions).all(axis=2)
    ghost_points = present.copy()
    report_every = max(1, frames // 100)
    for frame in range(frames):
        if frame % report_every == 0:
            if cancelled is not None and cancelled():
                raise CancelledError("automatic labelling cancelled; the take is unchanged")
            if progress is not None:
                progress(frame / frames)
        columns = np.flatnonzero(present[frame])
        point_index, confidence[frame], joint_angles[frame], residuals[frame] = tracker.track(
            positions[frame, columns])
        assignment[frame] = np.where(point_index >= 0, columns[np.maximum(point_index, 0)], -1)
        ghost_points[frame, columns[point_index[point_index >= 0]]] = False
    if progress is not None:
        progress(1.0)
    return LabelingResult(assignment, confidence, joint_angles, residuals, ghost_points, list(markers.names))
