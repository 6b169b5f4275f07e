"""Horn's closed-form rotation (Horn 1987), compiled: the rotation maximising ``trace(R H)`` for a 3 x 3
correlation matrix ``H``, from the unit quaternion of the largest eigenvalue of a symmetric 4 x 4 matrix.

Shared by the rigid-object tracks of the labeller (Kabsch's fit) and the PCA gap fill's donor poses; no LAPACK,
so that it runs inside other compiled kernels.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def largest_eigenvector(matrix: np.ndarray) -> np.ndarray:
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
def horn_rotation(h: np.ndarray, rotation: np.ndarray) -> None:
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
    q = largest_eigenvector(n)
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
