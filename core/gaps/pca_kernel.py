"""Compiled part of the PCA gap fill: the donors' pose in every frame of a window (:func:`core.gaps.pca._poses`).

Imported when a PCA fill first runs (numba is not needed to import :mod:`core.gaps`); compiled once by
``python -m core.workflows.warm_up`` and loaded from numba's cache afterwards.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Newton steps of the polar decomposition before a frame takes Horn's quaternion
POLAR_STEPS = 30
#: ``det H / |H|_F^3`` below which a frame takes Horn's quaternion (a reflection, nearly collinear or coplanar donors)
MIN_VOLUME = 1e-9


@njit(cache=True)
def _largest_eigenvector(matrix: np.ndarray) -> np.ndarray:
    """Unit eigenvector of the largest eigenvalue of a small symmetric matrix (cyclic Jacobi sweeps)."""
    size = matrix.shape[0]
    a = matrix.copy()
    vectors = np.eye(size)
    for _sweep in range(30):
        off = 0.0
        for p in range(size):
            for q in range(p + 1, size):
                off += a[p, q] * a[p, q]
        if off < 1e-22 * max(1e-300, (a * a).sum()):
            break
        for p in range(size):
            for q in range(p + 1, size):
                if abs(a[p, q]) < 1e-300:
                    continue
                tau = (a[q, q] - a[p, p]) / (2.0 * a[p, q])
                t = (1.0 if tau >= 0.0 else -1.0) / (abs(tau) + np.sqrt(1.0 + tau * tau))
                c = 1.0 / np.sqrt(1.0 + t * t)
                s = t * c
                for k in range(size):
                    akp, akq = a[k, p], a[k, q]
                    a[k, p], a[k, q] = c * akp - s * akq, s * akp + c * akq
                for k in range(size):
                    apk, aqk = a[p, k], a[q, k]
                    a[p, k], a[q, k] = c * apk - s * aqk, s * apk + c * aqk
                for k in range(size):
                    vkp, vkq = vectors[k, p], vectors[k, q]
                    vectors[k, p], vectors[k, q] = c * vkp - s * vkq, s * vkp + c * vkq
    best = 0
    for k in range(1, size):
        if a[k, k] > a[best, best]:
            best = k
    return vectors[:, best]


@njit(cache=True)
def _horn_rotation(h: np.ndarray, rotation: np.ndarray) -> None:
    """``rotation`` (3, 3), written: the rotation maximising ``trace(R H)`` for ``h = H (3, 3)`` (Horn 1987: the
    unit quaternion of the largest eigenvalue of the symmetric 4 x 4 matrix built from ``H``)."""
    n = np.empty((4, 4))
    n[0, 0] = h[0, 0] + h[1, 1] + h[2, 2]
    n[1, 1] = h[0, 0] - h[1, 1] - h[2, 2]
    n[2, 2] = -h[0, 0] + h[1, 1] - h[2, 2]
    n[3, 3] = -h[0, 0] - h[1, 1] + h[2, 2]
    n[0, 1] = n[1, 0] = h[1, 2] - h[2, 1]
    n[0, 2] = n[2, 0] = h[2, 0] - h[0, 2]
    n[0, 3] = n[3, 0] = h[0, 1] - h[1, 0]
    n[1, 2] = n[2, 1] = h[0, 1] + h[1, 0]
    n[1, 3] = n[3, 1] = h[2, 0] + h[0, 2]
    n[2, 3] = n[3, 2] = h[1, 2] + h[2, 1]
    q = _largest_eigenvector(n)
    w, x, y, z = q[0], q[1], q[2], q[3]
    rotation[0, 0] = w * w + x * x - y * y - z * z
    rotation[0, 1] = 2 * (x * y - w * z)
    rotation[0, 2] = 2 * (x * z + w * y)
    rotation[1, 0] = 2 * (y * x + w * z)
    rotation[1, 1] = w * w - x * x + y * y - z * z
    rotation[1, 2] = 2 * (y * z - w * x)
    rotation[2, 0] = 2 * (z * x - w * y)
    rotation[2, 1] = 2 * (z * y + w * x)
    rotation[2, 2] = w * w - x * x - y * y + z * z


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
            _horn_rotation(covariances[n], rotations[n])
    return origins, rotations
