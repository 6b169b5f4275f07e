"""Subject calibration: bone lengths and marker offsets from labelled frames (Zhao et al. 2012, eq. 2).

Minimises over the poses ``θ_n`` of N calibration frames, the bone scales ``s`` and the marker offsets
``d_i``

    Σ_n Σ_i ‖f(p_i + d_i; s, θ_n) − t_n^i‖²  +  w_s² ‖s − 1‖²  +  w_d² Σ_i ‖d_i‖²

with Levenberg–Marquardt (squared norms, as eq. 2; the two small priors fix the directions the data
leave free, e.g. a marker offset along a bone versus that bone's length). ``s`` holds one factor per
joint offset of the 16-joint skeleton (15: the wrist→knuckle "metacarpal" vector and the two
phalanges before the distal joint of each digit); ``d_i`` moves marker i in the rest pose (mm) and
the marker follows its skin influences. The normal equations are solved by the Schur complement of
the per-frame pose blocks, so the cost grows linearly with N. Jacobians are analytic (the pose part
is :func:`core.model.kinematics.points_and_jacobian_kernel`; a scale moves every joint after it by
``R_parent · offset``; an offset moves its marker by ``Σ_k w_k R_k R_rest,kᵀ``).

The result is a new :class:`HandModel` (joints moved, mesh vertices carried with their skin weights)
and its :class:`MarkerSet` (same anchors and weights, local points shifted by the offsets).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.ik import IKSettings, solve_positions
from handmocap.core.model import N_PARAMS, HandModel, MarkerLayout, MarkerSet, resolve_layout
from handmocap.core.model.kinematics import (
    ANCESTOR,
    forward_kinematics_kernel,
    points_and_jacobian_kernel,
    rotation_from_vector,
    skinned_points_kernel,
    vector_from_rotation,
)
from handmocap.core.model.skeleton import JOINT_PARENTS, N_JOINTS, Skeleton, default_joint_limits

SCALE_PRIOR = 10.0
"""w_s: mm of residual-equivalent cost per unit of bone scale change (a 10 % change costs 1 mm)."""
OFFSET_PRIOR = 0.5
"""w_d: residual-equivalent cost per mm of marker offset (a 10 mm move costs 5 mm)."""
SCALE_LIMITS = (0.7, 1.4)

#: DESCENDANT[j, k]: joint k is j or comes after j in j's digit chain
DESCENDANT = np.zeros((N_JOINTS, N_JOINTS), dtype=bool)
for _joint in range(N_JOINTS):
    for _other in range(N_JOINTS):
        _walk = _other
        while _walk >= 0:
            if _walk == _joint:
                DESCENDANT[_joint, _other] = True
                break
            _walk = JOINT_PARENTS[_walk]
SCALED_JOINTS = np.arange(1, N_JOINTS)


def _select_frames(observed: np.ndarray, max_frames: int) -> np.ndarray:
    """Up to ``max_frames`` well-observed frames spread over the window (indices into ``observed (F,M)``)."""
    counts = observed.sum(axis=1)
    good = np.flatnonzero(counts >= max(3, 0.8 * counts.max()))
    if len(good) <= max_frames:
        return good
    return good[np.linspace(0, len(good) - 1, max_frames).round().astype(int)]


class _Problem:
    """Residuals and Jacobian blocks of the calibration problem for the current parameters."""

    def __init__(self, model: HandModel, markers: MarkerSet, targets: np.ndarray):
        self.model, self.markers, self.targets = model, markers, targets
        self.observed = np.isfinite(targets).all(axis=2)                    # (N,M)
        self.clean = np.where(self.observed[:, :, None], targets, 0.0)
        chain = model.chain
        self.relative_rest, self.offsets0, self.abduction = chain.relative_rest, chain.offsets, chain.abduction_sign
        self.rest_rotations = model.skeleton.rest_rotations
        joints, weights = markers.influence_joints, markers.influence_weights
        self.joints, self.weights = joints, weights
        # per marker: Σ_k w_k [influence k is j or after j], (M,16)
        self.reach = np.einsum("mk,jmk->mj", weights, DESCENDANT[:, joints])
        self.rest_t = np.transpose(self.rest_rotations[joints], (0, 1, 3, 2))   # (M,4,3,3) R_restᵀ

    def local_points(self, offsets: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(self.markers.local_points + np.einsum("mkab,mb->mka", self.rest_t, offsets))

    def joint_offsets(self, scales: np.ndarray) -> np.ndarray:
        full = np.ones(N_JOINTS)
        full[SCALED_JOINTS] = scales
        return np.ascontiguousarray(self.offsets0 * full[:, None])

    def residuals(self, thetas: np.ndarray, scales: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """Residuals (N,M,3) of the poses ``thetas (N,26)``: target − model, 0 where unobserved."""
        joint_offsets, local = self.joint_offsets(scales), self.local_points(offsets)
        residuals = np.zeros((len(self.observed), self.observed.shape[1], 3))
        mask = self.observed[:, :, None].astype(float)
        for n, theta in enumerate(thetas):
            rotations, positions, _, _ = forward_kinematics_kernel(theta, self.relative_rest, joint_offsets,
                                                                   self.abduction)
            points = skinned_points_kernel(rotations, positions, self.joints, self.weights, local)
            residuals[n] = (self.clean[n] - points) * mask[n]
        return residuals

    def linearise(self, thetas: np.ndarray, scales: np.ndarray, offsets: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals (N,M,3) as :meth:`residuals`, the pose Jacobians (N,M,3,26) and the shape Jacobians
        (N,M,3,15+3M)."""
        joint_offsets, local = self.joint_offsets(scales), self.local_points(offsets)
        count, markers = self.observed.shape
        residuals = np.zeros((count, markers, 3))
        pose_jacobians = np.zeros((count, markers, 3, N_PARAMS))
        shape_jacobians = np.zeros((count, markers, 3, len(SCALED_JOINTS) + 3 * markers))
        mask = self.observed[:, :, None].astype(float)
        for n, theta in enumerate(thetas):
            points, jacobian = points_and_jacobian_kernel(theta, self.relative_rest, joint_offsets,
                                                          self.abduction, ANCESTOR, self.joints,
                                                          self.weights, local)
            rotations, _, _, _ = forward_kinematics_kernel(theta, self.relative_rest, joint_offsets,
                                                           self.abduction)
            pose_jacobians[n] = jacobian * mask[n, :, :, None]
            moved = np.einsum("jab,jb->ja", rotations[JOINT_PARENTS[SCALED_JOINTS]], self.offsets0[SCALED_JOINTS])
            shape_jacobians[n, :, :, :len(SCALED_JOINTS)] = (
                self.reach[:, SCALED_JOINTS, None] * moved[None]).transpose(0, 2, 1)
            carried = np.einsum("mk,mkab,mkbc->mac", self.weights, rotations[self.joints],
                                self.rest_rotations[self.joints])
            for i in range(markers):
                column = len(SCALED_JOINTS) + 3 * i
                shape_jacobians[n, i, :, column:column + 3] = carried[i]
            shape_jacobians[n] *= mask[n, :, :, None]
            residuals[n] = (self.clean[n] - points) * mask[n]
        return residuals, pose_jacobians, shape_jacobians


def _cost(residuals: np.ndarray, scales: np.ndarray, offsets: np.ndarray) -> float:
    return float((residuals ** 2).sum() + SCALE_PRIOR ** 2 * ((scales - 1.0) ** 2).sum()
                 + OFFSET_PRIOR ** 2 * (offsets ** 2).sum())


def _mean_residual(residuals: np.ndarray, observed: np.ndarray) -> float:
    return float(np.linalg.norm(residuals, axis=2)[observed].mean()) if observed.any() else float("nan")


def _apply_pose_step(theta: np.ndarray, step: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    moved = theta.copy()
    moved[0:3] += step[0:3]
    moved[3:6] = vector_from_rotation(rotation_from_vector(np.ascontiguousarray(step[3:6]))
                                      @ rotation_from_vector(np.ascontiguousarray(theta[3:6])))
    moved[6:] = np.clip(theta[6:] + step[6:], lower[6:], upper[6:])
    return moved


def calibrated_model(model: HandModel, markers: MarkerSet, scales: np.ndarray, offsets: np.ndarray
                     ) -> tuple[HandModel, MarkerSet]:
    """The hand with joint offsets scaled by ``scales (15,)`` and markers moved by ``offsets (M,3)`` mm
    (rest pose), as a new model and marker set."""
    skeleton = model.skeleton
    full = np.ones(N_JOINTS)
    full[SCALED_JOINTS] = scales
    rest = skeleton.rest_positions.copy()
    for joint in range(1, N_JOINTS):
        parent = JOINT_PARENTS[joint]
        rest[joint] = rest[parent] + full[joint] * (skeleton.rest_positions[joint] - skeleton.rest_positions[parent])
    distal = 3 + 3 * np.arange(5)
    tips = rest[distal] + (skeleton.tip_positions - skeleton.rest_positions[distal])
    new_skeleton = Skeleton(rest_positions=rest, rest_rotations=skeleton.rest_rotations.copy(), tip_positions=tips,
                            side=skeleton.side)
    shift = rest - skeleton.rest_positions                                   # (16,3)
    vertices = model.vertices + np.einsum("vk,vka->va", model.skin_weights, shift[model.skin_joints])
    new_model = replace(model, skeleton=new_skeleton, vertices=vertices, name=f"{model.name} (calibrated)")
    rest_t = np.transpose(skeleton.rest_rotations[markers.influence_joints], (0, 1, 3, 2))
    local = np.ascontiguousarray(markers.local_points + np.einsum("mkab,mb->mka", rest_t, offsets))
    rotations, positions = new_model.chain.joint_transforms(np.zeros(N_PARAMS))
    rest_markers = skinned_points_kernel(rotations, positions, markers.influence_joints, markers.influence_weights,
                                         local)
    new_markers = MarkerSet(list(markers.names), markers.vertex.copy(), rest_markers, markers.influence_joints,
                            markers.influence_weights, local, markers.offsets_mm.copy())
    return new_model, new_markers


def calibrate_subject(positions: np.ndarray, model: HandModel, layout: MarkerLayout | MarkerSet,
                      initial_angles: np.ndarray | None = None, max_frames: int = 24, iterations: int = 12,
                      progress: Callable[[float], None] | None = None,
                      cancelled: Callable[[], bool] | None = None) -> tuple[HandModel, MarkerSet, dict]:
    """Fit bone scales and marker offsets of ``model`` to labelled ``positions (F,M,3)`` mm (the
    layout's marker order, NaN missing). ``initial_angles (F,26)``: poses of those frames when known
    (e.g. from tracking), else solved by layered IK. Uses up to ``max_frames`` well-observed frames.

    Returns the calibrated model, its marker set and a report: ``frames`` used, ``scales`` (15,)
    per joint offset (joints 1..15), ``offsets_mm (M,3)``, ``residual_before_mm`` / ``residual_after_mm``
    mean marker residual over those frames (the template at its IK poses / the calibrated hand at the
    jointly fitted poses), ``residual_after_ik_mm`` (the calibrated hand solved frame by frame by the
    layered IK, as tracking does), ``iterations``.
    """
    markers = resolve_layout(model, layout) if isinstance(layout, MarkerLayout) else layout
    frames, targets = _calibration_frames(positions, len(markers.names), initial_angles, max_frames)
    if initial_angles is not None:
        thetas = np.array(initial_angles, dtype=float)[frames]
    else:
        thetas = solve_positions(targets, model, markers, settings=IKSettings(method="layered")).joint_angles
    thetas = np.ascontiguousarray(thetas)
    lower, upper = default_joint_limits()
    problem = _Problem(model, markers, targets)
    scales, offsets = np.ones(len(SCALED_JOINTS)), np.zeros((len(markers.names), 3))
    residuals, pose_jacobians, shape_jacobians = problem.linearise(thetas, scales, offsets)
    before = _mean_residual(residuals, problem.observed)
    cost = _cost(residuals, scales, offsets)
    damping = 1e-3
    done = 0
    for iteration in range(iterations):
        if cancelled is not None and cancelled():
            raise CancelledError("subject calibration cancelled; the model is unchanged")
        if progress is not None:
            progress(iteration / iterations)
        pose_steps, shape_step = _damped_step(residuals, pose_jacobians, shape_jacobians, scales, offsets, damping)
        new_scales = np.clip(scales + shape_step[:len(SCALED_JOINTS)], *SCALE_LIMITS)
        new_offsets = offsets + shape_step[len(SCALED_JOINTS):].reshape(offsets.shape)
        new_thetas = np.array([_apply_pose_step(thetas[n], pose_steps[n], lower, upper) for n in range(len(thetas))])
        new_residuals = problem.residuals(new_thetas, new_scales, new_offsets)
        new_cost = _cost(new_residuals, new_scales, new_offsets)
        done = iteration + 1
        if new_cost < cost:
            improvement = (cost - new_cost) / max(cost, 1e-12)
            thetas, scales, offsets, cost = new_thetas, new_scales, new_offsets, new_cost
            residuals, pose_jacobians, shape_jacobians = problem.linearise(thetas, scales, offsets)
            damping = max(damping / 3.0, 1e-7)
            if improvement < 1e-6:
                break
        else:
            damping *= 4.0
            if damping > 1e6:
                break
    if progress is not None:
        progress(1.0)
    new_model, new_markers = calibrated_model(model, markers, scales, offsets)
    resolved = solve_positions(targets, new_model, new_markers, settings=IKSettings(method="layered"))
    report = {"frames": int(len(frames)), "scales": scales.round(4).tolist(),
              "offsets_mm": offsets.round(3).tolist(), "residual_before_mm": round(before, 4),
              "residual_after_mm": round(_mean_residual(residuals, problem.observed), 4),
              "residual_after_ik_mm": round(resolved.mean_residual_mm, 4), "iterations": done}
    return new_model, new_markers, report


def _calibration_frames(positions: np.ndarray, marker_count: int, initial_angles: np.ndarray | None,
                        max_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """The frames (S,) of ``positions (F,M,3)`` mm the calibration uses (:func:`_select_frames`; a marker
    counts as observed where its position, and the frame's ``initial_angles`` when given, are finite) and
    their targets (S,M,3) mm (NaN unobserved). Raises :class:`InputError` for a wrong shape or fewer than
    3 labelled markers in every frame."""
    positions = np.asarray(positions, dtype=float)
    if positions.ndim != 3 or positions.shape[1:] != (marker_count, 3):
        raise InputError(f"calibration positions must be (F, {marker_count}, 3), got {positions.shape}")
    observed = np.isfinite(positions).all(axis=2)
    if initial_angles is not None:
        observed &= np.isfinite(np.asarray(initial_angles)).all(axis=1)[:, None]
    if not observed.any() or observed.sum(axis=1).max() < 3:
        raise InputError("subject calibration needs frames with at least 3 labelled markers")
    frames = _select_frames(observed, max_frames)
    return frames, np.where(observed[frames][:, :, None], positions[frames], np.nan)


def _damped_step(residuals: np.ndarray, pose_jacobians: np.ndarray, shape_jacobians: np.ndarray,
                 scales: np.ndarray, offsets: np.ndarray, damping: float) -> tuple[np.ndarray, np.ndarray]:
    """One Levenberg–Marquardt step of the joint fit: the pose steps (N,26) and the shape step (15+3M,)
    (scales, then marker offsets) from the linearisation (:meth:`_Problem.linearise`), the shape priors
    and ``damping``; the per-frame pose blocks are eliminated first (Schur complement on the shape)."""
    count, marker_count = len(residuals), len(offsets)
    shape_size = len(SCALED_JOINTS) + 3 * marker_count
    pose_j = pose_jacobians.reshape(count, -1, N_PARAMS)
    shape_j = shape_jacobians.reshape(count, -1, shape_size)
    flat = residuals.reshape(count, -1)
    shape_vector = np.concatenate([scales - 1.0, offsets.ravel()])
    prior = np.concatenate([np.full(len(SCALED_JOINTS), SCALE_PRIOR ** 2), np.full(3 * marker_count,
                                                                                  OFFSET_PRIOR ** 2)])
    pose_t = pose_j.transpose(0, 2, 1)
    system = pose_t @ pose_j
    system[:, np.arange(N_PARAMS), np.arange(N_PARAMS)] *= 1.0 + damping
    system[:, np.arange(N_PARAMS), np.arange(N_PARAMS)] += damping * 1e-6
    coupling = pose_t @ shape_j
    gradient = pose_t @ flat[:, :, None]
    solved = np.linalg.solve(system, np.concatenate([coupling, gradient], axis=2))
    stacked = shape_j.reshape(-1, shape_size)
    reduced = np.diag(prior) + stacked.T @ stacked \
        - coupling.reshape(-1, shape_size).T @ solved[:, :, :-1].reshape(-1, shape_size)
    reduced_rhs = -prior * shape_vector + stacked.T @ flat.ravel() \
        - coupling.reshape(-1, shape_size).T @ solved[:, :, -1].ravel()
    reduced[np.diag_indices(shape_size)] += damping * (np.diag(reduced) + 1e-6)
    shape_step = np.linalg.solve(reduced, reduced_rhs)
    return solved[:, :, -1] - solved[:, :, :-1] @ shape_step, shape_step
