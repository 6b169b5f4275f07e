"""The colours of a review's labels and raw points, shared by the 3D view, the camera dock and the plots."""

from __future__ import annotations

import numpy as np

from handmocap.core.review import ReviewTake

UNLABELLED_COLOUR = (0.62, 0.62, 0.64)
GHOST_COLOUR = (0.55, 0.22, 0.22)
PALETTE = np.array([                # Tableau-like qualitative colours, distinct on a dark background
    (0.36, 0.62, 0.92), (0.98, 0.60, 0.25), (0.40, 0.80, 0.45), (0.93, 0.38, 0.40), (0.70, 0.55, 0.90),
    (0.72, 0.52, 0.42), (0.96, 0.56, 0.80), (0.85, 0.85, 0.40), (0.35, 0.85, 0.85), (0.60, 0.75, 1.00),
    (1.00, 0.78, 0.55), (0.65, 0.92, 0.60), (1.00, 0.65, 0.65), (0.82, 0.72, 0.96), (0.88, 0.72, 0.62),
])


def label_colours(count: int) -> np.ndarray:
    """A distinct colour per label ``(count, 3)`` in [0, 1]."""
    return PALETTE[np.arange(count) % len(PALETTE)]


def point_colours(review: ReviewTake, frame: int) -> np.ndarray:
    """``(P, 3)`` colours of the raw points at ``frame`` as the 3D view and the camera dock draw them: the
    colour of the label a point holds, grey when unlabelled, dark red for ghosts."""
    labels = review.assignment[frame]
    colours = np.tile(UNLABELLED_COLOUR, (review.n_points, 1))
    colours[review.ghost[frame]] = GHOST_COLOUR
    taken = labels >= 0
    colours[labels[taken]] = label_colours(review.n_labels)[np.flatnonzero(taken)]
    return colours

