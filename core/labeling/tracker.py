"""One-hand labelling API (kept for callers of the first version): :func:`label_take` and
:func:`initial_pose_from_points` are the one-hand case of :mod:`core.labeling.scene`
(Maycock et al. 2015 §III: Hungarian assignment with a missing option, IK, adaptive threshold,
automatic initialisation by clustering, PCA sign combinations, OBB scale, ICP, IK and eq. 2).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from core.errors import InputError
from core.io import Take
from core.labeling.initialise import cluster_cut, initialise_frame
from core.labeling.models import HandTrack, SceneSettings
from core.model import N_PARAMS, HandModel, MarkerLayout, MarkerSet

TrackerSettings = SceneSettings
"""The tuning of the tracker is the scene's (:class:`core.labeling.models.SceneSettings`)."""


@dataclass
class LabelingResult:
    """Labelling of a take with M layout markers over F frames.

    ``assignment (F,M)`` point column of the take taken by each marker (-1 missing);
    ``confidence (F,M)`` mm: margin between the chosen and the next-best option of the marker in the
    final assignment (0 when the marker did not get its nearest option, NaN when nothing was solved);
    ``joint_angles (F,26)``; ``residuals_mm (F,M)`` distance from the solved effector to the taken
    point (NaN when missing); ``ghost_points (F,P)`` True for a measured point no marker took;
    ``marker_names`` the layout's markers.
    """

    assignment: np.ndarray
    confidence: np.ndarray
    joint_angles: np.ndarray
    residuals_mm: np.ndarray
    ghost_points: np.ndarray
    marker_names: list[str]


def initial_pose_from_points(points: np.ndarray, model: HandModel, markers: MarkerSet,
                             settings: TrackerSettings | None = None) -> np.ndarray:
    """θ (26,) of the hand in one frame's ``points (N,3)`` mm (NaN rows ignored), by the scene
    initialisation (:mod:`core.labeling.initialise`). Raises InputError with fewer than 3 points or
    when no cluster fits the hand."""
    settings = settings or TrackerSettings()
    points = np.asarray(points, dtype=float)
    points = points[np.isfinite(points).all(axis=1)]
    if len(points) < 3:
        raise InputError(f"the frame has {len(points)} point(s); automatic labelling needs at "
                         "least 3 to find the hand (give an initial posture instead)")
    track = HandTrack(model.side, model.side, model, markers, settings)
    fits = initialise_frame([track], [0], points, settings, cluster_cut([track], settings))
    if not fits:
        raise InputError("no cluster of the frame fits the hand; automatic labelling cannot find it "
                         "(give an initial posture instead)")
    return np.asarray(fits[0].state)


def label_take(take: Take, model: HandModel, layout: MarkerLayout | str,
               initial_theta: np.ndarray | None = None,
               progress: Callable[[float], None] | None = None,
               cancelled: Callable[[], bool] | None = None,
               settings: TrackerSettings | None = None) -> LabelingResult:
    """Label the unlabelled points of ``take`` (``marker_positions (F,P,3)`` mm) with the markers of
    ``layout`` on one hand ``model`` (its side decides right or left): the one-hand case of
    :func:`core.labeling.scene.label_scene` (offline, with subject calibration per ``settings``).
    ``initial_theta (26,)``: posture in the first frame (e.g. from a labelled first frame); None
    finds it automatically. Raises InputError (empty take, too few points) and CancelledError."""
    from core.labeling.scene import label_scene

    if initial_theta is not None and np.shape(initial_theta) != (N_PARAMS,):
        raise InputError(f"the initial posture must have {N_PARAMS} parameters, got {np.shape(initial_theta)}")
    side = model.side
    scene = label_scene(take, hands=side, layout=layout, settings=settings, progress=progress,
                        cancelled=cancelled, models={side: model},
                        initial_states=None if initial_theta is None else {side: initial_theta})
    return LabelingResult(scene.assignment, scene.confidence, scene.joint_angles[side], scene.residuals_mm,
                          scene.ghost_points, list(scene.marker_names))
