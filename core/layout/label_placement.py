"""Where to print the number of each marker on a drawing so that no two numbers and no number and
marker overlap: a greedy search over positions around each marker, outward first.

Page coordinates in mm (x right, y down, as the painter uses them).
"""

from __future__ import annotations

import numpy as np

LABEL_DISTANCES_MM = (5.0, 7.0, 9.5, 12.5, 16.0)   # label centre to marker centre, nearest first
ANGLE_STEP_DEG = 15.0                               # candidate directions: outward, then ±15°, ±30°, …
PADDING_MM = 0.4                                    # free space kept around each label


def _candidate_offsets(outward: np.ndarray) -> np.ndarray:
    """Offsets (C, 2) mm from a marker to candidate label centres: each distance of
    :data:`LABEL_DISTANCES_MM` with directions turning away from ``outward (2,)`` (unit) in turn."""
    turns = [0.0]
    for step in range(1, int(180.0 / ANGLE_STEP_DEG) + 1):
        turns += [step * ANGLE_STEP_DEG, -step * ANGLE_STEP_DEG]
    angles = np.radians(np.array(turns[:-1] if turns[-1] == -180.0 else turns))
    base = np.arctan2(outward[1], outward[0])
    directions = np.stack([np.cos(base + angles), np.sin(base + angles)], axis=1)       # (A, 2)
    distances = np.asarray(LABEL_DISTANCES_MM)[:, None, None]
    return (distances * directions[None]).reshape(-1, 2)


def place_labels(anchors: np.ndarray, labelled: np.ndarray, centre: np.ndarray, label_size: tuple[float, float],
                 marker_radius: float) -> np.ndarray:
    """Label centres (k, 2) mm for the markers at ``anchors (k, 2)`` mm whose ``labelled (k,)`` is True
    (NaN rows for the others). Labels are ``label_size`` (width, height) mm boxes; each goes at the
    first free place, outward from ``centre (2,)`` first, that overlaps no placed label and no marker
    disc of ``marker_radius`` mm. Markers far from the others are placed first; a marker with no free
    place nearby gets the outward position."""
    anchors = np.asarray(anchors, dtype=float)
    labels = np.full_like(anchors, np.nan)
    half = np.asarray(label_size, dtype=float) / 2.0 + PADDING_MM
    placed: list[np.ndarray] = []
    crowding = (np.linalg.norm(anchors[:, None] - anchors[None], axis=2) < 4.0 * marker_radius).sum(axis=1)
    for index in np.flatnonzero(labelled)[np.argsort(crowding[labelled], kind="stable")]:
        outward = anchors[index] - centre
        norm = float(np.linalg.norm(outward))
        outward = outward / norm if norm > 1e-9 else np.array([0.0, -1.0])
        candidates = anchors[index] + _candidate_offsets(outward)                          # (C, 2)
        # nearest point of each candidate box to each marker centre: inside the disc means overlap
        nearest = np.clip(anchors[None], candidates[:, None] - half, candidates[:, None] + half)
        free = (np.linalg.norm(nearest - anchors[None], axis=2) > marker_radius).all(axis=1)
        if placed:
            others = np.array(placed)
            apart = (np.abs(candidates[:, None] - others[None]) >= 2.0 * half).any(axis=2)   # (C, P)
            free &= apart.all(axis=1)
        choice = int(np.argmax(free)) if free.any() else 0
        labels[index] = candidates[choice]
        placed.append(candidates[choice])
    return labels
