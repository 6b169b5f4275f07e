"""Metrics of a marker layout over a motion (journal "Motion reconstruction" results).

Conditioning and distances are taken at every ``step``-th frame of the motion; the reconstruction
error comes from layered IK of the layout's simulated marker positions on HELD-OUT grasp motions, the
global pose given (the journal's fixed forearm anchor marker), as mean and max over frames of the
per-frame mean vertex distance (mm).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.ik import IKSettings, solve_positions
from handmocap.core.layout.objective import RANK_TOLERANCE
from handmocap.core.model import (
    HandModel,
    MarkerLayout,
    marker_jacobian,
    marker_positions_batch,
    mean_vertex_error,
    resolve_layout,
)
from handmocap.core.model.skeleton import N_GLOBAL
from handmocap.core.prior import PosturePrior, load_default_prior
from handmocap.core.simulate import simulate_joint_angles

LABELLING_RISK_MM = 20.0   # two markers closer than this (two marker diameters plus noise) can be swapped


@dataclass(frozen=True)
class LayoutMetrics:
    """``mean_condition``: mean κ(JᵀJ) of the subspace Jacobian without translation (the objective's
    E_cond); ``worst_occluded_condition``: the largest such mean when any one marker is hidden, and
    ``worst_occluded_marker``; ``min_distance_mm`` and the ``closest_pair`` of marker names reaching it
    at ``closest_frame``; ``risk_fraction``: the share of frames in which two markers come closer than
    :data:`LABELLING_RISK_MM` (where a labeller can swap them); ``reconstruction_mean_mm`` /
    ``reconstruction_max_mm`` (NaN when not computed)."""

    mean_condition: float
    worst_occluded_condition: float
    worst_occluded_marker: str
    min_distance_mm: float
    closest_pair: tuple[str, str]
    closest_frame: int
    reconstruction_mean_mm: float
    reconstruction_max_mm: float
    risk_fraction: float = 0.0


def _condition(jacobian: np.ndarray) -> np.ndarray:
    """κ(JᵀJ) = (σ_max/σ_min)² of stacked Jacobians ``(..., rows, c)``; inf when rows < c or singular."""
    if jacobian.shape[-2] < jacobian.shape[-1]:
        return np.full(jacobian.shape[:-2], np.inf)
    singular = np.linalg.svd(jacobian, compute_uv=False)
    ratio_sq = singular[..., -1] ** 2 / singular[..., 0] ** 2
    return np.where(ratio_sq <= RANK_TOLERANCE, np.inf, 1.0 / np.maximum(ratio_sq, RANK_TOLERANCE))


def reconstruction_error(model: HandModel, layout: MarkerLayout, prior: PosturePrior | None = None,
                         n_frames: int = 1500, seed: int = 7, subspace_dims: int | None = None,
                         step: int = 5, progress: Callable[[float], None] | None = None,
                         cancelled: Callable[[], bool] | None = None) -> tuple[float, float]:
    """Mean and max (mm) per-vertex error of layered IK on a held-out grasp motion (global pose given);
    :class:`CancelledError` when ``cancelled()`` turns true."""
    prior = prior or load_default_prior()
    truth = simulate_joint_angles(n_frames, seed, motion="heldout")
    markers = resolve_layout(model, layout)
    targets = marker_positions_batch(model, markers, truth)
    result = solve_positions(targets, model, markers, prior,
                             IKSettings(method="layered", subspace_dims=subspace_dims),
                             progress=progress, cancelled=cancelled, global_poses=truth[:, :N_GLOBAL])
    return mean_vertex_error(model, result.joint_angles, truth, step)


def evaluate_layout(model: HandModel, layout: MarkerLayout, motion: np.ndarray, subspace_dims: int,
                    prior: PosturePrior | None = None, step: int = 10,
                    reconstruction_frames: int = 1500, progress: Callable[[float], None] | None = None,
                    cancelled: Callable[[], bool] | None = None) -> LayoutMetrics:
    """Metrics of ``layout`` over ``motion (F, 26)`` (every ``step``-th frame) with ``subspace_dims`` PCs;
    ``reconstruction_frames = 0`` skips the IK reconstruction (which reports ``progress``)."""
    motion = np.asarray(motion, dtype=float)
    if motion.ndim != 2 or len(motion) == 0:
        raise InputError("the motion set is empty: nothing to evaluate the layout on")
    prior = prior or load_default_prior()
    markers = resolve_layout(model, layout)
    n_markers = len(markers.names)
    basis = prior.components[:, :subspace_dims]
    frames = np.arange(0, len(motion), step)
    point_list, jacobian_list = [], []
    for frame in frames:
        frame_points, jacobian = marker_jacobian(model, markers, motion[frame])
        point_list.append(frame_points)
        jacobian_list.append(np.concatenate([jacobian[:, :, 3:N_GLOBAL], jacobian[:, :, N_GLOBAL:] @ basis], axis=2))
    points, jacobians = np.stack(point_list), np.stack(jacobian_list)         # (F', k, 3), (F', k, 3, c)
    columns = jacobians.shape[-1]
    mean_condition = float(_condition(jacobians.reshape(len(frames), -1, columns)).mean())
    occluded = [float(_condition(np.delete(jacobians, marker, axis=1).reshape(len(frames), -1, columns)).mean())
                for marker in range(n_markers)]
    worst = int(np.argmax(occluded))
    first, second = np.triu_indices(n_markers, k=1)
    distances = np.linalg.norm(points[:, first] - points[:, second], axis=2)  # (F', pairs)
    risk = float((distances.min(axis=1) < LABELLING_RISK_MM).mean()) if distances.size else 0.0
    closest, pair = np.unravel_index(np.argmin(distances), distances.shape) if distances.size else (0, 0)
    error = (reconstruction_error(model, layout, prior, reconstruction_frames, subspace_dims=subspace_dims,
                                  progress=progress, cancelled=cancelled)
             if reconstruction_frames > 0 else (float("nan"), float("nan")))
    return LayoutMetrics(
        mean_condition=mean_condition, worst_occluded_condition=occluded[worst],
        worst_occluded_marker=markers.names[worst],
        min_distance_mm=float(distances[closest, pair]) if distances.size else float("inf"),
        closest_pair=(markers.names[first[pair]], markers.names[second[pair]]) if distances.size else ("", ""),
        closest_frame=int(frames[closest]), reconstruction_mean_mm=error[0], reconstruction_max_mm=error[1],
        risk_fraction=risk)
