"""Compiled part of the PCA gap fill: the donors' pose in every frame of a window (:func:`core.gaps.pca._poses`).

Imported when a PCA fill first runs (numba is not needed to import :mod:`core.gaps`); compiled once by
``python -m handmocap.core.workflows.warm_up`` and loaded from numba's cache afterwards.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from handmocap.core.ik.horn import horn_rotation

#: Newton steps of the polar decomposition before a frame takes Horn's quaternion
POLAR_STEPS = 30
#: ``det H / |H|_F^3`` below which a frame takes Horn's quaternion (a reflection, nearly collinear or coplanar donors)
MIN_VOLUME = 1e-9


@njit(cache=True)
def poses_kernel(donors: np.ndarray, reference: np.ndarray, share: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Per frame of ``donors (N, K, 3)`` mm (C-contiguous): the weighted (``share (K,)``, summing to 1) centroid
    (N, 3) and the rotation ``R (N, 3, 3)`` maximising ``trace(R H)`` (Kabsch's), ``H`` the weighted covariance
    of ``reference (K, 3)`` centred against the centred donors.

    Where ``det H`` is positive, ``R`` is the transposed orthogonal factor of the polar decomposition of ``H`` by
    scaled Newton iteration (``X <- (g X + X^-T / g) / 2``, ``g = |det X|^(-1/3)``); in the other frames (a
    reflection, donors nearly collinear or coplanar) and one that does not converge, Horn's quaternion."""
    frames, count = donors.shape[0], donors.shape[1]
    origins = np.zeros((frames, 3))
    covariances = np.zeros((frames, 3, 3))
    rotations = np.zeros((frames, 3, 3))
    centred = reference.copy()
    for axis in range(3):
        mean = 0.0
        for k in range(count):
            mean += share[k] * reference[k, axis]
        for k in range(count):
            centred[k, axis] = share[k] * (reference[k, axis] - mean)
    x = np.empty((3, 3))
    following = np.empty((3, 3))
    for n in range(frames):
        for axis in range(3):
            total = 0.0
            for k in range(count):
                total += share[k] * donors[n, k, axis]
            origins[n, axis] = total
        for i in range(3):
            for j in range(3):
                total = 0.0
                for k in range(count):
                    total += centred[k, i] * (donors[n, k, j] - origins[n, j])
                covariances[n, i, j] = total
        size = 0.0
        for i in range(3):
            for j in range(3):
                size += covariances[n, i, j] ** 2
        size = np.sqrt(size)
        if size <= 0.0:
            for i in range(3):
                rotations[n, i, i] = 1.0
            continue
        for i in range(3):
            for j in range(3):
                x[i, j] = covariances[n, i, j] / size
        volume = (x[0, 0] * (x[1, 1] * x[2, 2] - x[1, 2] * x[2, 1]) - x[0, 1] * (x[1, 0] * x[2, 2] - x[1, 2] * x[2, 0])
                  + x[0, 2] * (x[1, 0] * x[2, 1] - x[1, 1] * x[2, 0]))
        found = False
        for _step in range(POLAR_STEPS if volume > MIN_VOLUME else 0):
            volume = (x[0, 0] * (x[1, 1] * x[2, 2] - x[1, 2] * x[2, 1])
                      - x[0, 1] * (x[1, 0] * x[2, 2] - x[1, 2] * x[2, 0])
                      + x[0, 2] * (x[1, 0] * x[2, 1] - x[1, 1] * x[2, 0]))
            gain = abs(volume) ** (-1.0 / 3.0)
            change = 0.0
            for i in range(3):
                for j in range(3):
                    cofactor = (x[(i + 1) % 3, (j + 1) % 3] * x[(i + 2) % 3, (j + 2) % 3]
                                - x[(i + 1) % 3, (j + 2) % 3] * x[(i + 2) % 3, (j + 1) % 3])
                    following[i, j] = 0.5 * (gain * x[i, j] + cofactor / (gain * volume))
                    change = max(change, abs(following[i, j] - x[i, j]))
            x[:, :] = following
            if change < 1e-9:   # quadratic convergence: the step just taken left an error of order change²
                found = True
                break
        if found:
            for i in range(3):
                for j in range(3):
                    rotations[n, i, j] = x[j, i]
        else:
            horn_rotation(covariances[n], rotations[n])
    return origins, rotations
