"""Automatic initialisation of a scene's models on one frame (Maycock et al. 2015 §III-A, Fig. 2).

Euclidean clustering (single linkage cut above the models' own largest marker gap); every model
(hands and objects) is aligned to every cluster by its PCA frame with the four proper sign
combinations of the axes, the oriented-bounding-box scale, rigid ICP (Hungarian pairs + Kabsch), then
Hungarian assignment + IK (hands) or Kabsch (objects). Each (model, cluster) pair is scored by
eq. 2, ``E + αD``: E the mean distance (mm) of the matched markers, D the number of markers left
unmatched on either side (model markers without a point, cluster points without a marker). Pairs
are taken greedily by increasing score; a right hand and a left hand are told apart by this score
(a mirrored hand fits worse), never by names.

Assumptions (as the paper's): in the initialisation frame each model forms its own cluster (nothing
closer to it than the cut), most of its markers are visible, few ghosts sit in the cluster, and a
hand is not far from the mean posture of the prior.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import product

import numpy as np
from numba import njit

from handmocap.core.ik import kabsch
from handmocap.core.labelling.models import HandTracker, RigidTrack, SceneSettings, Track, pose_matrix
from handmocap.core.model.kinematics import rotation_from_vector, vector_from_rotation

LINK_MARGIN = 1.2
"""The clustering cut is at least this times a model's own largest single-linkage gap."""
SCALE_RANGE = (0.75, 1.33)
"""OBB scale factors outside this range reject a (model, cluster) pair (a different object)."""


RETRY_RESIDUAL_MM = 2.0
"""A hand fit whose mean residual (mm) stays above this is tried again from other starting postures."""
RETRY_COMPONENTS = 2
RETRY_STDDEVS = 1.5
"""The other starting postures: ± this many standard deviations along the prior's first components."""
REACQUIRE_POINTS = 16
"""At most this many points nearest to a lost object's predicted centre are tried for re-acquiring it."""
HAND_HYPOTHESES = 4
"""At most this many different labellings of a hand fitted to a cluster are kept as hypotheses."""
AMBIGUOUS_RATIO = 1.5
"""A re-acquisition is refused when another correspondence of as many markers fits within this factor."""


Fit = tuple[float, np.ndarray, int, float, np.ndarray]
"""A model fitted to points: (eq. 2 score, state, matched marker count, mean residual mm, point index per
marker (K,), -1 unmatched)."""


@dataclass
class Candidate:
    """A model fitted to a cluster: eq. 2 score, state, matched marker count, mean residual (mm)."""

    track_index: int
    cluster_index: int
    score: float
    state: np.ndarray   # hand θ (26,) or object pose (4,4)
    matched: int
    residual_mm: float
    point_index: np.ndarray   # (K,) index into the frame's points, -1 unmatched
    #: other fits of the same track to the same cluster, as (state, point index (K,)), best first
    alternatives: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)


def model_points(track: Track) -> np.ndarray:
    """The model's markers in its reference configuration (hands: mean posture of the prior) (K,3)."""
    if isinstance(track, HandTracker):
        return track.effectors(track.mean_theta)
    assert isinstance(track, RigidTrack)
    return track.local


def own_gap(track: Track) -> float:
    """The largest single-linkage gap (mm) between the model's own markers (0 for fewer than 2)."""
    points = model_points(track)
    from scipy.cluster.hierarchy import linkage  # imported when first needed: start-up of the GUI and CLI

    return float(linkage(points, method="single")[:, 2].max()) if len(points) >= 2 else 0.0


def cluster_cut(tracks: list[Track], settings: SceneSettings) -> float:
    """Single-linkage cut (mm): the settings' floor or the largest own gap of a hand × margin (so each hand
    is one cluster; models must stand farther apart than this in the initialisation frame). Objects do not
    widen it: an object wider than the cut (:func:`is_spread_object`, e.g. a guitar with markers on its
    body and its head) is found by its own geometry among all points (:func:`find_spread_object`), a
    compact one as a cluster of its own, so a large prop never merges the hands into one cluster."""
    cut = settings.cluster_cut_mm
    for track in tracks:
        if isinstance(track, HandTracker):
            cut = max(cut, LINK_MARGIN * own_gap(track))
    return float(cut)


def is_spread_object(track: Track, cut_mm: float) -> bool:
    """True for a rigid object whose own markers stand farther apart than the clustering cut."""
    return isinstance(track, RigidTrack) and LINK_MARGIN * own_gap(track) > cut_mm


def find_spread_object(track: RigidTrack, points: np.ndarray, settings: SceneSettings) -> Candidate | None:
    """A spread object's fit among all ``points (N,3)`` by its distance matrix (:func:`best_correspondence`),
    as an initial candidate (cluster index -1), or None when it is not there or is ambiguous."""
    least = max(3, int(np.ceil(settings.init_min_share * track.count)))
    found = best_correspondence(track, points, np.arange(len(points)), np.eye(4), settings, least)
    if found is None:
        return None
    index, pose, residuals = found
    observed = index >= 0
    residual = float(residuals[observed].mean())
    score, _, matched = _score(track.effectors(pose), points, index, settings.alpha, cluster_size=0)
    return Candidate(-1, -1, score, pose, matched, residual, index)


def clusters_of(points: np.ndarray, cut_mm: float) -> list[np.ndarray]:
    """Index arrays of the single-linkage clusters of ``points (N,3)`` cut at ``cut_mm``, ≥ 3 points each."""
    if len(points) < 3:
        return []
    from scipy.cluster.hierarchy import fcluster, linkage

    labels = fcluster(linkage(points, method="single"), t=cut_mm, criterion="distance")
    groups = [np.flatnonzero(labels == label) for label in np.unique(labels)]
    return [group for group in groups if len(group) >= 3]


def _principal_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centroid (3,), principal axes as columns (3,3) by decreasing variance, and the extents (3,)
    of the oriented bounding box along them."""
    centre = points.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((points - centre).T))
    axes = vectors[:, ::-1]
    projected = (points - centre) @ axes
    return centre, axes, np.ptp(projected, axis=0)


@njit(cache=True)
def pair_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distances (K,N) mm between ``a (K,3)`` and ``b (N,3)``."""
    result = np.empty((a.shape[0], b.shape[0]))
    for i in range(a.shape[0]):
        for j in range(b.shape[0]):
            dx, dy, dz = a[i, 0] - b[j, 0], a[i, 1] - b[j, 1], a[i, 2] - b[j, 2]
            result[i, j] = np.sqrt(dx * dx + dy * dy + dz * dz)
    return result


@njit(cache=True)
def nearest_within(distances: np.ndarray, gate: np.ndarray) -> tuple[np.ndarray, bool]:
    """Per row of ``distances (K,N)`` the nearest column closer than the row's ``gate (K,)`` (-1 none),
    and whether no column is the nearest of two rows."""
    rows, columns = distances.shape
    nearest = np.full(rows, -1, dtype=np.int64)
    owner = np.full(columns, -1, dtype=np.int64)
    unique = True
    for i in range(rows):
        best = gate[i]
        for j in range(columns):
            if distances[i, j] < best:
                best = distances[i, j]
                nearest[i] = j
        if nearest[i] >= 0:
            if owner[nearest[i]] >= 0:
                unique = False
            owner[nearest[i]] = i
    return nearest, unique


def gated_assignment(effectors: np.ndarray, points: np.ndarray, gate: np.ndarray | float,
                     distances: np.ndarray | None = None) -> np.ndarray:
    """Hungarian assignment of ``points (N,3)`` to ``effectors (K,3)`` with a "missing" option at
    ``gate`` mm (scalar or per effector (K,)); returns the point index per effector (K,), -1 missing.
    ``distances (K,N)``: the pair distances when already computed.

    Clipping every cost at the row's gate and solving the rectangular problem is equivalent to the
    augmented matrix with a missing column per effector: a pair at the clip value costs what missing
    costs, and is reported missing."""
    chosen = np.full(len(effectors), -1, dtype=np.int64)
    if not len(points) or not len(effectors):
        return chosen
    gate = np.asarray(gate, dtype=float)
    gate = np.full(len(effectors), float(gate)) if gate.ndim == 0 else gate
    if distances is None:
        distances = pair_distances(np.ascontiguousarray(effectors), np.ascontiguousarray(points))
    nearest, unique = nearest_within(distances, gate)
    if unique:
        # every row's own minimum, no two rows on one point: the sum of the row minima is a lower
        # bound of any assignment's cost and this one reaches it, so it is optimal (no Hungarian needed)
        return nearest
    near = distances < gate[:, None]
    row_any, column_any = near.any(axis=1), near.any(axis=0)
    if not row_any.any():
        return chosen
    rows, columns = np.flatnonzero(row_any), np.flatnonzero(column_any)
    cost = np.minimum(distances[rows[:, None], columns[None, :]], gate[rows, None])
    from scipy.optimize import linear_sum_assignment  # imported when first needed (start-up)

    assigned_rows, assigned_columns = linear_sum_assignment(cost)
    keep = near[rows[assigned_rows], columns[assigned_columns]]
    chosen[rows[assigned_rows[keep]]] = columns[assigned_columns[keep]]
    return chosen


def _icp(source: np.ndarray, target: np.ndarray, rotation: np.ndarray, translation: np.ndarray,
         iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Rigid ICP of ``source (K,3)`` onto ``target (N,3)``: Hungarian pairs, then Kabsch."""
    from scipy.optimize import linear_sum_assignment  # imported when first needed (start-up)

    for _ in range(iterations):
        moved = source @ rotation.T + translation
        rows, columns = linear_sum_assignment(np.linalg.norm(moved[:, None] - target[None], axis=2))
        if len(rows) < 3:
            break
        new_rotation, new_translation = kabsch(source[rows], target[columns])
        if np.allclose(new_rotation, rotation, atol=1e-9) and np.allclose(new_translation, translation, atol=1e-6):
            break
        rotation, translation = new_rotation, new_translation
    return rotation, translation


def _alignments(source: np.ndarray, target: np.ndarray, iterations: int
                ) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """(OBB scale, rotation, translation) per proper sign combination of the PCA axes, after ICP
    of the OBB-scaled source onto the target."""
    source_centre, source_axes, source_extents = _principal_frame(source)
    target_centre, target_axes, target_extents = _principal_frame(target)
    scale = float(np.sqrt(target_extents[:2].prod() / max(source_extents[:2].prod(), 1e-9)))
    scaled = source_centre + (source - source_centre) * scale
    results = []
    for signs in product((1.0, -1.0), repeat=2):
        flips = np.diag([signs[0], signs[1], 1.0])
        flips[2, 2] = np.linalg.det(target_axes @ flips @ source_axes.T)
        rotation = target_axes @ flips @ source_axes.T
        translation = target_centre - rotation @ source_centre
        rotation, translation = _icp(scaled, target, rotation, translation, iterations)
        # back to the unscaled model: moved = R (c + s (p - c)) + t = s R p + t'
        translation = translation + rotation @ (source_centre * (1.0 - scale))
        results.append((scale, rotation, translation))
    return results


def _assign_and_solve(track: Track, cluster: np.ndarray, state: np.ndarray, settings: SceneSettings, rounds: int = 3
                      ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Alternate the gated Hungarian assignment of ``cluster (N,3)`` to the track's markers and the
    track's solve, from ``state``; returns (state, effectors (K,3) or None when fewer than 3 markers
    ever matched, point index per marker (K,), -1 unmatched)."""
    point_index = gated_assignment(track.effectors(state), cluster, settings.gate_mm)
    effectors = None
    for _ in range(rounds):
        if (point_index >= 0).sum() < 3:
            break
        targets = np.where((point_index >= 0)[:, None], cluster[np.maximum(point_index, 0)], np.nan)
        state, effectors = track.solve(targets, point_index >= 0, state)
        point_index = gated_assignment(effectors, cluster, settings.gate_mm)
    return state, effectors, point_index


def _score(effectors: np.ndarray, cluster: np.ndarray, point_index: np.ndarray, alpha: float,
           cluster_size: int | None = None) -> tuple[float, float, int]:
    """Eq. 2 of a fit: (E + αD, E, matched count); the first ``cluster_size`` points of ``cluster`` are
    the cluster (the rest: stray points offered to unmatched markers, counted only when matched)."""
    matched = point_index >= 0
    count = int(matched.sum())
    if count < 3:
        return np.inf, np.inf, count
    residual = float(np.linalg.norm(effectors[matched] - cluster[point_index[matched]], axis=1).mean())
    size = len(cluster) if cluster_size is None else cluster_size + int((point_index >= cluster_size).sum())
    unmatched = (len(effectors) - count) + (size - count)
    return residual + alpha * unmatched, residual, count


def _posture_starts(track: HandTracker) -> list[np.ndarray]:
    """Finger postures (26,) to start a fit from other than the prior's mean: the mean moved
    ±:data:`RETRY_STDDEVS` standard deviations along each of the prior's first
    :data:`RETRY_COMPONENTS` principal components (clipped to the joint limits)."""
    prior, solver = track.solver.prior, track.solver
    starts = []
    for component in range(min(RETRY_COMPONENTS, prior.n_components)):
        for sign in (1.0, -1.0):
            theta = track.mean_theta.copy()
            posture = prior.mean + sign * RETRY_STDDEVS * prior.stddev[component] * prior.components[:, component]
            theta[6:] = np.clip(posture, solver.angle_lower, solver.angle_upper)
            starts.append(theta)
    return starts


def fit_hand(track: HandTracker, cluster: np.ndarray, settings: SceneSettings, strays: np.ndarray | None = None
             ) -> list[Fit]:
    """Eq. 2 fits of a hand to ``cluster (N,3)``, best first: (score, θ, matched, residual, point index
    (K,)), at most :data:`HAND_HYPOTHESES` with different labellings (the runners-up are hypotheses the
    labeller tracks over a window before it decides: a finger shift or a flipped hand fits a single
    frame almost as well). ``strays (S,3)``: points of clusters too small for any model (e.g. an
    abducted thumb's two markers farther than the cut from the hand), offered to unmatched markers by
    the completion step; point indices ≥ N refer to them. The fit starts from the prior's mean posture
    in each PCA alignment; when the best residual stays above :data:`RETRY_RESIDUAL_MM` (a local
    minimum, e.g. the markers taken one finger over), it starts again from the postures of
    :func:`_posture_starts`. Empty when nothing fits."""
    source = model_points(track)
    alignments = _alignments(source, cluster, settings.icp_iterations)
    extended = cluster if strays is None or not len(strays) else np.concatenate([cluster, strays])
    fits: list[Fit] = []
    for postures in ([track.mean_theta], _posture_starts(track)):
        if fits and min(fits, key=lambda fit: fit[0])[3] <= RETRY_RESIDUAL_MM:
            break
        for posture, (_scale, rotation, translation) in product(postures, alignments):
            fit = _fit_from(track, cluster, extended, settings, posture, rotation, translation)
            if fit is not None and np.isfinite(fit[0]):
                fits.append(fit)
    distinct: list[Fit] = []
    for fit in sorted(fits, key=lambda fit: fit[0]):
        if not any(np.array_equal(fit[4], kept[4]) for kept in distinct):
            distinct.append(fit)
    return distinct[:HAND_HYPOTHESES]


def _fit_from(track: HandTracker, cluster: np.ndarray, extended: np.ndarray, settings: SceneSettings,
              posture: np.ndarray, rotation: np.ndarray, translation: np.ndarray) -> Fit | None:
    """Fit of the hand starting from ``posture (26,)`` moved by the alignment ``rotation``,
    ``translation``: alternate Hungarian assignment and IK, then complete; the tuple of
    :func:`fit_hand`, or None when fewer than 3 markers match."""
    start = posture.copy()
    start[3:6] = vector_from_rotation(rotation @ rotation_from_vector(posture[3:6]))
    start[0:3] = rotation @ posture[0:3] + translation
    theta, effectors, point_index = _assign_and_solve(track, cluster, start, settings)
    if effectors is None:
        return None
    score, residual, count = _score(effectors, cluster, point_index, settings.alpha)
    theta, effectors, point_index, score, residual, count = _complete(
        track, extended, len(cluster), theta, effectors, point_index, (score, residual, count), settings)
    return score, theta, count, residual, point_index


def _complete(track: HandTracker, cluster: np.ndarray, cluster_size: int, theta: np.ndarray, effectors: np.ndarray,
              point_index: np.ndarray, scored: tuple[float, float, int], settings: SceneSettings
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float, int]:
    """Offer the cluster points no marker took to the unmatched markers within
    ``init_completion_gate_mm`` (a digit posed far from the prior's mean, e.g. an abducted thumb),
    solve the IK with them, and keep the result when eq. 2 improves."""
    score, residual, count = scored
    for _ in range(2):
        unmatched = np.flatnonzero(point_index < 0)
        free = np.setdiff1d(np.arange(len(cluster)), point_index[point_index >= 0])
        if not len(unmatched) or not len(free):
            break
        extra = gated_assignment(effectors[unmatched], cluster[free], settings.init_completion_gate_mm)
        if not (extra >= 0).any():
            break
        trial = point_index.copy()
        trial[unmatched[extra >= 0]] = free[extra[extra >= 0]]
        targets = np.where((trial >= 0)[:, None], cluster[np.maximum(trial, 0)], np.nan)
        trial_theta, trial_effectors = track.solve(targets, trial >= 0, theta)
        trial_theta, trial_effectors = track.solve(targets, trial >= 0, trial_theta)
        trial_index = gated_assignment(trial_effectors, cluster, settings.gate_mm)
        trial_score, trial_residual, trial_count = _score(trial_effectors, cluster, trial_index, settings.alpha,
                                                          cluster_size)
        if trial_score >= score:
            break
        theta, effectors, point_index = trial_theta, trial_effectors, trial_index
        score, residual, count = trial_score, trial_residual, trial_count
    return theta, effectors, point_index, score, residual, count


def fit_object(track: RigidTrack, cluster: np.ndarray, settings: SceneSettings
               ) -> Fit:
    """Best eq. 2 fit of a rigid object to ``cluster (N,3)``: (score, pose (4,4), matched, residual,
    point index (K,)). The OBB scale must be plausible (the primitive's size), the fit is rigid."""
    best = (np.inf, np.eye(4), 0, np.inf, np.full(track.count, -1))
    if len(cluster) > 3 * track.count + 3:
        return best
    for scale, rotation, translation in _alignments(track.local, cluster, settings.icp_iterations):
        if not SCALE_RANGE[0] <= scale <= SCALE_RANGE[1]:
            continue
        pose = pose_matrix(rotation, translation + (scale - 1.0) * rotation @ track.local.mean(axis=0))
        pose, _effectors, point_index = _assign_and_solve(track, cluster, pose, settings)
        score, residual, count = _score(track.effectors(pose), cluster, point_index, settings.alpha)
        if score < best[0]:
            best = (score, pose, count, residual, point_index)
    return best


def rigid_correspondences(local: np.ndarray, points: np.ndarray, tolerance_mm: float, min_matched: int = 3
                          ) -> list[np.ndarray]:
    """Every injective correspondence of at least ``min_matched`` markers of ``local (K,3)`` to
    ``points (N,3)`` whose pair distances all agree with the markers' within ``tolerance_mm``; each
    is the point index per marker (K,), -1 unmatched. Depth-first over the markers with pruning by the
    distance matrices (cheap for the K ≤ 8 markers of an object and a dozen points)."""
    count, size = len(local), len(points)
    if size < min_matched or count < min_matched:
        return []
    model = pair_distances(local, local)
    measured = pair_distances(points, points)
    agree = np.abs(measured[None, None] - model[:, :, None, None]) < tolerance_mm     # (K,K,N,N)
    found: list[np.ndarray] = []
    index = np.full(count, -1, dtype=np.int64)
    used = np.zeros(size, dtype=bool)

    def descend(marker: int, matched: int) -> None:
        if marker == count:
            if matched >= min_matched:
                found.append(index.copy())
            return
        allowed = ~used
        for other in range(marker):
            if index[other] >= 0:
                allowed &= agree[marker, other, :, index[other]]
        for point in np.flatnonzero(allowed):
            index[marker], used[point] = point, True
            descend(marker + 1, matched + 1)
            index[marker], used[point] = -1, False
        if matched + count - marker - 1 >= min_matched:
            descend(marker + 1, matched)

    descend(0, 0)
    return found


def reacquire_object(track: RigidTrack, points: np.ndarray, start: np.ndarray, settings: SceneSettings
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Re-acquire a rigid object from ``points (N,3)`` (the frame's points it may take) near its pose
    ``start (4,4)``: the :data:`REACQUIRE_POINTS` points nearest it, then :func:`best_correspondence`.
    Returns the point index per marker (K,), the pose and the residuals (K,) mm, or None."""
    if len(points) < 3 or track.count < 3:
        return None
    centre = start[:3, :3] @ track.local.mean(axis=0) + start[:3, 3]
    distance = np.sqrt(((points - centre) ** 2).sum(axis=1))
    near = np.flatnonzero(distance < track.search_radius())
    if len(near) < 3:
        return None
    near = near[np.argsort(distance[near])[:REACQUIRE_POINTS]]
    return best_correspondence(track, points, near, start, settings)


def best_correspondence(track: RigidTrack, points: np.ndarray, near: np.ndarray, start: np.ndarray,
                        settings: SceneSettings, min_matched: int = 3
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Of the points ``near`` (indices into ``points (N,3)``), the correspondence of most markers, then least
    RMS residual, whose rigid fit reaches each matched point within ``reacquire_fit_mm``
    (:func:`rigid_correspondences`): the point index per marker (K,) into ``points``, the pose (4,4) and the
    residuals (K,) mm; None when nothing fits or two different correspondences fit about equally well (a
    symmetric marker set)."""
    candidates = points[near]
    fits = []
    for index in rigid_correspondences(track.local, candidates, 2.0 * settings.reacquire_fit_mm, min_matched):
        observed = index >= 0
        targets = np.where(observed[:, None], candidates[np.maximum(index, 0)], np.nan)
        pose, effectors = track.solve(targets, observed, start)
        residuals = np.sqrt(((effectors - targets) ** 2).sum(axis=1))
        if residuals[observed].max() <= settings.reacquire_fit_mm:
            rms = float(np.sqrt((residuals[observed] ** 2).mean()))
            fits.append((-int(observed.sum()), rms, index, pose, residuals))
    if not fits:
        return None
    fits.sort(key=lambda fit: (fit[0], fit[1]))
    best = fits[0]
    for other in fits[1:]:
        if other[0] != best[0]:
            break
        if other[1] < AMBIGUOUS_RATIO * best[1] + 0.05:
            return None
    index = np.where(best[2] >= 0, near[np.maximum(best[2], 0)], -1)
    return index, best[3], best[4]


def initialise_frame(tracks: list[Track], candidates_for: list[int], points: np.ndarray,
                     settings: SceneSettings, cut_mm: float) -> list[Candidate]:
    """Fit the tracks ``candidates_for`` (indices into ``tracks``) to the clusters of ``points (N,3)``;
    returns the accepted fits, at most one per track and per cluster (greedy on eq. 2)."""
    candidates: list[Candidate] = []
    free = np.ones(len(points), dtype=bool)
    for track_index in candidates_for:
        track = tracks[track_index]
        if not is_spread_object(track, cut_mm):
            continue
        assert isinstance(track, RigidTrack)
        found = find_spread_object(track, points, settings)
        if found is not None:
            found.track_index, found.cluster_index = track_index, -1 - len(candidates)
            free[found.point_index[found.point_index >= 0]] = False
            candidates.append(found)
    remaining = np.flatnonzero(free)
    clusters = [remaining[members] for members in clusters_of(points[remaining], cut_mm)]
    in_cluster = ~free
    for members in clusters:
        in_cluster[members] = True
    strays = np.flatnonzero(~in_cluster)
    for track_index in candidates_for:
        track = tracks[track_index]
        if is_spread_object(track, cut_mm):
            continue
        for cluster_index, members in enumerate(clusters):
            cluster = points[members]
            if len(cluster) < max(3, int(np.ceil(settings.init_min_share * track.count))):
                continue
            least = max(3, int(np.ceil(settings.init_min_share * track.count)))
            if isinstance(track, HandTracker):
                fits = fit_hand(track, cluster, settings, points[strays])
            else:
                assert isinstance(track, RigidTrack)
                fits = [fit_object(track, cluster, settings)]
            fits = [fit for fit in fits if np.isfinite(fit[0]) and fit[3] <= settings.init_max_residual_mm
                    and fit[2] >= least]
            if not fits:
                continue
            reachable = np.concatenate([members, strays])
            labelled = [(fit[1], np.where(fit[4] >= 0, reachable[np.maximum(fit[4], 0)], -1)) for fit in fits]
            score, state, matched, residual, _ = fits[0]
            candidates.append(Candidate(track_index, cluster_index, score, state, matched, residual,
                                        labelled[0][1], labelled[1:]))
    accepted: list[Candidate] = []
    used_tracks: set[int] = set()
    used_clusters: set[int] = set()
    for candidate in sorted(candidates, key=lambda c: c.score):
        if candidate.track_index in used_tracks or candidate.cluster_index in used_clusters:
            continue
        taken = {int(index) for fit in accepted for index in fit.point_index if index >= 0}
        shared = np.isin(candidate.point_index, list(taken)) & (candidate.point_index >= 0)
        if shared.any():       # a stray point already given to another model
            candidate.point_index = np.where(shared, -1, candidate.point_index)
        accepted.append(candidate)
        used_tracks.add(candidate.track_index)
        used_clusters.add(candidate.cluster_index)
    return accepted
