"""Synthetic hand scans with ground truth: a (re-proportioned) skinned hand sampled like a 3D scanner would.

Points are sampled area-uniformly on the posed mesh (barycentric sampling of triangles) and carry the
interpolated normal and a skin colour; then noise along the normals, holes, uniform outliers and a
grey/blue table plane below the hand are added.
"""

from __future__ import annotations

import numpy as np

from handmocap.core.calibration.align import anatomical_landmarks
from handmocap.core.calibration.scan import Scan
from handmocap.core.model import HandModel, load_template, skin_vertices
from handmocap.core.model.hand_model import mesh_vertex_normals
from handmocap.core.model.skeleton import N_GLOBAL, N_PARAMS, HandProportions
from handmocap.core.model.template_mesh import LANDMARK_NAMES, build_template

SKIN_TONE = np.array([212.0, 158.0, 128.0])   # RGB, passes the Kovac rule with a wide margin
POSTURE_JITTER_RAD = 0.05                      # spread of the default posture around the flat hand
TABLE_GAP_MM = 15.0                            # distance from the lowest hand point down to the table
TABLE_MARGIN_MM = 60.0                         # how far the table extends beyond the hand

#: values of ``truth["labels"]``
HAND, OUTLIER, BACKGROUND = 0, 1, 2


def sample_surface(vertices: np.ndarray, faces: np.ndarray, count: int, rng: np.random.Generator
                   ) -> tuple[np.ndarray, np.ndarray]:
    """``count`` area-uniform points (count,3) on a triangle mesh and their interpolated unit normals."""
    corners = vertices[faces]
    areas = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    triangles = rng.choice(len(faces), size=count, p=areas / areas.sum())
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    barycentric = np.column_stack([1.0 - u - v, u, v])
    points = np.einsum("nk,nka->na", barycentric, corners[triangles])
    normals = np.einsum("nk,nka->na", barycentric, mesh_vertex_normals(vertices, faces)[faces[triangles]])
    return points, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def _skin_colors(count: int, rng: np.random.Generator) -> np.ndarray:
    """Skin colours (count,3) uint8: the skin tone with a shading factor and a small per-channel spread."""
    shade = rng.normal(1.0, 0.06, size=(count, 1))
    return np.clip(SKIN_TONE * shade + rng.normal(0.0, 4.0, size=(count, 3)), 0, 255).astype(np.uint8)


def _table(count: int, lower: np.ndarray, upper: np.ndarray, rng: np.random.Generator
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points, normals and colours of a table plane below the box ``lower..upper``; grey or blue halves."""
    xy = rng.uniform(lower[:2] - TABLE_MARGIN_MM, upper[:2] + TABLE_MARGIN_MM, size=(count, 2))
    points = np.column_stack([xy, np.full(count, lower[2] - TABLE_GAP_MM)])
    normals = np.tile([0.0, 0.0, 1.0], (count, 1))
    grey = rng.uniform(60, 200, size=(count, 1)) + rng.normal(0.0, 3.0, size=(count, 3))
    blue = np.array([40.0, 70.0, 150.0]) * rng.uniform(0.7, 1.3, size=(count, 1))
    colors = np.where(xy[:, :1] < 0.5 * (lower[0] + upper[0]), grey, blue)
    return points, normals, np.clip(colors, 0, 255).astype(np.uint8)


def synthetic_scan(proportions: HandProportions | None = None, theta: np.ndarray | None = None,
                   n_points: int = 200_000, noise_mm: float = 0.5, holes: int = 3, outlier_share: float = 0.01,
                   background_points: int = 20_000, seed: int = 0) -> tuple[Scan, dict]:
    """A synthetic scan of a hand with ``proportions`` (default: the template) posed at ``theta (26,)``.

    ``theta`` defaults to the flat calibration pose (global pose zero) with a small seeded posture jitter.
    ``n_points`` surface samples before holes are cut; holes are balls of 8–15 mm radius.
    Returns ``(scan, truth)``; ``truth`` holds ``model`` (the subject's :class:`HandModel`), ``theta (26,)``,
    ``vertices (V,3)``, ``joints (16,3)``, ``landmarks (20,3)`` (order ``landmark_names``: the subject
    mesh's landmark vertices), ``landmark_points (20,3)`` (the exact anatomical surface points of
    ``LANDMARK_DESCRIPTIONS``, what a careful operator picks; the vertices are up to half an edge, 1–1.5 mm,
    off them: see :func:`anatomical_landmarks_from_truth`), all in the scan frame (mm),
    ``labels (N,)`` per scan point (:data:`HAND`, :data:`OUTLIER`, :data:`BACKGROUND`)
    and ``hole_centres (holes,3)``.
    """
    rng = np.random.default_rng(seed)
    model: HandModel = load_template() if proportions is None else build_template(proportions)
    landmark_corners, landmark_weights = anatomical_landmarks(model, LANDMARK_NAMES)
    if theta is None:
        theta = np.zeros(N_PARAMS)
        theta[N_GLOBAL:] = rng.normal(0.0, POSTURE_JITTER_RAD, N_PARAMS - N_GLOBAL)
    theta = np.asarray(theta, dtype=np.float64)
    vertices = skin_vertices(model, theta)
    _, joints = model.chain.joint_transforms(theta)

    points, normals = sample_surface(vertices, model.faces, n_points, rng)
    points = points + rng.normal(0.0, noise_mm, size=(n_points, 1)) * normals
    hole_centres = points[rng.choice(n_points, size=holes, replace=False)]
    hole_radii = rng.uniform(8.0, 15.0, size=holes)
    outside = np.all(np.linalg.norm(points[:, None] - hole_centres[None], axis=2) > hole_radii, axis=1)
    points, normals = points[outside], normals[outside]
    colors = _skin_colors(len(points), rng)

    lower, upper = vertices.min(axis=0), vertices.max(axis=0)
    n_outliers = int(round(outlier_share * len(points)))
    outlier_points = rng.uniform(lower, upper, size=(n_outliers, 3))
    outlier_normals = rng.normal(size=(n_outliers, 3))
    outlier_normals /= np.linalg.norm(outlier_normals, axis=1, keepdims=True)
    outlier_colors = rng.integers(0, 256, size=(n_outliers, 3), dtype=np.uint8)
    table_points, table_normals, table_colors = _table(background_points, lower, upper, rng)

    labels = np.concatenate([np.full(len(points), HAND), np.full(n_outliers, OUTLIER),
                             np.full(background_points, BACKGROUND)])
    order = rng.permutation(len(labels))
    scan = Scan(
        points=np.concatenate([points, outlier_points, table_points])[order],
        normals=np.concatenate([normals, outlier_normals, table_normals])[order],
        colors=np.concatenate([colors, outlier_colors, table_colors])[order],
    )
    truth = {
        "model": model,
        "theta": theta,
        "vertices": vertices,
        "joints": joints,
        "landmark_names": LANDMARK_NAMES,
        "landmarks": vertices[[model.landmarks[name] for name in LANDMARK_NAMES]],
        "landmark_points": np.einsum("lk,lka->la", landmark_weights, vertices[landmark_corners]),
        "labels": labels[order],
        "hole_centres": hole_centres,
    }
    return scan, truth


def anatomical_landmarks_from_truth(truth: dict) -> dict[str, np.ndarray | None]:
    """The exact anatomical landmark points (mm) of a synthetic scan's ``truth``, name -> (3,)."""
    return {name: np.array(point) for name, point in zip(truth["landmark_names"], truth["landmark_points"],
                                                         strict=True)}
