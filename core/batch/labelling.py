"""Auto-label a take into an undoable review command, with a report of what was found."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.io import Take
from core.labeling.scene import SceneLabeling, label_scene
from core.model import HandModel, MarkerLayout, load_layout
from core.session import ApplyLabelling, HandTrack, LabellingArrays


@dataclass
class AutoLabelOutcome:
    """An auto-label run: the ``command`` to push on the review's undo stack, the engine's ``result``,
    the calibrated hand ``models`` per side and a JSON-ready ``report``."""

    command: ApplyLabelling
    result: SceneLabeling
    models: dict[str, HandModel]
    report: dict


def hand_tracks(result: SceneLabeling, layout_name: str | None) -> list[HandTrack]:
    """The solved hands of a scene labelling as review :class:`HandTrack` entries (objects are not hands)."""
    tracks = []
    for model in result.models:
        if model.kind not in ("right", "left"):
            continue
        labels = np.arange(model.markers.start, model.markers.stop)
        tracks.append(HandTrack(model.name, model.kind, layout_name, labels, result.joint_angles[model.name]))
    return tracks


def labelling_report(result: SceneLabeling, seconds: float) -> dict:
    """What a labelling found: per model its first tracked frame, per label the share of frames
    labelled and the mean residual (mm), the ghost points left, the frame rate reached."""
    frames = result.assignment.shape[0]
    labelled = result.assignment >= 0
    residuals = np.where(labelled, result.residuals_mm, np.nan)
    models = []
    for model in result.models:
        columns = slice(model.markers.start, model.markers.stop)
        block = residuals[:, columns]
        entry = {"name": model.name, "kind": model.kind, "first_frame_tracked": int(model.init_frame),
                 "labelled_share": round(float(labelled[:, columns].mean()), 4) if frames else 0.0,
                 "mean_residual_mm": round(float(np.nanmean(block)), 3) if np.isfinite(block).any() else None}
        if model.calibration:
            entry["calibration"] = {key: value for key, value in model.calibration.items()
                                    if isinstance(value, int | float | str | bool | list)}
        models.append(entry)
    return {
        "frames": int(frames), "points": int(result.ghost_points.shape[1]), "labels": len(result.marker_names),
        "online": bool(result.online), "seconds": round(seconds, 3),
        "frames_per_s": round(frames / seconds, 1) if seconds > 0 else None,
        "labelled_share": round(float(labelled.mean()), 4) if labelled.size else 0.0,
        "ghost_points": int(result.ghost_points.sum()),
        "mean_residual_mm": round(float(np.nanmean(residuals)), 3) if np.isfinite(residuals).any() else None,
        "models": models,
        "per_label": {name: round(float(share), 4) for name, share in
                      zip(result.marker_names, labelled.mean(axis=0) if frames else [], strict=False)},
    }


def auto_label(take: Take, layout: str | MarkerLayout = "dense", hands: str = "right",
               objects: str | Path | list | None = None, online: bool = False,
               models: dict[str, HandModel] | None = None,
               progress: Callable[[float], None] | None = None,
               cancelled: Callable[[], bool] | None = None) -> AutoLabelOutcome:
    """Label the raw points of ``take`` (see :func:`core.labeling.scene.label_scene`) and wrap the result
    as an undoable :class:`ApplyLabelling` for a review of this take. Raises InputError/CancelledError."""
    layout = load_layout(layout) if isinstance(layout, str) else layout
    started = time.perf_counter()
    result = label_scene(take, hands=hands, layout=layout, objects=objects, online=online, models=models,
                         progress=progress, cancelled=cancelled)
    seconds = time.perf_counter() - started
    tracks = hand_tracks(result, layout.name)
    arrays = LabellingArrays(list(result.marker_names), result.assignment, result.confidence, result.residuals_mm,
                             result.ghost_points, tracks, rigid_bodies=result.rigid_bodies)
    description = f"auto-label ({hands} hand{'s' if hands == 'both' else ''}, {layout.name})"
    command = ApplyLabelling(arrays, hands=tracks, description=description)
    calibrated = {model.kind: model.hand_model for model in result.models
                  if model.kind in ("right", "left") and model.hand_model is not None}
    return AutoLabelOutcome(command, result, calibrated, labelling_report(result, seconds))
