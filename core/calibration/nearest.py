"""Nearest-neighbour queries of many points at once (scipy's ``cKDTree.query``, which returns scalars for
one point and arrays for many; its type stubs cannot tell the two apart, this function always returns arrays)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def nearest_neighbours(tree: cKDTree, points: np.ndarray, k: int = 1, upper_bound_mm: float = np.inf
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Distances (mm) and indices into the tree's points of the ``k`` nearest neighbours of each of
    ``points (N,3)``: shapes (N,) for ``k == 1``, else (N,k). A neighbour farther than ``upper_bound_mm``
    has distance inf and index ``tree.n``. Runs on all cores."""
    distances, indices = tree.query(points, k=k, distance_upper_bound=upper_bound_mm, workers=-1)
    return np.asarray(distances), np.asarray(indices)
