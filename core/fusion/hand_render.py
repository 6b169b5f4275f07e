"""Rendering of a hypothesised hand pose into the camera on a crop around the hand (Zhao et al. §5.2):
depth map, silhouette and edge map of the skinned subject model, and distance transforms of edge maps.

A :class:`Crop` is a window of the ideal (undistorted) image sampled every ``stride`` pixels: crop pixel
``(row, column)`` is image pixel ``(top + stride·row, left + stride·column)``, so the crop is a pinhole
image of focal ``f / stride`` and principal point ``((c - left) / stride, ...)``. Distances measured on a
crop are given back in image pixels (× ``stride``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from handmocap.core.camera.model import Camera
from handmocap.core.camera.render import rasterise
from handmocap.core.model import HandModel
from handmocap.core.model.kinematics import skinned_points_kernel
from handmocap.core.model.skeleton import JOINT_NAMES

#: a rendered pixel is an edge when its 4-neighbour differs in depth by more than this (mm): an occluding
#: contour inside the silhouette (a finger over the palm); a finger is ≥ 12 mm thick
DEPTH_EDGE_MM = 10.0
MIDDLE_MCP = JOINT_NAMES.index("middle_mcp")


@dataclass(frozen=True)
class Crop:
    """A window ``left, top`` (image px) of ``rows × columns`` samples every ``stride`` px."""

    left: int
    top: int
    rows: int
    columns: int
    stride: int

    @property
    def shape(self) -> tuple[int, int]:
        return self.rows, self.columns

    def intrinsics(self, camera: Camera) -> tuple[tuple[float, float], tuple[float, float]]:
        """``(focal, principal point)`` px of the crop's pinhole."""
        (fx, fy), (cx, cy) = camera.focal, camera.principal_point
        return (fx / self.stride, fy / self.stride), ((cx - self.left) / self.stride, (cy - self.top) / self.stride)

    def take(self, image: np.ndarray) -> np.ndarray:
        """The crop's samples of a full ideal image ``(H,W[,C])`` (nearest sample, no filtering)."""
        return np.ascontiguousarray(image[self.top:self.top + self.rows * self.stride:self.stride,
                                          self.left:self.left + self.columns * self.stride:self.stride])

    def window(self, image: np.ndarray) -> np.ndarray:
        """The full-resolution window of ``image`` the crop covers."""
        return image[self.top:self.top + self.rows * self.stride, self.left:self.left + self.columns * self.stride]


def crop_around(pixels: np.ndarray, camera: Camera, margin: float = 0.25, max_side: int = 96) -> Crop:
    """A crop around image ``pixels (N,2)`` (e.g. the projected model) widened by ``margin`` of its size on
    each side, clipped to the image, with the smallest stride that keeps both sides ≤ ``max_side`` samples."""
    finite = pixels[np.isfinite(pixels).all(axis=1)]
    low, high = finite.min(axis=0), finite.max(axis=0)
    pad = margin * (high - low).max() + 4.0
    left, top = (int(max(np.floor(value - pad), 0)) for value in low)
    right = int(min(np.ceil(high[0] + pad), camera.width - 1))
    bottom = int(min(np.ceil(high[1] + pad), camera.height - 1))
    right, bottom = max(right, left), max(bottom, top)
    stride = max(1, int(np.ceil(max(right - left + 1, bottom - top + 1) / max_side)))
    return Crop(left, top, (bottom - top) // stride + 1, (right - left) // stride + 1, stride)


@dataclass
class Rendering:
    """One rendered hypothesis on a crop: ``depth (h,w) float32`` mm (inf = background), ``face (h,w)``
    (-1 = background), ``silhouette (h,w) bool``, ``edges (h,w) bool`` (outline and occluding contours),
    ``points (V,3)`` camera-frame mm of the posed vertices."""

    depth: np.ndarray
    face: np.ndarray
    silhouette: np.ndarray
    edges: np.ndarray
    points: np.ndarray


def edge_map(depth: np.ndarray, silhouette: np.ndarray, jump_mm: float = DEPTH_EDGE_MM) -> np.ndarray:
    """Edges (h,w) bool of a depth image (inf = none): the silhouette's outline and depth jumps over ``jump_mm``
    between neighbours inside it that both have depth."""
    mask = silhouette.astype(np.uint8)
    outline = silhouette & (cv2.erode(mask, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT,
                                      borderValue=0) == 0)
    known = silhouette & np.isfinite(depth)
    values = np.where(known, depth, 0.0).astype(np.float32)
    jump = np.zeros(depth.shape, dtype=bool)
    jump[:, 1:] |= (np.abs(np.diff(values, axis=1)) > jump_mm) & known[:, 1:] & known[:, :-1]
    jump[1:, :] |= (np.abs(np.diff(values, axis=0)) > jump_mm) & known[1:, :] & known[:-1, :]
    return outline | (jump & silhouette)


def distance_to(edges: np.ndarray) -> np.ndarray:
    """Distance (h,w) float32 in crop samples from every pixel to the nearest edge pixel (``cv2.distanceTransform``,
    exact L2); a large constant where there is no edge at all."""
    if not edges.any():
        return np.full(edges.shape, float(sum(edges.shape)), dtype=np.float32)
    return cv2.distanceTransform((~edges).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)


def hand_faces(model: HandModel) -> np.ndarray:
    """The faces (T,3) int64 of the hand proper: those whose rest centroid lies beyond the wrist joint along the
    wrist → middle knuckle axis (the forearm stub is cut as the observed silhouette is cut at the wrist)."""
    wrist = model.skeleton.rest_positions[0]
    axis = model.skeleton.rest_positions[MIDDLE_MCP] - wrist
    centroids = np.asarray(model.vertices)[model.faces].mean(axis=1)
    keep = (centroids - wrist) @ (axis / np.linalg.norm(axis)) >= 0.0
    return np.ascontiguousarray(model.faces[keep], dtype=np.int64)


class HandRenderer:
    """Poses the subject model (linear blend skinning, numba) and renders it into ``camera`` on a crop."""

    def __init__(self, model: HandModel, camera: Camera) -> None:
        self.model, self.camera = model, camera
        self.faces = hand_faces(model)
        self.influence_joints = np.ascontiguousarray(model.skin_joints, dtype=np.int64)
        self.influence_weights = np.ascontiguousarray(model.skin_weights, dtype=np.float64)
        self.local_points = model.chain.local_coordinates(np.asarray(model.vertices, float), self.influence_joints)

    def vertices(self, theta: np.ndarray) -> np.ndarray:
        """Posed vertices (V,3) mm, mocap frame."""
        rotations, positions = self.model.chain.joint_transforms(theta)
        return skinned_points_kernel(rotations, positions, self.influence_joints, self.influence_weights,
                                     self.local_points)

    def camera_points(self, theta: np.ndarray) -> np.ndarray:
        """Posed vertices (V,3) mm in the camera frame."""
        return self.camera.to_camera(self.vertices(theta))

    def pixels(self, theta: np.ndarray) -> np.ndarray:
        """Ideal (undistorted) image positions (V,2) px of the posed vertices."""
        points = self.camera_points(theta)
        (fx, fy), (cx, cy) = self.camera.focal, self.camera.principal_point
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.column_stack([fx * points[:, 0] / points[:, 2] + cx, fy * points[:, 1] / points[:, 2] + cy])

    def render(self, theta: np.ndarray, crop: Crop, with_edges: bool = True) -> Rendering:
        """Depth, silhouette and (``with_edges``) edge map of the pose ``theta (26,)`` on ``crop``."""
        points = self.camera_points(theta)
        focal, principal = crop.intrinsics(self.camera)
        depth, face = rasterise(points, self.faces, focal, principal, crop.shape)
        silhouette = face >= 0
        edges = edge_map(depth, silhouette) if with_edges else np.zeros(0, dtype=bool)
        return Rendering(depth, face, silhouette, edges, points)
