"""The result of labelling a scene (:class:`SceneLabelling`) and its models (:class:`SceneModel`): what
the scene tracker returns and what health checks, whole-take checks, workflows and evaluations read."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from handmocap.core.io import Take
from handmocap.core.labelling.health_warning import HealthWarning
from handmocap.core.labelling.sides import SideDecision
from handmocap.core.model import HandModel, MarkerSet
from handmocap.core.model.objects import ObjectSpec


@dataclass
class SceneModel:
    """One model of the scene: ``name``, ``kind`` ("right", "left" or "object"), its columns
    ``markers`` (slice into the scene's marker list), the (calibrated) hand model and marker set used,
    or the object spec; ``init_frame`` where it was first initialised (-1 never), the subject
    calibration report of a hand, and the frames where a lost hand was fitted afresh."""

    name: str
    kind: str
    markers: slice
    hand_model: HandModel | None = None
    marker_set: MarkerSet | None = None
    object_spec: ObjectSpec | None = None
    init_frame: int = -1
    calibration: dict = field(default_factory=dict)
    reinitialised: list[int] = field(default_factory=list)


@dataclass
class SceneLabelling:
    """Labelling of a take with M scene markers over F frames and P point columns.

    ``marker_names (M,)`` (two hands: prefixed ``R_``/``L_``; objects' marker names as given),
    ``model_of_marker (M,)`` index into ``models``; ``assignment (F,M)`` point column taken by each
    marker (-1 missing); ``confidence (F,M)`` mm margin between the chosen and the next-best option
    (0 when the marker did not take its nearest option, NaN where the model was not tracked);
    ``residuals_mm (F,M)`` distance from the solved marker to its point (NaN missing);
    ``ghost_points (F,P)`` True for a measured point no marker took; ``joint_angles`` per hand name
    ``(F,26)``; ``object_poses`` per object name ``(F,4,4)`` (NaN where not tracked); ``points``:
    the input ``(F,P,3)`` mm; ``noise_mm`` the marker noise σ per axis estimated on the take (mm, None
    when it could not be estimated); ``health`` the doubts the operator should check; ``side_decision``
    how ``hands="auto"`` decided the sides (None when they were given).
    """

    marker_names: list[str]
    model_of_marker: np.ndarray
    models: list[SceneModel]
    assignment: np.ndarray
    confidence: np.ndarray
    residuals_mm: np.ndarray
    ghost_points: np.ndarray
    joint_angles: dict[str, np.ndarray]
    object_poses: dict[str, np.ndarray]
    points: np.ndarray
    online: bool = False
    noise_mm: float | None = None
    health: list[HealthWarning] = field(default_factory=list)
    side_decision: SideDecision | None = None

    def labelled_positions(self) -> np.ndarray:
        """``(F,M,3)`` mm: the input point each marker took, unchanged; NaN where missing."""
        taken = np.take_along_axis(self.points, np.maximum(self.assignment, 0)[:, :, None], axis=1)
        return np.where((self.assignment >= 0)[:, :, None], taken, np.nan)

    def labelled_take(self, take: Take) -> Take:
        """A labelled copy of ``take``: one column per scene marker (measured points unchanged)."""
        return Take(marker_names=list(self.marker_names), marker_positions=self.labelled_positions(),
                    frame_rate=take.frame_rate, first_frame=take.first_frame, vendor=take.vendor,
                    source_units=take.source_units, source_path=take.source_path,
                    parameters=dict(take.parameters))

    def model(self, name: str) -> SceneModel:
        return next(model for model in self.models if model.name == name)

    @property
    def rigid_bodies(self) -> dict[str, list[int]]:
        """The marker indices (into ``marker_names``) of each rigid object, by object name."""
        indices = np.arange(len(self.marker_names))
        return {model.name: indices[model.markers].tolist() for model in self.models if model.kind == "object"}
