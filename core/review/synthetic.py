"""A small synthetic labelled take for tests and demos of the review (no hand model needed).

``synthetic_labelling`` makes M labels moving on smooth, well separated trajectories, writes them
per-frame shuffled into P point columns (plus ghosts), hides one stretch of each of some labels
(gaps), and returns the raw take, a labelling result (as ``core.labelling`` returns it) and the truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handmocap.core.io import Take


@dataclass
class SyntheticLabelling:
    """``marker_names (M,)``, ``assignment (F, M)``, ``confidence (F, M)`` mm, ``residuals_mm (F, M)``,
    ``ghost_points (F, P)``, ``joint_angles (F, 26)``: a one-hand labelling result for
    :meth:`ReviewTake.from_labelling`."""

    marker_names: list[str]
    assignment: np.ndarray
    confidence: np.ndarray
    residuals_mm: np.ndarray
    ghost_points: np.ndarray
    joint_angles: np.ndarray


def synthetic_labelling(frames: int = 60, labels: int = 5, ghosts: int = 1, seed: int = 0,
                        gap_labels: int = 2, spacing_mm: float = 40.0, shuffle: bool = True,
                        ) -> tuple[Take, SyntheticLabelling, np.ndarray]:
    """A raw take ``(F, P, 3)`` with P = labels + ghosts, its (correct) labelling and the true
    positions ``(F, M, 3)`` mm. Label m moves on a circle of radius 5 mm around ``m * spacing_mm``
    on X; ``gap_labels`` labels miss a stretch of F/6 frames in the middle; a ghost point appears
    every third frame next to label 0. ``shuffle``: points in a random column order per frame (as an
    unlabelled export), else label m is column m."""
    rng = np.random.default_rng(seed)
    time = np.arange(frames)[:, None] / 10.0
    truth = np.stack([np.concatenate([100.0 + spacing_mm * m + 5.0 * np.cos(time + m),
                                      200.0 + 5.0 * np.sin(time + m), 300.0 + time * 2.0], axis=1)
                      for m in range(labels)], axis=1)
    truth = truth.astype(np.float32).astype(np.float64)  # exactly representable in a float C3D
    visible = np.ones((frames, labels), dtype=bool)
    gap = max(1, frames // 6)
    for m in range(min(gap_labels, labels)):
        start = frames // 3 + 3 * m
        visible[start:start + gap, m] = False
    count = labels + ghosts
    points = np.full((frames, count, 3), np.nan)
    assignment = np.full((frames, labels), -1, dtype=np.int64)
    ghost_points = np.zeros((frames, count), dtype=bool)
    for frame in range(frames):
        order = rng.permutation(count) if shuffle else np.arange(count)
        for m in range(labels):
            if visible[frame, m]:
                points[frame, order[m]] = truth[frame, m]
                assignment[frame, m] = order[m]
        for g in range(ghosts):
            if frame % 3 == g % 3:
                column = order[labels + g]
                points[frame, column] = np.float32(truth[frame, 0] + [12.0, 0.0, 3.0 * g])
                ghost_points[frame, column] = True
    take = Take([f"point_{i:03d}" for i in range(count)], points, 100.0, first_frame=1, vendor="simulated")
    confidence = np.where(assignment >= 0, 8.0, np.nan)
    residuals = np.where(assignment >= 0, 0.5, np.nan)
    result = SyntheticLabelling([f"M{m}" for m in range(labels)], assignment, confidence, residuals, ghost_points,
                                np.zeros((frames, 26)))
    return take, result, truth
