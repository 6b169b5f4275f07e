"""Mean value coordinates of points with respect to a closed triangle mesh (Floater et al. 2005;
the robust evaluation of Ju, Schaefer & Warren 2005, "Mean value coordinates for closed triangular
meshes", Fig. 4).

The coordinates ``W (P,V)`` of points ``q (P,3)`` reproduce them from the mesh, ``q = W @ vertices``,
and are computed once on the undeformed template; applied to the deformed vertices they move the
skeleton joints with the surface (journal: "Hand model generation", last paragraph).
"""

from __future__ import annotations

import numpy as np

_EPSILON = 1e-9


def mean_value_coordinates(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Mean value coordinates ``(P,V)`` of ``points (P,3)`` w.r.t. the closed mesh ``vertices (V,3)``,
    ``faces (T,3)``; rows sum to 1 and ``coordinates @ vertices`` reproduces the points."""
    vertices = np.asarray(vertices, dtype=np.float64)
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    result = np.zeros((len(points), len(vertices)))
    for row, point in enumerate(points):
        result[row] = _coordinates_of(vertices, faces, point)
    return result


def _coordinates_of(vertices: np.ndarray, faces: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Mean value coordinates (V,) of one point (vectorised over the triangles)."""
    count = len(vertices)
    offsets = vertices - point
    distances = np.linalg.norm(offsets, axis=1)
    weights = np.zeros(count)
    coincident = distances < _EPSILON
    if np.any(coincident):
        weights[np.argmax(coincident)] = 1.0
        return weights
    units = offsets / distances[:, None]
    u = units[faces]                                          # (T,3 corners,3)
    d = distances[faces]                                      # (T,3)
    nxt, prv = [1, 2, 0], [2, 0, 1]
    lengths = np.linalg.norm(u[:, nxt] - u[:, prv], axis=2)   # l_i = |u_{i+1} - u_{i-1}|
    theta = 2.0 * np.arcsin(np.clip(lengths / 2.0, -1.0, 1.0))
    half = theta.sum(axis=1) / 2.0
    on_triangle = np.pi - half < 1e-7
    if np.any(on_triangle):
        t = int(np.argmax(on_triangle))
        local = np.sin(theta[t]) * d[t, prv] * d[t, nxt]
        weights[faces[t]] = local / local.sum()
        return weights
    sin_theta = np.sin(theta)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = 2.0 * np.sin(half)[:, None] * np.sin(half[:, None] - theta) / (sin_theta[:, nxt] * sin_theta[:, prv]) \
            - 1.0
    sign = np.sign(np.linalg.det(u))
    s = sign[:, None] * np.sqrt(np.clip(1.0 - c * c, 0.0, None))
    valid = np.all(np.abs(s) > 1e-9, axis=1) & np.all(np.isfinite(c), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = (theta - c[:, nxt] * theta[:, prv] - c[:, prv] * theta[:, nxt]) / (d * sin_theta[:, nxt] * s[:, prv])
    w = np.where(valid[:, None] & np.isfinite(w), w, 0.0)
    for k in range(3):
        weights += np.bincount(faces[:, k], weights=w[:, k], minlength=count)
    total = weights.sum()
    return weights / total if abs(total) > 0 else weights
