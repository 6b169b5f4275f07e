"""Scan cleaning: keep skin-coloured points (Kovac et al. 2003) and drop statistical outliers."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from handmocap.core.calibration.nearest import nearest_neighbours
from handmocap.core.calibration.scan import Scan
from handmocap.core.errors import InputError

#: Kovac et al. 2003, uniform daylight: R > 95, G > 40, B > 20, max - min > 15, |R - G| > 15 (then R > G, R > B)
KOVAC_THRESHOLDS = np.array([95.0, 40.0, 20.0, 15.0, 15.0])
#: how much each threshold rises at ``strictness = 1``
STRICT_INCREMENTS = np.array([40.0, 20.0, 10.0, 20.0, 20.0])


def skin_mask(colors: np.ndarray, strictness: float = 0.0) -> np.ndarray:
    """True (N,) where the RGB colour (N,3, 0..255) is skin by the Kovac et al. 2003 daylight rule.

    ``strictness`` in 0..1 raises the thresholds linearly from the published values (0) to
    :data:`KOVAC_THRESHOLDS` + :data:`STRICT_INCREMENTS` (1); a stricter rule accepts a subset.
    """
    if not 0.0 <= strictness <= 1.0:
        raise InputError(f"skin strictness must be between 0 and 1, not {strictness}")
    rgb = np.asarray(colors, dtype=np.int32)
    red, green, blue = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    r_min, g_min, b_min, spread_min, rg_min = KOVAC_THRESHOLDS + strictness * STRICT_INCREMENTS
    spread = rgb.max(axis=1) - rgb.min(axis=1)
    return ((red > r_min) & (green > g_min) & (blue > b_min) & (spread > spread_min)
            & (np.abs(red - green) > rg_min) & (red > green) & (red > blue))


def statistical_outlier_mask(points: np.ndarray, k: int = 16, std_ratio: float = 2.0) -> np.ndarray:
    """True (N,) for outliers: points whose mean distance to their ``k`` nearest neighbours (mm) exceeds
    the mean of that distance over the cloud by more than ``std_ratio`` standard deviations."""
    if len(points) <= k:
        return np.zeros(len(points), dtype=bool)
    distances, _ = nearest_neighbours(cKDTree(points), points, k=k + 1)
    mean_distance = distances[:, 1:].mean(axis=1)
    return mean_distance > mean_distance.mean() + std_ratio * mean_distance.std()


def clean_scan(scan: Scan, strictness: float = 0.5, k: int = 16, std_ratio: float = 2.0) -> tuple[Scan, dict]:
    """Remove non-skin points (when the scan has colours), then statistical outliers.

    Returns the cleaned scan and a report: ``input_points``, ``non_skin_removed``, ``outliers_removed``,
    ``kept_points``, ``colour_filter`` (whether it ran).
    """
    report = {"input_points": len(scan), "colour_filter": scan.colors is not None, "non_skin_removed": 0}
    if scan.colors is not None:
        skin = skin_mask(scan.colors, strictness)
        report["non_skin_removed"] = int(np.count_nonzero(~skin))
        scan = scan.subset(skin)
    if len(scan) == 0:
        raise InputError("no skin points left after filtering")
    outliers = statistical_outlier_mask(scan.points, k, std_ratio)
    report["outliers_removed"] = int(np.count_nonzero(outliers))
    scan = scan.subset(~outliers)
    report["kept_points"] = len(scan)
    return scan, report
