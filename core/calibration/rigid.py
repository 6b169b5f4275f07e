"""Rigid alignment with scale: Umeyama's closed-form similarity and an ICP built on it."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from handmocap.core.calibration.nearest import nearest_neighbours
from handmocap.core.errors import InputError

MAX_NORMAL_ANGLE_DEG = 60.0   # ICP rejects pairs whose normals disagree by more than this
REJECT_MEDIAN_FACTOR = 3.0    # ICP also rejects pairs farther than this many median pair distances
CONVERGENCE_MM = 1e-4         # ICP stops when the RMS changes by less than this between iterations


def similarity_transform(source: np.ndarray, target: np.ndarray, weights: np.ndarray | None = None,
                         with_scale: bool = True) -> tuple[float, np.ndarray, np.ndarray]:
    """The similarity ``(s, R (3,3), t (3,))`` minimising ``sum w |s R source + t - target|^2``.

    ``source``, ``target``: corresponding points (N,3) in mm, ``weights (N,)`` non-negative.
    Umeyama 1991: ``R`` is a proper rotation (det +1) even when the best orthogonal fit is a reflection;
    ``s = 1`` when ``with_scale`` is False.
    """
    source, target = np.asarray(source, dtype=np.float64), np.asarray(target, dtype=np.float64)
    if source.shape != target.shape or source.ndim != 2 or source.shape[1] != 3:
        raise InputError(f"point sets must both be (N,3); got {source.shape} and {target.shape}")
    weights = np.ones(len(source)) if weights is None else np.asarray(weights, dtype=np.float64)
    if np.count_nonzero(weights > 0) < 3:
        raise InputError("a similarity transform needs at least 3 weighted point pairs")
    weights = weights / weights.sum()
    source_mean, target_mean = weights @ source, weights @ target
    source_centred, target_centred = source - source_mean, target - target_mean
    covariance = (target_centred * weights[:, None]).T @ source_centred
    u, singular, vt = np.linalg.svd(covariance)
    signs = np.array([1.0, 1.0, np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0])
    rotation = (u * signs) @ vt
    scale = 1.0
    if with_scale:
        source_variance = float(weights @ np.einsum("na,na->n", source_centred, source_centred))
        if source_variance <= 0.0:
            raise InputError("the source points all coincide; scale is undefined")
        scale = float(singular @ signs) / source_variance
    return scale, rotation, target_mean - scale * rotation @ source_mean


def rigid_icp(source_points: np.ndarray, target_points: np.ndarray, source_normals: np.ndarray | None = None,
              target_normals: np.ndarray | None = None,
              initial: tuple[float, np.ndarray, np.ndarray] | None = None, iterations: int = 30,
              max_distance_mm: float = 10.0, with_scale: bool = True
              ) -> tuple[float, np.ndarray, np.ndarray, float]:
    """Align ``source_points (N,3)`` to ``target_points (M,3)`` (mm) by ICP with a similarity transform.

    Every iteration pairs each transformed source point with its closest target point, rejects pairs
    farther than ``max_distance_mm`` or than :data:`REJECT_MEDIAN_FACTOR` times the median pair distance
    (holes in the scan) and, when both normal sets are given, pairs whose normals disagree by more than
    :data:`MAX_NORMAL_ANGLE_DEG`; then solves :func:`similarity_transform` on the rest.
    ``initial`` is the starting ``(s, R, t)`` (identity by default). Returns ``(s, R, t, rms_mm)`` with
    the RMS distance of the accepted pairs at the returned transform.
    """
    scale, rotation, translation = initial if initial is not None else (1.0, np.eye(3), np.zeros(3))
    rotation, translation = np.asarray(rotation, dtype=np.float64), np.asarray(translation, dtype=np.float64)
    tree = cKDTree(target_points)
    min_cosine = np.cos(np.radians(MAX_NORMAL_ANGLE_DEG))
    previous_rms = np.inf
    for iteration in range(iterations + 1):
        moved = scale * source_points @ rotation.T + translation
        distances, nearest = nearest_neighbours(tree, moved, upper_bound_mm=max_distance_mm)
        accepted = np.isfinite(distances)
        if np.any(accepted):
            accepted &= distances <= REJECT_MEDIAN_FACTOR * np.median(distances[accepted])
        if source_normals is not None and target_normals is not None:
            paired_normals = target_normals[np.minimum(nearest, len(target_points) - 1)]
            agreement = np.einsum("na,na->n", source_normals @ rotation.T, paired_normals)
            accepted &= agreement >= min_cosine
        if np.count_nonzero(accepted) < 3:
            raise InputError(f"ICP found fewer than 3 point pairs closer than {max_distance_mm} mm; "
                             "improve the initial alignment")
        rms = float(np.sqrt(np.mean(distances[accepted] ** 2)))
        if iteration == iterations or previous_rms - rms < CONVERGENCE_MM:
            break
        previous_rms = rms
        scale, rotation, translation = similarity_transform(
            source_points[accepted], target_points[nearest[accepted]], with_scale=with_scale)
    return scale, rotation, translation, rms
