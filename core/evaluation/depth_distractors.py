"""Real depth frames made harder: a body or a chair nearer to the camera than the hand (the segmentation must
still pick the hand, :mod:`core.fusion.hand_segment`). Used by the depth-fit tests and ``evaluate_depth_fit``.
Depth frames are ``(H, W)`` mm, 0 = no depth."""

from __future__ import annotations

import numpy as np

#: mm behind the hand's depth beyond which a pixel is the body or the room (moved by :func:`body_nearer`)
BEHIND_HAND_MM = 120.0
#: mm the body and the room are moved towards the camera
BODY_SHIFT_MM = 330.0


def body_nearer(depth: np.ndarray, hand_depth_mm: float) -> np.ndarray:
    """The frame with everything more than :data:`BEHIND_HAND_MM` behind the hand (at ``hand_depth_mm``) moved
    :data:`BODY_SHIFT_MM` nearer: the body is then nearer than the hand."""
    moved = depth.copy()
    moved[depth > hand_depth_mm + BEHIND_HAND_MM] -= BODY_SHIFT_MM
    return moved


def chair_nearer(depth: np.ndarray) -> np.ndarray:
    """The 640 x 480 frame with a chair 420-460 mm from the camera in the lower left (seat, back and frame)."""
    chair = depth.copy()
    chair[330:480, 0:260] = 420.0 + np.linspace(0.0, 40.0, 150)[:, None]
    chair[150:330, 20:70] = 430.0
    chair[150:330, 200:250] = 430.0
    chair[140:170, 20:250] = 430.0
    return chair
