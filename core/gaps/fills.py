"""Gap fills of one marker trajectory; each returns the filled positions (length, 3) in mm.

Every fill takes the marker's trajectory ``(F, 3)`` mm (NaN = missing) and the gap ``start, length``
(0-based frames ``start .. start + length - 1``; the samples there are ignored, not required to be NaN)
and raises :class:`InputError` with the reason when its conditions are not met:

* linear — 1 observed frame on each side;
* spline — 2 on each side; a cubic spline through up to ``context`` observed frames on each side;
* pattern (Vicon Nexus "pattern fill") — 1 on each side and a donor marker observed from the frame
  before to the frame after the gap: the gap follows the donor, the offset to the donor is interpolated
  linearly between the two ends;
* rigid body — 1 on each side and at least 3 non-collinear donors observed from the frame before to the
  frame after: the marker's position in the donors' frame (Kabsch, per frame) is interpolated linearly;
* model (maycock2015 §III-C) — 2 on each side and IK joint angles solved without the gap: the joint
  angles that only the gap marker determines are interpolated by minimum squared angular acceleration
  with the two frames on each side fixed (C¹ at both ends; their angles and velocities from a line
  through up to 5 solved frames on each side), and the marker follows by forward kinematics.
"""

from __future__ import annotations

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.model import HandModel, MarkerSet, marker_positions_batch
from handmocap.core.model.kinematics import ANCESTOR

SPLINE_CONTEXT = 10
MODEL_CONTEXT = 2
#: solved frames on each side of a gap through which the model fill fits its end angles and velocities
MODEL_FIT = 5


def _validate_gap(trajectory: np.ndarray, start: int, length: int) -> None:
    if trajectory.ndim != 2 or trajectory.shape[1] != 3:
        raise InputError(f"a marker trajectory must have shape (frames, 3), got {trajectory.shape}")
    if length < 1 or start < 0 or start + length > len(trajectory):
        raise InputError(f"gap frames {start}..{start + length - 1} are outside the take "
                         f"(0..{len(trajectory) - 1})")


def observed_run(observed: np.ndarray, start: int, length: int) -> tuple[int, int]:
    """Number of consecutive observed frames right before ``start`` and right after the gap."""
    before = observed[:start][::-1]
    after = observed[start + length:]
    count_before = int(np.argmin(before)) if not before.all() else len(before)
    count_after = int(np.argmin(after)) if not after.all() else len(after)
    return count_before, count_after


def _require_sides(trajectory: np.ndarray, start: int, length: int, needed: int, method: str,
                   reach: int = 0) -> tuple[int, int]:
    """Observed frames right before and right after the gap, each counted up to ``max(needed, reach)``
    (only those frames are read, so the cost does not grow with the take); InputError below ``needed``."""
    _validate_gap(trajectory, start, length)
    reach = max(needed, reach)
    first = max(0, start - reach)
    window = np.isfinite(trajectory[first:start + length + reach]).all(axis=1)
    before, after = observed_run(window, start - first, length)
    if before < needed or after < needed:
        raise InputError(f"{method} fill needs {needed} observed frame(s) on each side of the gap "
                         f"(frames {start}..{start + length - 1}); the marker has {before} before and "
                         f"{after} after")
    return before, after


def _require_donors(donors: np.ndarray, start: int, length: int, method: str) -> None:
    """Donors ``(F, K, 3)`` must be observed from the frame before the gap to the frame after it."""
    span = donors[start - 1:start + length + 1]
    invalid = ~np.isfinite(span).all(axis=(0, 2))
    if invalid.any():
        raise InputError(f"{method} fill: donor(s) {', '.join(map(str, np.flatnonzero(invalid)))} are not "
                         f"observed through the gap (frames {start - 1}..{start + length}, ends included)")


def fill_linear(trajectory: np.ndarray, start: int, length: int) -> np.ndarray:
    """Straight line between the samples before and after the gap, (length, 3) mm."""
    _require_sides(trajectory, start, length, 1, "linear")
    weights = (np.arange(1, length + 1) / (length + 1))[:, None]
    return (1.0 - weights) * trajectory[start - 1] + weights * trajectory[start + length]


def fill_spline(trajectory: np.ndarray, start: int, length: int, context: int = SPLINE_CONTEXT) -> np.ndarray:
    """Cubic spline (not-a-knot) through up to ``context`` observed frames on each side, (length, 3) mm."""
    before, after = _require_sides(trajectory, start, length, 2, "spline", context)
    frames = np.concatenate([np.arange(start - min(before, context), start),
                             np.arange(start + length, start + length + min(after, context))])
    from scipy.interpolate import CubicSpline  # imported when first needed (start-up of the GUI and CLI)

    spline = CubicSpline(frames, trajectory[frames], axis=0)
    return spline(np.arange(start, start + length))


def fill_pattern(trajectory: np.ndarray, start: int, length: int, donor: np.ndarray) -> np.ndarray:
    """The donor's trajectory ``(F, 3)`` plus the offset to it interpolated linearly between the gap ends."""
    _require_sides(trajectory, start, length, 1, "pattern")
    _require_donors(donor[:, None, :], start, length, "pattern")
    end = start + length
    offsets = fill_linear(trajectory[start - 1:end + 1] - donor[start - 1:end + 1], 1, length)
    return donor[start:end] + offsets


def _kabsch_batch(source: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (N, 3, 3) and translations (N, 3) that best map ``source (K, 3)`` onto each ``targets[n] (K, 3)``."""
    source_centre = source.mean(axis=0)
    target_centres = targets.mean(axis=1)
    covariance = np.einsum("ki,nkj->nij", source - source_centre, targets - target_centres[:, None])
    u, _, vt = np.linalg.svd(covariance)
    signs = np.sign(np.linalg.det(np.einsum("nji,nkj->nik", vt, u)))
    signs[signs == 0] = 1.0
    correction = np.ones((len(targets), 3))
    correction[:, 2] = signs
    rotations = np.einsum("nji,nj,nkj->nik", vt, correction, u)
    return rotations, target_centres - rotations @ source_centre


def fill_rigid(trajectory: np.ndarray, start: int, length: int, donors: np.ndarray,
               min_spread_mm: float = 5.0) -> np.ndarray:
    """Rigid-body fill from ``donors (F, K, 3)`` (K ≥ 3, non-collinear), (length, 3) mm.

    The donors' pose per frame is the Kabsch fit of their positions in the frame before the gap; the
    marker's local position in that pose is interpolated linearly between the frames around the gap.
    """
    _require_sides(trajectory, start, length, 1, "rigid body")
    if donors.ndim != 3 or donors.shape[1] < 3:
        raise InputError(f"rigid body fill needs at least 3 donor markers, got "
                         f"{donors.shape[1] if donors.ndim == 3 else 0}")
    _require_donors(donors, start, length, "rigid body")
    end = start + length
    reference = donors[start - 1]
    spread = np.linalg.svd(reference - reference.mean(axis=0), compute_uv=False)
    if spread[1] < min_spread_mm:
        raise InputError(f"rigid body fill: the donors are (nearly) collinear (spread {spread[1]:.1f} mm < "
                         f"{min_spread_mm} mm), their pose is undetermined")
    rotations, translations = _kabsch_batch(reference, donors[start - 1:end + 1])
    ends = [0, -1]
    local_ends = np.einsum("nji,nj->ni", rotations[ends], trajectory[[start - 1, end]] - translations[ends])
    weights = (np.arange(1, length + 1) / (length + 1))[:, None]
    local = (1.0 - weights) * local_ends[0] + weights * local_ends[1]
    return np.einsum("nij,nj->ni", rotations[1:-1], local) + translations[1:-1]


def minimum_acceleration_interpolation(before: np.ndarray, after: np.ndarray, length: int) -> np.ndarray:
    """Values at ``length`` frames between two fixed frames on each side, minimising Σ‖θ''‖².

    ``before (2, P)`` are the two frames before the gap, ``after (2, P)`` the two after; the second
    differences over the whole span are minimised, a pentadiagonal SPD system (rows ``[1 -4 6 -4 1]``)
    solved per column. Its solution is the cubic through the four fixed frames: C¹ at both ends with
    the finite-difference velocities of the fixed frames. Returns (length, P).
    """
    known = np.zeros((length + 4, before.shape[1]))
    known[:2], known[-2:] = before, after
    stencil = (1.0, -4.0, 6.0, -4.0, 1.0)
    right_side = -sum((weight * known[shift:shift + length] for shift, weight in enumerate(stencil)),
                      np.zeros((length, before.shape[1])))
    banded = np.zeros((3, length))
    banded[0, 2:], banded[1, 1:], banded[2] = 1.0, -4.0, 6.0
    from scipy.linalg import solveh_banded

    return solveh_banded(banded, right_side)


def _unwrap_rotation_vectors(rotation_vectors: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) rad made continuous: each row is replaced by its equivalent
    ``r (1 - 2π/|r|)`` when that is closer to the previous row."""
    result = rotation_vectors.copy()
    for row in range(1, len(result)):
        angle = np.linalg.norm(result[row])
        if angle > 0.0:
            alternative = result[row] * (1.0 - 2.0 * np.pi / angle)
            if np.linalg.norm(alternative - result[row - 1]) < np.linalg.norm(result[row] - result[row - 1]):
                result[row] = alternative
    return result


def _boundary_angles(joint_angles: np.ndarray, start: int, end: int) -> np.ndarray:
    """IK angles ``(4, 26)`` at the :data:`MODEL_CONTEXT` frames on each side of the gap, from the line
    fitted (least squares, per parameter) through the up to :data:`MODEL_FIT` solved frames next to the
    gap on that side: IK noise would otherwise set the interpolation's end velocities. Rotation vectors
    are made continuous across both sides first."""
    sides = (np.arange(max(0, start - MODEL_FIT), start), np.arange(end, min(len(joint_angles), end + MODEL_FIT)))
    solved = [frames[np.isfinite(joint_angles[frames]).all(axis=1)] for frames in sides]
    values = joint_angles[np.concatenate(solved)].copy()
    values[:, 3:6] = _unwrap_rotation_vectors(values[:, 3:6])
    before, after = values[:len(solved[0])], values[len(solved[0]):]
    targets = (np.arange(start - MODEL_CONTEXT, start), np.arange(end, end + MODEL_CONTEXT))
    return np.vstack([np.polynomial.polynomial.polyval(target, np.polynomial.polynomial.polyfit(frames, side, 1)).T
                      for frames, side, target in zip(solved, (before, after), targets, strict=True)])


def affected_parameters(markers: MarkerSet, marker: int, observed_markers: np.ndarray) -> np.ndarray:
    """(26,) bool: the parameters that move ``marker`` but none of the ``observed_markers (M,) bool``
    (each marker judged by the joint carrying most of its skin weight)."""
    dominant = markers.influence_joints[np.arange(len(markers.names)), markers.influence_weights.argmax(axis=1)]
    moves = ANCESTOR[:, dominant]
    others = observed_markers.copy()
    others[marker] = False
    return moves[:, marker] & ~moves[:, others].any(axis=1)


def fill_model(positions: np.ndarray, start: int, length: int, marker: int, joint_angles: np.ndarray,
               model: HandModel, markers: MarkerSet) -> np.ndarray:
    """Model fill of marker ``marker`` of ``markers``, (length, 3) mm.

    ``positions (F, M, 3)`` mm are the measured markers in ``markers`` order; ``joint_angles (F, 26)``
    come from IK solved with the gap missing. The parameters that move the marker but no marker
    observed through the whole gap are interpolated by :func:`minimum_acceleration_interpolation`
    from the two frames on each side (smoothed by :func:`_boundary_angles`); the others keep their IK
    values. Those others shift when the
    marker drops out of the IK, so at the frames next to the gap they are extrapolated linearly from
    the gap frames; the forward-kinematics positions are then shifted by the residual (measured − model)
    at those two frames, interpolated linearly, so the fill joins the measured samples without a jump.
    """
    if positions.ndim != 3 or positions.shape[1:] != (len(markers.names), 3):
        raise InputError(f"model fill: positions must have shape (frames, {len(markers.names)}, 3), "
                         f"got {positions.shape}")
    if joint_angles.shape != (len(positions), 26):
        raise InputError(f"model fill: joint angles must have shape ({len(positions)}, 26), "
                         f"got {joint_angles.shape}")
    trajectory = positions[:, marker]
    _require_sides(trajectory, start, length, MODEL_CONTEXT, "model")
    end = start + length
    context = np.r_[start - MODEL_CONTEXT:start, end:end + MODEL_CONTEXT]
    if not np.isfinite(joint_angles[context]).all():
        raise InputError(f"model fill: no IK solution in the frames around the gap "
                         f"({start - MODEL_CONTEXT}..{end + MODEL_CONTEXT - 1})")
    observed_through = np.isfinite(positions[start:end]).all(axis=(0, 2))
    affected = affected_parameters(markers, marker, observed_through)
    angles = joint_angles[start - 1:end + 1].copy()
    if not np.isfinite(angles[:, ~affected]).all():
        raise InputError(f"model fill: no IK solution during the gap (frames {start}..{end - 1})")
    inner = angles[1:-1, ~affected]
    steps = inner[[0, -1]] - inner[[1, -2]] if length >= 2 else np.zeros((2, inner.shape[1]))
    angles[np.ix_(np.array([0, -1]), np.flatnonzero(~affected))] = inner[[0, -1]] + steps
    boundary = _boundary_angles(joint_angles, start, end)
    angles[1:-1, affected] = minimum_acceleration_interpolation(boundary[:2, affected], boundary[2:, affected],
                                                                length)
    kinematic = marker_positions_batch(model, markers.subset(np.array([marker])), angles)[:, 0]
    residuals = trajectory[[start - 1, end]] - kinematic[[0, -1]]
    weights = (np.arange(1, length + 1) / (length + 1))[:, None]
    return kinematic[1:-1] + (1.0 - weights) * residuals[0] + weights * residuals[1]

