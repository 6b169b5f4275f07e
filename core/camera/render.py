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
def fill_triangles(pixels, depth, faces, perspective, centre, tolerance, near, zbuffer, face_index, values,
                   image):  # pragma: no cover - numba
    """Z-buffered fill of the triangles ``faces (T,3)`` whose corners stand at ``pixels (V,2)`` (x right, y
    down; the pixel ``(x, y)`` is sampled at ``(x + centre, y + centre)``) with ``depth (V,)``: a pixel is
    the triangle's when none of its barycentric weights is below ``-tolerance`` and it is nearer than
    ``zbuffer (H,W)``; it then gets the depth, the face's index in ``face_index (H,W)`` and, when
    ``image (H,W)`` is not empty, the corners' ``values (V,)`` interpolated. ``perspective``: the depth is
    a camera z, interpolated as 1/z (pinhole), else linearly (orthographic). Triangles with a corner
    nearer than ``near`` are not drawn."""
    height, width = zbuffer.shape
    shaded = image.size > 0
    for t in range(faces.shape[0]):
        a, b, c = faces[t, 0], faces[t, 1], faces[t, 2]
        za, zb, zc = depth[a], depth[b], depth[c]
        if za < near or zb < near or zc < near:
            continue
        xa, ya, xb, yb, xc, yc = pixels[a, 0], pixels[a, 1], pixels[b, 0], pixels[b, 1], pixels[c, 0], pixels[c, 1]
        area = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya)
        if abs(area) < 1e-12:
            continue
        left = max(int(np.ceil(min(xa, xb, xc) - centre)), 0)
        right = min(int(np.floor(max(xa, xb, xc) - centre)), width - 1)
        top = max(int(np.ceil(min(ya, yb, yc) - centre)), 0)
        bottom = min(int(np.floor(max(ya, yb, yc) - centre)), height - 1)
        for y in range(top, bottom + 1):
            py = y + centre
            for x in range(left, right + 1):
                px = x + centre
                wa = ((xb - px) * (yc - py) - (xc - px) * (yb - py)) / area
                wb = ((xc - px) * (ya - py) - (xa - px) * (yc - py)) / area
                wc = 1.0 - wa - wb
                if wa < -tolerance or wb < -tolerance or wc < -tolerance:
                    continue
                z = 1.0 / (wa / za + wb / zb + wc / zc) if perspective else wa * za + wb * zb + wc * zc
                if z < zbuffer[y, x]:
                    zbuffer[y, x] = z
                    face_index[y, x] = t
                    if shaded:
                        image[y, x] = wa * values[a] + wb * values[b] + wc * values[c]


_NO_VALUES = np.empty(0)
_NO_IMAGE = np.empty((0, 0), dtype=np.float32)


def _pinhole(points: np.ndarray, faces: np.ndarray, fx: float, fy: float, cx: float, cy: float, depth: np.ndarray,
             face_index: np.ndarray) -> None:
    """Z-buffer camera-frame ``points (V,3)`` float64 through a pinhole into ``depth`` and ``face_index``."""
    z = points[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):                # corners behind NEAR_MM are not drawn
        pixels = np.column_stack([fx * points[:, 0] / z + cx, fy * points[:, 1] / z + cy])
    fill_triangles(pixels, np.ascontiguousarray(z), faces, True, 0.0, 0.0, NEAR_MM, depth, face_index, _NO_VALUES,
                   _NO_IMAGE)


def render_mesh(camera: Camera, vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Render mocap-frame ``vertices (V,3)`` mm with ``faces (T,3)``: ``(depth (H,W) float32 mm, inf where
    empty; face (H,W) int32, -1 where empty)``."""
    points = np.ascontiguousarray(camera.to_camera(vertices))
    depth = np.full((camera.height, camera.width), np.inf, dtype=np.float32)
    face_index = np.full((camera.height, camera.width), -1, dtype=np.int32)
    (fx, fy), (cx, cy) = camera.focal, camera.principal_point
    _pinhole(points, np.ascontiguousarray(faces, dtype=np.int64), fx, fy, cx, cy, depth, face_index)
    return depth, face_index


def rasterise(points: np.ndarray, faces: np.ndarray, focal: tuple[float, float], principal: tuple[float, float],
              shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Z-buffer of camera-frame ``points (V,3)`` mm with ``faces (T,3) int64`` into an image of ``shape``
    (rows, columns) with pinhole ``focal`` and ``principal`` point (px; e.g. a crop or a reduced image):
    ``(depth (H,W) float32 mm, inf where empty; face (H,W) int32, -1 where empty)``."""
    depth = np.full(shape, np.inf, dtype=np.float32)
    face_index = np.full(shape, -1, dtype=np.int32)
    _pinhole(np.ascontiguousarray(points, dtype=np.float64), faces, float(focal[0]), float(focal[1]),
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
