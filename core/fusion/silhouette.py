"""Hand silhouette extraction (Zhao et al. §5.1): background subtraction locates the hand, OpenCV's GrabCut
(graph cut with colour GMMs) refines it, the arm is cut at a coloured wristband when one is seen, else at the
model's wrist. Depth-based segmentation is the alternative when colour is poor (or absent).

All images are full ideal (undistorted) images or full-resolution crop windows of them; masks are bool.
"""

from __future__ import annotations

import cv2
import numpy as np

#: background subtraction: a pixel differs when its largest channel difference exceeds this many robust
#: standard deviations (1.4826 × MAD) of the difference over the image (most pixels are background) …
SUBTRACTION_SIGMAS = 6.0
#: … and at least this (8-bit levels): sensor noise alone (σ ≈ 2 levels) never reaches it
MIN_SUBTRACTION_LEVELS = 12.0
GRABCUT_ITERATIONS = 3
#: a wristband needs at least this many pixels (a 20 mm band 600 mm away is ~ 300 px)
MIN_WRISTBAND_PIXELS = 40
#: depth segmentation: pixels within this depth (mm) of the nearest surface belong to the nearest object; a
#: hand seen from the front spans < 80 mm in depth, and a body behind an outstretched hand is ≥ 100 mm back
NEAREST_BAND_MM = 100.0


def subtract_background(colour: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Pixels (H,W) bool that differ from the ``background`` image (both (H,W,3) uint8), opened and closed."""
    difference = np.abs(colour.astype(np.float32) - background.astype(np.float32)).max(axis=2)
    median = float(np.median(difference))
    spread = 1.4826 * float(np.median(np.abs(difference - median)))
    foreground = difference > max(median + SUBTRACTION_SIGMAS * spread, MIN_SUBTRACTION_LEVELS)
    kernel = np.ones((3, 3), np.uint8)
    foreground = cv2.morphologyEx(foreground.astype(np.uint8), cv2.MORPH_OPEN, kernel)
    return cv2.morphologyEx(foreground, cv2.MORPH_CLOSE, kernel).astype(bool)


def grabcut(colour: np.ndarray, sure: np.ndarray, likely: np.ndarray, possible: np.ndarray) -> np.ndarray:
    """GrabCut of ``colour (H,W,3) uint8`` initialised from masks: ``sure`` foreground, ``likely`` (probable)
    foreground, ``possible`` (probable background; everything else is sure background). Returns (H,W) bool;
    the initial foreground when GrabCut cannot run (no foreground or no background pixel)."""
    mask = np.full(colour.shape[:2], cv2.GC_BGD, np.uint8)
    mask[possible] = cv2.GC_PR_BGD
    mask[likely] = cv2.GC_PR_FGD
    mask[sure] = cv2.GC_FGD
    foreground = (mask == cv2.GC_FGD) | (mask == cv2.GC_PR_FGD)
    if foreground.sum() < 10 or (~foreground).sum() < 10:
        return foreground
    background_model, foreground_model = np.zeros((1, 65)), np.zeros((1, 65))
    try:
        # the stubs require a rect, but OpenCV takes None with GC_INIT_WITH_MASK
        cv2.grabCut(colour, mask, None, background_model, foreground_model, GRABCUT_ITERATIONS,  # type: ignore[call-overload]
                    cv2.GC_INIT_WITH_MASK)
    except cv2.error:
        return foreground
    return (mask == cv2.GC_FGD) | (mask == cv2.GC_PR_FGD)


def colour_silhouette(colour: np.ndarray, background: np.ndarray, model_mask: np.ndarray) -> np.ndarray:
    """Hand silhouette (H,W) bool in a colour window: background subtraction, then GrabCut with the
    subtraction ∧ the (dilated) projected model as probable foreground, their overlap eroded as sure
    foreground, and a band around the model as probable background."""
    subtracted = subtract_background(colour, background)
    size = max(3, int(0.08 * max(model_mask.shape)) | 1)
    near_model = cv2.dilate(model_mask.astype(np.uint8), np.ones((size, size), np.uint8)).astype(bool)
    likely = subtracted & near_model
    sure = cv2.erode((likely & model_mask).astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    wide = cv2.dilate(near_model.astype(np.uint8), np.ones((size, size), np.uint8)).astype(bool)
    return largest_component(grabcut(colour, sure, likely, wide | subtracted) & wide)


def largest_component(mask: np.ndarray) -> np.ndarray:
    """The largest 8-connected component of ``mask`` (all False when empty)."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if count <= 1:
        return np.zeros(mask.shape, dtype=bool)
    return labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))


def wristband_line(colour: np.ndarray, hue_range: tuple[int, int], near: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray] | None:
    """``(centre (2,), axis (2,))`` px of a coloured wristband (OpenCV hue ``hue_range`` 0..180, saturated) among
    the ``near`` pixels: the band's centroid and its long axis; None when too few band pixels are seen."""
    hsv = cv2.cvtColor(colour, cv2.COLOR_BGR2HSV)
    low, high = hue_range
    hue = hsv[..., 0]
    inside = (hue >= low) & (hue <= high) if low <= high else (hue >= low) | (hue <= high)
    band = inside & (hsv[..., 1] > 120) & (hsv[..., 2] > 60) & near
    rows, columns = np.nonzero(band)
    if len(rows) < MIN_WRISTBAND_PIXELS:
        return None
    points = np.column_stack([columns, rows]).astype(float)
    centre = points.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((points - centre).T))
    return centre, vectors[:, 1]


def cut_at_wrist(mask: np.ndarray, wrist: np.ndarray, towards_fingers: np.ndarray, margin_px: float = 0.0
                 ) -> np.ndarray:
    """``mask`` without the pixels behind the wrist: those whose offset from ``wrist (2,)`` px has a component
    along ``towards_fingers (2,)`` below ``-margin_px``."""
    direction = towards_fingers / max(float(np.linalg.norm(towards_fingers)), 1e-9)
    rows, columns = np.indices(mask.shape)
    along = (columns - wrist[0]) * direction[0] + (rows - wrist[1]) * direction[1]
    return mask & (along >= -margin_px)


def band_cut(mask: np.ndarray, centre: np.ndarray, band_axis: np.ndarray, towards_fingers: np.ndarray
             ) -> np.ndarray:
    """``mask`` cut along a wristband: the band's normal (perpendicular to its long axis ``band_axis``), oriented
    towards the fingers, through its ``centre``."""
    normal = np.array([-band_axis[1], band_axis[0]])
    if normal @ towards_fingers < 0:
        normal = -normal
    return cut_at_wrist(mask, centre, normal)


def depth_silhouette(depth: np.ndarray, model_depth: np.ndarray | None = None, band_mm: float = NEAREST_BAND_MM
                     ) -> np.ndarray:
    """Hand silhouette (H,W) bool from depth (mm, 0 = none). With the rendered ``model_depth`` (inf off the
    model) of a predicted pose: the valid pixels within ``band_mm`` of the model's depth range near the model;
    without: the nearest object (pixels within ``band_mm`` of the 1st depth percentile), largest component."""
    valid = depth > 0
    if not valid.any():
        return np.zeros(depth.shape, dtype=bool)
    if model_depth is None or not np.isfinite(model_depth).any():
        nearest = float(np.percentile(depth[valid], 1.0))
        return largest_component(valid & (depth < nearest + band_mm))
    on_model = np.isfinite(model_depth)
    low, high = float(model_depth[on_model].min()), float(model_depth[on_model].max())
    size = max(3, int(0.1 * max(depth.shape)) | 1)
    near = cv2.dilate(on_model.astype(np.uint8), np.ones((size, size), np.uint8)).astype(bool)
    return valid & near & (depth > low - band_mm / 2) & (depth < high + band_mm / 2)
