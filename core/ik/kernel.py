"""Compiled per-frame damped Gauss-Newton IK (journal "Inverse kinematics", thesis §3.2.2, §6.4.4).

One solve minimises, over the six global parameters and the posture parameters ``p``,

    E = Σ_observed ‖t_i − x_i(θ)‖²  +  ‖w ∘ S (θ_posture − μ)‖²

with ``θ_posture = clip(c + B p)``: ``B = I₂₀, c = 0`` for full IK and ``B = P_l, c = μ`` for subspace
IK (journal eq. 3–4). Each step solves ``(JᵀJ + D²) δ = Jᵀ r`` (D: 0 for the global parameters,
``damping · (1 + |∂H/∂p|)`` for posture parameters whose step moves them towards their nearer limit:
Chan & Dubey, with the direction read from the step instead of from the previous frame), then halves
``δ`` until the energy decreases. The wrist rotation is updated by left-composing ``exp(δ_rot)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from handmocap.core.model.kinematics import (
    forward_kinematics_kernel,
    matmul3,
    points_and_jacobian_kernel,
    rotation_from_vector,
    skinned_points_kernel,
    vector_from_rotation,
)


@njit(cache=True)
def limit_gradient(values, lower, upper):
    """|∂H/∂p| of the Chan–Dubey joint-limit function H = (u−l)² / ((u−p)(p−l)), per parameter."""
    result = np.zeros(values.shape[0])
    for i in range(values.shape[0]):
        low, high = lower[i], upper[i]
        if not (np.isfinite(low) and np.isfinite(high)):
            continue
        to_high = max(high - values[i], 1e-6)
        to_low = max(values[i] - low, 1e-6)
        value = (high - low) ** 2 * (2.0 * values[i] - high - low) / (4.0 * to_high ** 2 * to_low ** 2)
        result[i] = min(abs(value), 1e6)
    return result


@njit(cache=True)
def solve_spd(system, rhs):
    """Solve ``system x = rhs`` for a small symmetric positive (semi-)definite system by Cholesky;
    pivots below 1e-12 × the largest diagonal are floored (an unconstrained direction gets no step)."""
    size = rhs.shape[0]
    factor = system.copy()
    floor = 1e-12 * max(np.abs(np.diag(system)).max(), 1e-30)
    for j in range(size):
        pivot = factor[j, j]
        for k in range(j):
            pivot -= factor[j, k] * factor[j, k]
        pivot = np.sqrt(max(pivot, floor))
        factor[j, j] = pivot
        for i in range(j + 1, size):
            value = factor[i, j]
            for k in range(j):
                value -= factor[i, k] * factor[j, k]
            factor[i, j] = value / pivot
    solution = rhs.copy()
    for i in range(size):
        value = solution[i]
        for k in range(i):
            value -= factor[i, k] * solution[k]
        solution[i] = value / factor[i, i]
    for i in range(size - 1, -1, -1):
        value = solution[i]
        for k in range(i + 1, size):
            value -= factor[k, i] * solution[k]
        solution[i] = value / factor[i, i]
    return solution


@njit(cache=True)
def _posture(centre, basis, params, angle_lower, angle_upper):
    posture = centre + basis @ params
    return np.minimum(np.maximum(posture, angle_lower), angle_upper)


@njit(cache=True)
def _energy(points, targets, observed, posture, prior_matrix, prior_mean, prior_weights):
    energy = 0.0
    for i in range(points.shape[0]):
        if observed[i]:
            for c in range(3):
                energy += (targets[i, c] - points[i, c]) ** 2
    if prior_weights.max() > 0.0:
        residual = prior_weights * (prior_matrix @ (posture - prior_mean))
        energy += residual @ residual
    return energy


@njit(cache=True)
def normal_equations(jacobian, points, targets, observed):
    """``JᵀJ (26,26)`` and ``Jᵀr (26,)`` of the observed markers (``r = t − x``), from the Jacobian
    ``(M,3,26)``: each marker's row moves only the global parameters and its own digit's, so only its
    non-zero columns are multiplied (a dense product would be ~6× the work)."""
    size = jacobian.shape[2]
    system = np.zeros((size, size))
    rhs = np.zeros(size)
    columns = np.empty(size, dtype=np.int64)
    for i in range(jacobian.shape[0]):
        if not observed[i]:
            continue
        used = 0
        for d in range(size):
            if jacobian[i, 0, d] != 0.0 or jacobian[i, 1, d] != 0.0 or jacobian[i, 2, d] != 0.0:
                columns[used] = d
                used += 1
        for c in range(3):
            residual = targets[i, c] - points[i, c]
            for a in range(used):
                column = columns[a]
                value = jacobian[i, c, column]
                rhs[column] += value * residual
                for b in range(a, used):
                    system[column, columns[b]] += value * jacobian[i, c, columns[b]]
    for a in range(size):
        for b in range(a):
            system[a, b] = system[b, a]
    return system, rhs


@njit(cache=True)
def _reduced_normal_equations(jacobian, points, targets, observed, basis, identity_basis):
    """The normal equations in the solved parameters (6 global + ``basis (20,n)`` posture coordinates)."""
    system, rhs = normal_equations(jacobian, points, targets, observed)
    if identity_basis:
        return system, rhs
    n = basis.shape[1]
    reduced = np.empty((6 + n, 6 + n))
    reduced_rhs = np.empty(6 + n)
    reduced[:6, :6] = system[:6, :6]
    coupling = np.ascontiguousarray(system[:6, 6:]) @ basis
    reduced[:6, 6:] = coupling
    reduced[6:, :6] = coupling.T
    reduced[6:, 6:] = basis.T @ (np.ascontiguousarray(system[6:, 6:]) @ basis)
    reduced_rhs[:6] = rhs[:6]
    reduced_rhs[6:] = basis.T @ np.ascontiguousarray(rhs[6:])
    return reduced, reduced_rhs


@njit(cache=True)
def frame_energy_kernel(theta, targets, observed, relative_rest, offsets, abduction_sign, influence_joints,
                        influence_weights, local_points, prior_matrix, prior_mean, prior_weights):
    """The IK energy E (mm²) of ``theta (26,)`` for one frame (see module docstring)."""
    rotations, positions, _, _ = forward_kinematics_kernel(theta, relative_rest, offsets, abduction_sign)
    points = skinned_points_kernel(rotations, positions, influence_joints, influence_weights, local_points)
    return _energy(points, targets, observed, theta[6:], prior_matrix, prior_mean, prior_weights)


@njit(cache=True)
def solve_frame_kernel(theta, targets, observed, relative_rest, offsets, abduction_sign, ancestor,
                       influence_joints, influence_weights, local_points, basis, centre, param_lower,
                       param_upper, damping, prior_matrix, prior_mean,
                       prior_weights, angle_lower, angle_upper, max_iterations, tolerance, global_free):
    """Solve one frame from the start ``theta (26,)``; returns (theta, energy, marker positions (M,3)).

    ``targets (M,3)`` mm, ``observed (M,)`` bool, ``basis (20,n)``, ``centre (20,)``, parameter limits
    ``(n,)``, ``prior_matrix (20,20)`` = S, ``prior_weights (20,)`` = per-row √ω₄ (0 = no prior);
    ``global_free`` False holds the six global parameters at their start values.
    """
    n = basis.shape[1]
    params = basis.T @ (theta[6:] - centre)
    params = np.minimum(np.maximum(params, param_lower), param_upper)
    current = theta.copy()
    current[6:] = _posture(centre, basis, params, angle_lower, angle_upper)
    prior_jacobian = (prior_weights.reshape(-1, 1) * prior_matrix) @ basis
    use_prior = prior_weights.max() > 0.0
    gradient = limit_gradient(params, param_lower, param_upper)
    points, jacobian = points_and_jacobian_kernel(current, relative_rest, offsets, abduction_sign, ancestor,
                                                  influence_joints, influence_weights, local_points)
    energy = _energy(points, targets, observed, current[6:], prior_matrix, prior_mean, prior_weights)
    identity_basis = n == 20 and np.all(basis == np.eye(20))
    prior_normal = prior_jacobian.T @ prior_jacobian
    for _ in range(max_iterations):
        system, rhs = _reduced_normal_equations(jacobian, points, targets, observed, basis, identity_basis)
        if use_prior:
            prior_residual = -prior_weights * (prior_matrix @ (current[6:] - prior_mean))
            system[6:, 6:] += prior_normal
            rhs[6:] += prior_jacobian.T @ prior_residual
        for k in range(n):
            system[6 + k, 6 + k] += damping ** 2
        for k in range(6):
            system[k, k] += 1e-9 if global_free else 1e12
        step = solve_spd(system, rhs)
        # Chan & Dubey: parameters whose step moves them towards their nearer limit are slowed by
        # (1 + |∂H/∂p|); parameters moving away from a limit stay free.
        slowed = False
        for k in range(n):
            middle = 0.5 * (param_lower[k] + param_upper[k])
            if gradient[k] > 0.0 and step[6 + k] * (params[k] - middle) > 0.0:
                system[6 + k, 6 + k] += (damping * (1.0 + gradient[k])) ** 2 - damping ** 2
                slowed = True
        if slowed:
            step = solve_spd(system, rhs)
        accepted = False
        fraction = 1.0
        for _halving in range(10):
            candidate = current.copy()
            candidate[0:3] = current[0:3] + fraction * step[0:3]
            rotation = matmul3(rotation_from_vector(fraction * step[3:6]), rotation_from_vector(current[3:6]))
            candidate[3:6] = vector_from_rotation(rotation)
            candidate_params = np.minimum(np.maximum(params + fraction * step[6:], param_lower), param_upper)
            candidate[6:] = _posture(centre, basis, candidate_params, angle_lower, angle_upper)
            rotations, positions, _, _ = forward_kinematics_kernel(candidate, relative_rest, offsets,
                                                                   abduction_sign)
            candidate_points = skinned_points_kernel(rotations, positions, influence_joints,
                                                     influence_weights, local_points)
            candidate_energy = _energy(candidate_points, targets, observed, candidate[6:], prior_matrix,
                                       prior_mean, prior_weights)
            if candidate_energy < energy:
                accepted = True
                break
            fraction *= 0.5
        if not accepted:
            break
        improvement = energy - candidate_energy
        current, params, energy, points = candidate, candidate_params, candidate_energy, candidate_points
        gradient = limit_gradient(params, param_lower, param_upper)
        if improvement < tolerance * (1.0 + energy):
            break
        points, jacobian = points_and_jacobian_kernel(current, relative_rest, offsets, abduction_sign,
                                                      ancestor, influence_joints, influence_weights,
                                                      local_points)
    return current, energy, points
