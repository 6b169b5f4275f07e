"""Frame-rate lifting (Zhao et al. §6): poses solved at the RGB-D rate carried to every mocap frame.

1. The poses of the RGB-D frames are interpolated to each mocap frame (linearly; the wrist rotation by slerp):
   ``q̂``.
2. Each mocap frame is refined on its own markers with a pull to ``q̂`` (eq. 12, squared): a damped
   Gauss-Newton on ``Σ‖x_i(q) − m_i‖² + λ²‖W (q − q̂)‖²`` (W: 1 per rad, 0.1 per mm of wrist translation).
3. Per-frame IK plus filtering (PFIK+F, Gleicher 2001): the change the refinement made to ``q̂`` is low-pass
   filtered over time (Gaussian), and the refinement is repeated from the filtered pose, ``passes`` times.
"""

from __future__ import annotations

import numpy as np

from handmocap.core.fusion.pose import left_compose
from handmocap.core.model import HandModel, MarkerSet, marker_jacobian
from handmocap.core.model.skeleton import N_PARAMS

#: per-parameter scale of the pull to the interpolated pose: rad count 1, wrist translation mm count 0.1
PULL_SCALE = np.concatenate([np.full(3, 0.1), np.ones(N_PARAMS - 3)])


def interpolate_poses(key_frames: np.ndarray, key_poses: np.ndarray, n_frames: int) -> np.ndarray:
    """Poses (F,26) at mocap frames ``0..n_frames-1`` from poses (K,26) at fractional mocap frames (K,)
    (increasing); held constant before the first and after the last key."""
    frames = np.clip(np.arange(n_frames, dtype=float), key_frames[0], key_frames[-1])
    poses = np.empty((n_frames, N_PARAMS))
    for column in list(range(3)) + list(range(6, N_PARAMS)):
        poses[:, column] = np.interp(frames, key_frames, key_poses[:, column])
    if len(key_frames) == 1:
        poses[:, 3:6] = key_poses[0, 3:6]
    else:
        from scipy.spatial.transform import Rotation, Slerp  # imported when first needed (start-up)

        poses[:, 3:6] = Slerp(key_frames, Rotation.from_rotvec(key_poses[:, 3:6]))(frames).as_rotvec()
    return poses


def refine_frame(model: HandModel, markers: MarkerSet, targets: np.ndarray, guess: np.ndarray, pull: float,
                 lower: np.ndarray, upper: np.ndarray, iterations: int = 5) -> np.ndarray:
    """Eq. 12 for one frame: the pose (26,) near ``guess`` that fits the seen ``targets (M,3)`` mm (NaN = not
    seen); ``pull`` λ in mm per rad."""
    seen = np.isfinite(targets).all(axis=1)
    theta = guess.copy()
    if not seen.any():
        return theta
    weights = (pull * PULL_SCALE) ** 2
    for _ in range(iterations):
        positions, jacobian = marker_jacobian(model, markers, theta)
        residual = (positions - targets)[seen].reshape(-1)
        rows = jacobian[seen].reshape(-1, N_PARAMS)
        hessian = rows.T @ rows + np.diag(weights) + 1e-6 * np.eye(N_PARAMS)
        gradient = rows.T @ residual + weights * (theta - guess)
        step = -np.linalg.solve(hessian, gradient)
        theta = np.clip(left_compose(theta, step), lower, upper)
        if np.abs(step).max() < 1e-5:
            break
    return theta


def lift(model: HandModel, markers: MarkerSet, targets: np.ndarray, key_frames: np.ndarray, key_poses: np.ndarray,
         lower: np.ndarray, upper: np.ndarray, pull: float = 10.0, filter_frames: float = 2.0, passes: int = 2
         ) -> np.ndarray:
    """Poses (F,26) for every mocap frame of ``targets (F,M,3)`` mm from the RGB-D poses ``key_poses (K,26)`` at
    fractional mocap frames ``key_frames (K,)`` (steps in the module docstring; ``filter_frames``: σ of the
    Gaussian filter in mocap frames)."""
    from scipy.ndimage import gaussian_filter1d  # imported when first needed (start-up)

    interpolated = interpolate_poses(key_frames, key_poses, len(targets))
    guess = interpolated
    for _ in range(passes):
        refined = np.array([refine_frame(model, markers, targets[frame], guess[frame], pull, lower, upper)
                            for frame in range(len(targets))])
        change = gaussian_filter1d(refined - interpolated, filter_frames, axis=0, mode="nearest")
        guess = np.clip(interpolated + change, lower, upper)
    return np.array([refine_frame(model, markers, targets[frame], guess[frame], pull, lower, upper)
                     for frame in range(len(targets))])
