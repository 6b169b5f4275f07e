"""What a camera view shows of a take: the markers at a camera frame's mocap time, projected into the
image, and an overlay drawn on the frame (markers coloured by label, the selected one highlighted,
unlabelled points in grey, optionally the model's projected skeleton)."""

from __future__ import annotations

import colorsys

import cv2
import numpy as np

from handmocap.core.camera.model import Camera

UNLABELLED_BGR = (170, 170, 170)
SELECTED_BGR = (0, 255, 255)


def markers_at(positions: np.ndarray, mocap_frame: float) -> np.ndarray:
    """Marker positions ``(M,3)`` mm at a fractional mocap frame of ``positions (F,M,3)``: linear between the
    neighbouring frames, NaN where either is missing or outside the take."""
    last = positions.shape[0] - 1
    if not 0 <= mocap_frame <= last:
        return np.full(positions.shape[1:], np.nan)
    low = int(np.floor(mocap_frame))
    high, weight = min(low + 1, last), mocap_frame - low
    return (1 - weight) * positions[low] + weight * positions[high]


def project_take(camera: Camera, positions: np.ndarray, mocap_rate: float, camera_time: float) -> np.ndarray:
    """Pixels ``(M,2)`` (NaN = not shown) of the take's markers ``(F,M,3)`` at the mocap time of
    ``camera_time`` s (the camera's clock)."""
    return camera.project(markers_at(positions, float(camera.clock.mocap_frame(camera_time, mocap_rate))))


def label_colours(count: int) -> np.ndarray:
    """``(count,3)`` distinct BGR colours (uint8), one per label."""
    colours = [colorsys.hsv_to_rgb((0.61803 * index) % 1.0, 0.85, 1.0) for index in range(count)]
    return (np.array(colours)[:, ::-1] * 255).astype(np.uint8).reshape(-1, 3)


def draw_overlay(image: np.ndarray, pixels: np.ndarray, labelled: np.ndarray | None = None,
                 selected: int | None = None, skeleton: np.ndarray | None = None, radius: int = 5) -> np.ndarray:
    """A copy of ``image`` (BGR uint8, or a depth image in mm, shown in grey) with circles at ``pixels
    (M,2)``: coloured by label where ``labelled (M,)`` is True, grey otherwise, ``selected`` ringed in
    yellow; ``skeleton (B,2,2)`` px: bone segments drawn as lines."""
    canvas = _bgr(image)
    colours = label_colours(len(pixels))
    labelled = np.ones(len(pixels), dtype=bool) if labelled is None else labelled
    if skeleton is not None:
        for start, end in skeleton:
            if np.isfinite(start).all() and np.isfinite(end).all():
                cv2.line(canvas, _point(start), _point(end), (255, 255, 255), 1, cv2.LINE_AA, 4)
    for index, pixel in enumerate(pixels):
        if not np.isfinite(pixel).all() or np.abs(pixel).max() > 1e5:
            continue
        colour = tuple(int(c) for c in colours[index]) if labelled[index] else UNLABELLED_BGR
        cv2.circle(canvas, _point(pixel), radius * 16, colour, 2, cv2.LINE_AA, 4)
        if index == selected:
            cv2.circle(canvas, _point(pixel), (radius + 4) * 16, SELECTED_BGR, 2, cv2.LINE_AA, 4)
    return canvas


def _point(pixel: np.ndarray) -> tuple[int, int]:
    """Fixed-point (4 fractional bits) pixel for OpenCV's sub-pixel drawing."""
    return int(round(pixel[0] * 16)), int(round(pixel[1] * 16))


def _bgr(image: np.ndarray) -> np.ndarray:
    if image.ndim == 3:
        return image.copy()
    valid = image[image > 0]
    far = float(np.percentile(valid, 99)) if len(valid) else 1.0
    grey = np.clip(255.0 * (1.0 - image / max(far, 1e-6)), 0, 255) * (image > 0)
    return cv2.cvtColor(grey.astype(np.uint8), cv2.COLOR_GRAY2BGR)
