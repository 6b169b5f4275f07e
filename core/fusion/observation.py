"""One RGB-D frame prepared for the energy: the crop around the hand, the observed silhouette, depth and edge
maps on it, the distance transform of the observed edges, and the frame's markers.

Images are first brought to the ideal pinhole (lens distortion removed with ``cv2.remap``; nearest sample for
depth) so that the renderer needs no distortion. Colour edges are Canny edges (thresholds from the window's
median gradient) near the silhouette; without colour the observed edges are the depth image's (as rendered).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from handmocap.core.camera.model import Camera
from handmocap.core.fusion.hand_render import MIDDLE_MCP, Crop, HandRenderer, crop_around, distance_to, edge_map
from handmocap.core.fusion.silhouette import band_cut, colour_silhouette, cut_at_wrist, depth_silhouette, wristband_line

#: the colour silhouette is replaced by the depth one when it covers less than this share of the model's
#: projected area (colour too poor: hand over a hand-coloured background, bad light)
MIN_COLOUR_COVERAGE = 0.3


@dataclass
class Observation:
    """Observed data of one frame on ``crop``: ``silhouette (h,w) bool``, ``depth (h,w) float32`` mm (0 = none),
    ``edges (h,w) bool`` and ``edge_distance (h,w) float32`` (crop samples), ``markers (M,3)`` mm mocap frame in
    layout order (NaN = not seen), ``source`` of the silhouette ("colour" or "depth")."""

    crop: Crop
    silhouette: np.ndarray
    depth: np.ndarray
    edges: np.ndarray
    edge_distance: np.ndarray
    markers: np.ndarray
    source: str

    def depth_points(self, camera: Camera, count: int) -> np.ndarray:
        """Up to ``count`` observed hand points (N,3) mm in the mocap frame, evenly spread over the silhouette."""
        rows, columns = np.nonzero(self.silhouette & (self.depth > 0))
        if len(rows) > count:
            keep = np.linspace(0, len(rows) - 1, count).astype(int)
            rows, columns = rows[keep], columns[keep]
        (fx, fy), (cx, cy) = self.crop.intrinsics(camera)
        z = self.depth[rows, columns].astype(float)
        points = np.column_stack([(columns - cx) / fx * z, (rows - cy) / fy * z, z])
        return camera.to_mocap(points)


@lru_cache(maxsize=4)
def _undistortion_maps(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    return cv2.initUndistortRectifyMap(camera.matrix, camera.distortion, None, camera.matrix, camera.size,
                                       cv2.CV_32FC1)


def ideal_image(image: np.ndarray, camera: Camera, nearest: bool = False) -> np.ndarray:
    """``image`` as the distortion-free pinhole of the same intrinsic matrix would see it."""
    if not np.any(camera.distortion):
        return np.asarray(image)
    map_x, map_y = _undistortion_maps(camera)
    return cv2.remap(np.asarray(image), map_x, map_y, cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR)


def _canny(colour: np.ndarray, near: np.ndarray) -> np.ndarray:
    grey = cv2.cvtColor(colour, cv2.COLOR_BGR2GRAY)
    gradient = np.hypot(cv2.Sobel(grey, cv2.CV_32F, 1, 0), cv2.Sobel(grey, cv2.CV_32F, 0, 1))
    level = float(np.median(gradient[near])) if near.any() else 50.0
    return (cv2.Canny(grey, max(level, 20.0), max(2.5 * level, 50.0), L2gradient=True) > 0) & near


def _reduce(mask: np.ndarray, crop: Crop) -> np.ndarray:
    """A full-resolution window mask on the crop's samples: a sample is set when any pixel of its block is."""
    if crop.stride == 1:
        return mask[:crop.rows, :crop.columns].copy()
    padded = np.zeros((crop.rows * crop.stride, crop.columns * crop.stride), dtype=bool)
    padded[:mask.shape[0], :mask.shape[1]] = mask
    return np.asarray(padded.reshape(crop.rows, crop.stride, crop.columns, crop.stride).any(axis=(1, 3)), dtype=bool)


def _majority(mask: np.ndarray, crop: Crop) -> np.ndarray:
    """A full-resolution window mask on the crop's samples: a sample is set when most of its block is."""
    padded = np.zeros((crop.rows * crop.stride, crop.columns * crop.stride), dtype=np.float32)
    padded[:mask.shape[0], :mask.shape[1]] = mask
    return padded.reshape(crop.rows, crop.stride, crop.columns, crop.stride).mean(axis=(1, 3)) >= 0.5


def observe(renderer: HandRenderer, guess: np.ndarray, depth: np.ndarray, colour: np.ndarray | None,
            background: np.ndarray | None, markers: np.ndarray, wristband_hue: tuple[int, int] | None = None,
            max_side: int = 96, cut_wrist: bool = True, include: np.ndarray | None = None,
            segmented: np.ndarray | None = None) -> Observation:
    """The observation of one frame. ``guess (26,)``: a predicted pose (from the markers) that places the crop,
    the GrabCut initialisation and the wrist cut; ``depth (H,W)`` mm and ``colour (H,W,3)`` / ``background``
    ideal images (see :func:`ideal_image`); ``markers (M,3)`` mm; ``cut_wrist``: cut the arm at the guess's wrist
    when no wristband is seen; ``include (N,2)`` px: image points the crop must hold too; ``segmented (H,W)``
    bool: the hand's pixels found beforehand (:func:`core.fusion.hand_segment.find_hands`) instead of the depth
    band around the guess."""
    camera = renderer.camera
    pixels = renderer.pixels(guess)
    crop = crop_around(pixels if include is None else np.vstack([pixels, include]), camera, max_side=max_side)
    full = Crop(crop.left, crop.top, crop.rows * crop.stride, crop.columns * crop.stride, 1)
    model = renderer.render(guess, full, with_edges=False)
    depth_window = full.window(depth)
    height, width = depth_window.shape
    model_mask = model.silhouette[:height, :width]
    model_depth = model.depth[:height, :width]
    rotations, positions = renderer.model.chain.joint_transforms(guess)
    wrist, knuckle = camera.project(positions[[0, MIDDLE_MCP]]) - [crop.left, crop.top]
    towards_fingers = knuckle - wrist
    source = "depth"
    if segmented is None:
        silhouette = depth_silhouette(depth_window, model_depth)
    else:
        silhouette = full.window(segmented) & (depth_window > 0)
    if colour is not None and background is not None:
        colour_window = full.window(colour)
        from_colour = colour_silhouette(np.ascontiguousarray(colour_window), np.ascontiguousarray(
            full.window(background)), model_mask)
        if from_colour.sum() >= MIN_COLOUR_COVERAGE * max(model_mask.sum(), 1):
            silhouette, source = from_colour, "colour"
    band = None
    if colour is not None and wristband_hue is not None:
        band = wristband_line(np.ascontiguousarray(full.window(colour)), wristband_hue,
                              cv2.dilate(model_mask.astype(np.uint8), np.ones((15, 15), np.uint8)).astype(bool))
    if band is not None:
        silhouette = band_cut(silhouette, band[0], band[1], towards_fingers)
    elif cut_wrist:
        silhouette = cut_at_wrist(silhouette, wrist, towards_fingers)
    if source == "colour":
        assert colour is not None  # the colour silhouette needs the colour image
        near = cv2.dilate(silhouette.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
        edges = _reduce(_canny(np.ascontiguousarray(full.window(colour)), near), crop)
    else:
        edges = None
    crop_silhouette = _majority(silhouette, crop)
    crop_depth = crop.take(depth).astype(np.float32)
    if edges is None:
        edges = edge_map(np.where(crop_depth > 0, crop_depth, np.inf), crop_silhouette)
    return Observation(crop, crop_silhouette, np.where(crop_silhouette, crop_depth, 0.0).astype(np.float32),
                       edges, distance_to(edges), np.asarray(markers, float), source)
