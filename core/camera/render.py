"""Z-buffer rendering of a triangle mesh into a pinhole camera (numba, no display): the depth (camera z,
mm) and the index of the visible face at every pixel. Distortion is not applied here (see
:func:`distort_image`); pixel centres are at integer coordinates as in OpenCV.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from numba import njit

from handmocap.core.camera.model import Camera

#: points nearer than this (mm, camera z) are clipped: their triangles are not drawn
NEAR_MM = 10.0


@njit(cache=True)
def _rasterise(points, faces, fx, fy, cx, cy, depth, face_index):  # pragma: no cover - numba
    height, width = depth.shape
    for t in range(faces.shape[0]):
        a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
        za, zb, zc = points[a, 2], points[b, 2], points[c, 2]
        if za < NEAR_MM or zb < NEAR_MM or zc < NEAR_MM:
            continue
        xa, ya = fx * points[a, 0] / za + cx, fy * points[a, 1] / za + cy
        xb, yb = fx * points[b, 0] / zb + cx, fy * points[b, 1] / zb + cy
        xc, yc = fx * points[c, 0] / zc + cx, fy * points[c, 1] / zc + cy
        area = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya)
        if abs(area) < 1e-12:
            continue
        left = max(int(np.ceil(min(xa, xb, xc))), 0)
        right = min(int(np.floor(max(xa, xb, xc))), width - 1)
        top = max(int(np.ceil(min(ya, yb, yc))), 0)
        bottom = min(int(np.floor(max(ya, yb, yc))), height - 1)
        for y in range(top, bottom + 1):
            for x in range(left, right + 1):
                wa = ((xb - x) * (yc - y) - (xc - x) * (yb - y)) / area
                wb = ((xc - x) * (ya - y) - (xa - x) * (yc - y)) / area
                wc = 1.0 - wa - wb
                if wa < 0.0 or wb < 0.0 or wc < 0.0:
                    continue
                z = 1.0 / (wa / za + wb / zb + wc / zc)
                if z < depth[y, x]:
                    depth[y, x] = z
                    face_index[y, x] = t


def render_mesh(camera: Camera, vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Render mocap-frame ``vertices (V,3)`` mm with ``faces (T,3)``: ``(depth (H,W) float32 mm, inf where
    empty; face (H,W) int32, -1 where empty)``."""
    points = np.ascontiguousarray(camera.to_camera(vertices))
    depth = np.full((camera.height, camera.width), np.inf, dtype=np.float32)
    face_index = np.full((camera.height, camera.width), -1, dtype=np.int32)
    (fx, fy), (cx, cy) = camera.focal, camera.principal_point
    _rasterise(points, np.ascontiguousarray(faces, dtype=np.int64), fx, fy, cx, cy, depth, face_index)
    return depth, face_index


def rasterise(points: np.ndarray, faces: np.ndarray, focal: tuple[float, float], principal: tuple[float, float],
              shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Z-buffer of camera-frame ``points (V,3)`` mm with ``faces (T,3) int64`` into an image of ``shape``
    (rows, columns) with pinhole ``focal`` and ``principal`` point (px; e.g. a crop or a reduced image):
    ``(depth (H,W) float32 mm, inf where empty; face (H,W) int32, -1 where empty)``."""
    depth = np.full(shape, np.inf, dtype=np.float32)
    face_index = np.full(shape, -1, dtype=np.int32)
    _rasterise(np.ascontiguousarray(points, dtype=np.float64), faces, float(focal[0]), float(focal[1]),
               float(principal[0]), float(principal[1]), depth, face_index)
    return depth, face_index


def shade(camera: Camera, vertices: np.ndarray, faces: np.ndarray, face_index: np.ndarray,
          colour: tuple[float, float, float], ambient: float = 0.35) -> tuple[np.ndarray, np.ndarray]:
    """Lambert shading with a light at the camera: ``(image (H,W,3) float32 BGR 0..255, mask (H,W) bool)``
    of the rendered faces ``face_index`` (from :func:`render_mesh`) in ``colour`` (BGR 0..255)."""
    points = camera.to_camera(vertices)
    corners = points[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    centres = corners.mean(axis=1)
    cosine = np.abs(np.einsum("ij,ij->i", normals, centres)) / (
        np.linalg.norm(normals, axis=1) * np.linalg.norm(centres, axis=1) + 1e-12)
    mask = face_index >= 0
    intensity = np.zeros(face_index.shape, dtype=np.float32)
    intensity[mask] = ambient + (1.0 - ambient) * cosine[face_index[mask]]
    return intensity[..., None] * np.asarray(colour, dtype=np.float32), mask


def distort_image(ideal: np.ndarray, camera: Camera, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
    """The image the distorted ``camera`` sees, from the ``ideal`` pinhole image (same intrinsic matrix);
    ``interpolation=cv2.INTER_NEAREST`` for depth and label images."""
    if not np.any(camera.distortion):
        return ideal
    map_x, map_y = _distortion_maps(camera)
    return cv2.remap(ideal, map_x, map_y, interpolation, borderMode=cv2.BORDER_REPLICATE)


@lru_cache(maxsize=8)
def _distortion_maps(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """For every pixel of the distorted image, where it comes from in the ideal image: ``(map_x, map_y)``."""
    columns, rows = np.meshgrid(np.arange(camera.width, dtype=np.float64), np.arange(camera.height, dtype=np.float64))
    pixels = np.column_stack([columns.ravel(), rows.ravel()])
    normalised = camera.undistort_pixels(pixels)
    (fx, fy), (cx, cy) = camera.focal, camera.principal_point
    map_x = (normalised[:, 0] * fx + cx).reshape(camera.height, camera.width).astype(np.float32)
    map_y = (normalised[:, 1] * fy + cy).reshape(camera.height, camera.width).astype(np.float32)
    return map_x, map_y
