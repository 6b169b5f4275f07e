"""A calibrated camera: pinhole intrinsics with OpenCV's distortion model, extrinsics to the mocap frame,
projection of 3D mocap points to pixels and back-projection of depth pixels to 3D mocap points.

Units: pixels for the image, mm for space. The mocap frame is Z up; a camera point is
``x_cam = rotation @ x_mocap + translation`` (OpenCV's camera frame: X right, Y down, Z forward).
Pixel coordinates follow OpenCV: the centre of the top-left pixel is (0, 0).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from handmocap.core.errors import InputError

#: OpenCV's distortion vectors have 4, 5, 8, 12 or 14 coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]])
DISTORTION_LENGTHS = (4, 5, 8, 12, 14)
#: largest image side accepted (pixels): larger is not a camera of this lab
MAX_IMAGE_SIDE = 16384


@dataclass(frozen=True)
class CameraClock:
    """Time mapping camera → mocap: ``mocap_time = rate_ratio * camera_time + offset_s`` (seconds).

    ``rate_ratio`` is 1 when both clocks run at the same speed; a camera frame's ``camera_time`` is its
    timestamp in the video (frame index / nominal frame rate)."""

    offset_s: float = 0.0
    rate_ratio: float = 1.0

    def mocap_time(self, camera_time: np.ndarray | float) -> np.ndarray | float:
        """Mocap time(s) in s of camera time(s) in s."""
        return self.rate_ratio * np.asarray(camera_time, dtype=float) + self.offset_s

    def camera_time(self, mocap_time: np.ndarray | float) -> np.ndarray | float:
        """Camera time(s) in s of mocap time(s) in s."""
        return (np.asarray(mocap_time, dtype=float) - self.offset_s) / self.rate_ratio

    def mocap_frame(self, camera_time: np.ndarray | float, mocap_rate: float) -> np.ndarray | float:
        """Fractional 0-based mocap frame(s) at camera time(s) in s, for a take at ``mocap_rate`` Hz."""
        return self.mocap_time(camera_time) * mocap_rate


@dataclass(frozen=True, eq=False)
class Camera:
    """Intrinsics ``matrix (3,3)`` px, ``distortion (D,)`` (OpenCV order), image ``size`` (width, height) px;
    extrinsics ``rotation (3,3)`` and ``translation (3,)`` mm mapping mocap to camera points; ``clock``;
    ``registered`` is False until the extrinsics are known (then rotation is the identity)."""

    matrix: np.ndarray
    distortion: np.ndarray
    size: tuple[int, int]
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    clock: CameraClock = field(default_factory=CameraClock)
    registered: bool = False
    name: str = "camera"

    def __post_init__(self) -> None:
        matrix = np.asarray(self.matrix, dtype=float)
        distortion = np.asarray(self.distortion, dtype=float).ravel()
        rotation = np.asarray(self.rotation, dtype=float)
        translation = np.asarray(self.translation, dtype=float).ravel()
        problems = []
        if matrix.shape != (3, 3) or not np.isfinite(matrix).all():
            problems.append("the camera matrix must be 3×3 finite numbers")
        elif not (matrix[0, 0] > 0 and matrix[1, 1] > 0 and np.allclose(matrix[2], [0, 0, 1])
                  and matrix[1, 0] == 0):
            problems.append("the camera matrix must have positive focal lengths and a last row 0 0 1")
        if len(distortion) not in (0, *DISTORTION_LENGTHS) or not np.isfinite(distortion).all():
            problems.append(f"distortion must have 0, 4, 5, 8, 12 or 14 finite coefficients, got {len(distortion)}")
        width, height = (int(v) for v in self.size)
        if not (0 < width <= MAX_IMAGE_SIDE and 0 < height <= MAX_IMAGE_SIDE):
            problems.append(f"image size must be within 1..{MAX_IMAGE_SIDE} px, got {width}×{height}")
        if rotation.shape != (3, 3) or not np.isfinite(rotation).all() or \
                not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6) or np.linalg.det(rotation) <= 0:
            problems.append("the rotation must be a 3×3 rotation matrix")
        if translation.shape != (3,) or not np.isfinite(translation).all():
            problems.append("the translation must be 3 finite numbers (mm)")
        if not (np.isfinite(self.clock.offset_s) and np.isfinite(self.clock.rate_ratio)
                and 0.5 < self.clock.rate_ratio < 2.0):
            problems.append("the clock needs a finite offset and a rate ratio within 0.5..2")
        if problems:
            raise InputError(f"camera '{self.name}': " + "; ".join(problems))
        for name, value in (("matrix", matrix), ("distortion", distortion), ("rotation", rotation),
                            ("translation", translation)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "size", (width, height))

    @property
    def width(self) -> int:
        return self.size[0]

    @property
    def height(self) -> int:
        return self.size[1]

    @property
    def focal(self) -> tuple[float, float]:
        """(fx, fy) px."""
        return float(self.matrix[0, 0]), float(self.matrix[1, 1])

    @property
    def principal_point(self) -> tuple[float, float]:
        """(cx, cy) px."""
        return float(self.matrix[0, 2]), float(self.matrix[1, 2])

    @property
    def centre(self) -> np.ndarray:
        """Optical centre (3,) in mocap mm."""
        return -self.rotation.T @ self.translation

    @property
    def rotation_vector(self) -> np.ndarray:
        """Rodrigues vector (3,) of :attr:`rotation` (for OpenCV calls)."""
        return cv2.Rodrigues(self.rotation)[0].ravel()

    def with_pose(self, rotation: np.ndarray, translation: np.ndarray) -> Camera:
        """This camera registered at ``rotation (3,3)`` / ``translation (3,)`` mm (mocap → camera)."""
        return replace(self, rotation=rotation, translation=translation, registered=True)

    def with_clock(self, clock: CameraClock) -> Camera:
        return replace(self, clock=clock)

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """Mocap points ``(N,3)`` mm → camera-frame points ``(N,3)`` mm."""
        return np.asarray(points, dtype=float).reshape(-1, 3) @ self.rotation.T + self.translation

    def to_mocap(self, points: np.ndarray) -> np.ndarray:
        """Camera-frame points ``(N,3)`` mm → mocap points ``(N,3)`` mm."""
        return (np.asarray(points, dtype=float).reshape(-1, 3) - self.translation) @ self.rotation

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels ``(N,2)`` of mocap points ``(N,3)`` mm, distortion applied; NaN for points that are NaN
        or not in front of the camera."""
        return self.project_camera_points(self.to_camera(points))

    def project_camera_points(self, points: np.ndarray) -> np.ndarray:
        """Pixels ``(N,2)`` of camera-frame points ``(N,3)`` mm; NaN where NaN or z ≤ 0."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        pixels = np.full((len(points), 2), np.nan)
        front = np.isfinite(points).all(axis=1) & (points[:, 2] > 1e-6)
        if front.any():
            projected, _ = cv2.projectPoints(points[front], np.zeros(3), np.zeros(3), self.matrix,
                                             self.distortion if len(self.distortion) else None)
            pixels[front] = projected.reshape(-1, 2)
        return pixels

    def undistort_pixels(self, pixels: np.ndarray) -> np.ndarray:
        """Normalised image coordinates ``(N,2)`` (x/z, y/z) of distorted pixels ``(N,2)``."""
        pixels = np.asarray(pixels, dtype=float).reshape(-1, 1, 2)
        if len(pixels) == 0:
            return np.zeros((0, 2))
        distortion = self.distortion if len(self.distortion) else None
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-10)
        return cv2.undistortPoints(pixels, self.matrix, distortion, R=None, P=None, criteria=criteria).reshape(-1, 2)

    def rays(self, pixels: np.ndarray) -> np.ndarray:
        """Camera-frame viewing directions ``(N,3)`` with z = 1 of pixels ``(N,2)``."""
        normalised = self.undistort_pixels(pixels)
        return np.column_stack([normalised, np.ones(len(normalised))])

    def back_project(self, pixels: np.ndarray, depth_mm: np.ndarray) -> np.ndarray:
        """Mocap points ``(N,3)`` mm of pixels ``(N,2)`` whose depth (camera z, as a depth camera reports it)
        is ``depth_mm (N,)``."""
        depth = np.asarray(depth_mm, dtype=float).reshape(-1, 1)
        return self.to_mocap(self.rays(pixels) * depth)

    def back_project_depth(self, depth_mm: np.ndarray, step: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Back-project a depth image ``(H,W)`` in mm (0 or NaN = no depth) sampled every ``step`` pixels:
        ``(points (N,3) mocap mm, pixels (N,2))`` of the pixels with depth."""
        depth = np.asarray(depth_mm, dtype=float)
        if depth.shape != (self.height, self.width):
            raise InputError(f"depth image is {depth.shape[1]}×{depth.shape[0]} px but camera '{self.name}' "
                             f"is {self.width}×{self.height}")
        rows, columns = np.mgrid[0:self.height:step, 0:self.width:step]
        values = depth[rows, columns]
        valid = np.isfinite(values) & (values > 0)
        pixels = np.column_stack([columns[valid], rows[valid]]).astype(float)
        return self.back_project(pixels, values[valid]), pixels


def rotation_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle in degrees of the rotation between rotation matrices ``a`` and ``b`` (3,3)."""
    cosine = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))
