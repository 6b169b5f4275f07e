"""Calibration report: landmark residuals, scan-to-model distances, per-vertex distance map, warnings.

Also the geometric helpers the report and the evaluation share: exact point-to-triangle distances
(Ericson, "Real-Time Collision Detection", 5.1.5) against the nearest candidate triangles.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from handmocap.core.calibration.nearest import nearest_neighbours
from handmocap.core.model.skeleton import JOINT_NAMES

SWAP_RESIDUAL_MM = 8.0         # a landmark with a larger residual is examined for a swap
LARGE_RESIDUAL_MM = 5.0        # a landmark with a larger residual after the fit is reported
UNSUPPORTED_MM = 4.0           # a vertex farther than this from every scan point has no scan support
UNSUPPORTED_AREA_MM2 = 150.0   # a connected area without scan support larger than this (mm²) warns
CANDIDATE_TRIANGLES = 12


def closest_points_on_triangles(points: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest points (N,3) on triangles ``a, b, c (N,3)`` to ``points (N,3)`` (Ericson 5.1.5), vectorised."""
    ab, ac, ap = b - a, c - a, points - a
    d1, d2 = np.einsum("na,na->n", ab, ap), np.einsum("na,na->n", ac, ap)
    bp = points - b
    d3, d4 = np.einsum("na,na->n", ab, bp), np.einsum("na,na->n", ac, bp)
    cp = points - c
    d5, d6 = np.einsum("na,na->n", ab, cp), np.einsum("na,na->n", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denominator = 1.0 / (va + vb + vc)
        v_in, w_in = vb * denominator, vc * denominator
        result = a + ab * v_in[:, None] + ac * w_in[:, None]
        # edge regions
        t_ab = d1 / (d1 - d3)
        on_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        t_ac = d2 / (d2 - d6)
        on_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        on_bc = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
    result = np.where(on_bc[:, None], b + t_bc[:, None] * (c - b), result)
    result = np.where(on_ac[:, None], a + t_ac[:, None] * ac, result)
    result = np.where(on_ab[:, None], a + t_ab[:, None] * ab, result)
    # vertex regions
    result = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, result)
    result = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, result)
    result = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, result)
    return result


def point_to_mesh_distances(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
                            candidates: int = CANDIDATE_TRIANGLES) -> np.ndarray:
    """Distance (N,) in mm of each point to the triangle mesh (exact over the ``candidates`` triangles
    with the nearest centroids, which is exact for meshes with even triangles)."""
    centroids = vertices[faces].mean(axis=1)
    _, nearest = nearest_neighbours(cKDTree(centroids), points, k=min(candidates, len(faces)))
    nearest = np.atleast_2d(nearest.T).T if nearest.ndim == 1 else nearest
    best = np.full(len(points), np.inf)
    for column in range(nearest.shape[1]):
        triangles = faces[nearest[:, column]]
        closest = closest_points_on_triangles(points, vertices[triangles[:, 0]], vertices[triangles[:, 1]],
                                              vertices[triangles[:, 2]])
        best = np.minimum(best, np.linalg.norm(points - closest, axis=1))
    return best


@dataclass
class CalibrationReport:
    """What the operator reviews after a fit (all distances mm).

    ``landmark_residuals``: name -> distance of the fitted landmark vertex to the picked point;
    ``scan_to_model``: mean/median/p95/p99/max of the scan points' distance to the fitted surface;
    ``vertex_distance (V,)``: each fitted vertex's distance to the nearest scan point (the distance map);
    ``warnings``: one line each; ``notes``: what the pipeline did (subsampling, units, cleaning).
    """

    landmark_residuals: dict[str, float]
    scan_to_model: dict[str, float]
    vertex_distance: np.ndarray
    unsupported_share: float
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    alignment: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict:
        """A JSON-serialisable summary (the distance map is summarised, not listed)."""
        finite = self.vertex_distance[np.isfinite(self.vertex_distance)]
        return {
            "landmark_residuals_mm": {k: round(v, 3) for k, v in self.landmark_residuals.items()},
            "landmark_rms_mm": round(float(np.sqrt(np.mean(np.square(list(self.landmark_residuals.values()))))), 3)
            if self.landmark_residuals else None,
            "scan_to_model_mm": {k: round(v, 3) for k, v in self.scan_to_model.items()},
            "vertex_distance_mm": {"mean": round(float(finite.mean()), 3) if len(finite) else None,
                                   "max": round(float(finite.max()), 3) if len(finite) else None},
            "unsupported_surface_share": round(self.unsupported_share, 4),
            "alignment": {k: round(float(v), 4) for k, v in self.alignment.items()},
            "warnings": list(self.warnings),
            "notes": list(self.notes),
        }


def distance_statistics(distances: np.ndarray) -> dict[str, float]:
    """mean, median, p95, p99 and max (mm) of a distance sample."""
    return {"mean": float(np.mean(distances)), "median": float(np.median(distances)),
            "p95": float(np.percentile(distances, 95)), "p99": float(np.percentile(distances, 99)),
            "max": float(np.max(distances))}


def find_swapped_pairs(names: list[str], model_points: np.ndarray, targets: np.ndarray,
                       threshold_mm: float = SWAP_RESIDUAL_MM) -> list[tuple[str, str, float, float]]:
    """Landmark pairs that look swapped: both residuals above ``threshold_mm`` and exchanging their
    targets lowers both well below. Returns ``(name a, name b, residual before, residual after)``."""
    residuals = np.linalg.norm(model_points - targets, axis=1)
    suspects = np.flatnonzero(residuals > threshold_mm)
    found = []
    used: set[int] = set()
    for i in suspects:
        for j in suspects:
            if j <= i or i in used or j in used:
                continue
            swapped = max(np.linalg.norm(model_points[i] - targets[j]), np.linalg.norm(model_points[j] - targets[i]))
            before = min(residuals[i], residuals[j])
            if swapped < 0.5 * before:
                found.append((names[i], names[j], float(before), float(swapped)))
                used.update((int(i), int(j)))
    return found


def unsupported_areas(vertices: np.ndarray, faces: np.ndarray, vertex_distance: np.ndarray,
                      skin_joints: np.ndarray, skin_weights: np.ndarray, limit_mm: float = UNSUPPORTED_MM
                      ) -> tuple[float, list[tuple[float, str]]]:
    """Share of the surface without scan support and the large connected unsupported areas as
    ``(area mm², name of the joint that carries most of it)``, largest first."""
    corners = vertices[faces]
    face_area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    vertex_area = np.zeros(len(vertices))
    for k in range(3):
        vertex_area += np.bincount(faces[:, k], weights=face_area / 3.0, minlength=len(vertices))
    total = vertex_area.sum()
    unsupported = ~(vertex_distance <= limit_mm)
    share = float(vertex_area[unsupported].sum() / total)
    if not np.any(unsupported):
        return share, []
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edges = edges[unsupported[edges[:, 0]] & unsupported[edges[:, 1]]]
    graph = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])),
                              shape=(len(vertices), len(vertices)))
    _, labels = connected_components(graph, directed=False)
    areas = []
    for label in np.unique(labels[unsupported]):
        members = np.flatnonzero(unsupported & (labels == label))
        area = float(vertex_area[members].sum())
        if area >= UNSUPPORTED_AREA_MM2:
            dominant = skin_joints[members, np.argmax(skin_weights[members], axis=1)]
            areas.append((area, JOINT_NAMES[int(np.bincount(dominant).argmax())]))
    return share, sorted(areas, reverse=True)
