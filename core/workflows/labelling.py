"""Auto-label a take into an undoable review command, with a report of what was found.

What the input file knows is kept (:func:`file_labels`): points it labels with names outside the
scene (an arm, the back, an object of a body take) are not offered to the labeller, are not ghosts,
and come out as labels of their own; points it labels with the scene's names (the layout's markers,
``R_``/``L_`` prefixed for two hands, or the objects' markers) are evidence: the file's label is kept
where the file has one and the labeller's result is used for the rest. ``relabel=True`` labels from
scratch: every point is offered to the labeller and its result is used as it is (the file's labels are
only compared with it).

The report carries the labeller's noise estimate and health warnings, plus the warnings that need only
the result (:func:`result_health`): a model labelling a small share of its markers while the points
are there, many points left as ghosts, no hand found (then the hands' labels are dropped: a share
labelled by a hand fitted to stray points is not claimed).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from handmocap.core.calibration.subject import calibrated_model
from handmocap.core.errors import InputError
from handmocap.core.io import Take, is_marker_label
from handmocap.core.io.labelled_c3d import SubjectCalibration, subject_calibrations
from handmocap.core.labelling.health_warning import HealthWarning
from handmocap.core.labelling.result import SceneLabelling
from handmocap.core.labelling.scene import HAND_PREFIX, label_scene
from handmocap.core.model import HandModel, MarkerLayout, MarkerSet, load_layout, load_template, resolve_layout
from handmocap.core.model.lab_template import LabTemplate, load_lab_template
from handmocap.core.model.objects import ObjectSpec, load_scene_spec
from handmocap.core.review import ApplyLabelling, HandTrack, LabellingArrays

#: a hand model is "found" when it labels at least half of its markers in this share of the frames
HAND_FOUND_SHARE = 0.05
#: a hand labelling less than this fraction of the markers the points present allow, over the frames it
#: is tracked, is reported (a wrong side or layout labels about half)
LOW_SHARE_RATIO = 0.75
#: labelling is refused when the columns left to the labeller (not labelled outside the scene) are fewer
#: than this share of the layout's markers: the layout is not the one the take is labelled with
MIN_OFFERED_SHARE = 0.5


@dataclass
class FileLabels:
    """What a take's point names say before labelling: ``kept`` columns labelled outside the scene
    (``kept_names``, the file's names), and ``evidence`` ``{take column: scene label name}`` of the
    columns labelled with a scene label's name (case-insensitive; an unprefixed hand name of a
    two-hand scene is resolved after labelling, see :func:`merge_file_labels`)."""

    kept_columns: np.ndarray
    kept_names: list[str]
    evidence: dict[int, str] = field(default_factory=dict)


@dataclass
class AutoLabelOutcome:
    """An auto-label run: the ``command`` to push on the review's undo stack, the engine's ``result``,
    the calibrated hand ``models`` and ``marker_sets`` per side (the subject's marker offsets live in the
    marker set), their ``subjects`` (calibrations relative to the template, for a labelled C3D) and a
    JSON-ready ``report``."""

    command: ApplyLabelling
    result: SceneLabelling
    models: dict[str, HandModel]
    report: dict
    marker_sets: dict[str, MarkerSet] = field(default_factory=dict)
    subjects: list[SubjectCalibration] = field(default_factory=list)


def hand_tracks(result: SceneLabelling, layout_name: str | None) -> list[HandTrack]:
    """The solved hands of a scene labelling as review :class:`HandTrack` entries (objects are not hands)."""
    tracks = []
    for model in result.models:
        if model.kind not in ("right", "left"):
            continue
        labels = np.arange(model.markers.start, model.markers.stop)
        tracks.append(HandTrack(model.name, model.kind, layout_name, labels, result.joint_angles[model.name]))
    return tracks


def scene_label_names(layout: MarkerLayout | LabTemplate, specs: list[ObjectSpec]) -> set[str]:
    """Lower-case names a scene's labels may have: the layout's (a template's: both hands' and its objects'),
    ``r_``/``l_`` prefixed, and the objects'."""
    names = {name.strip().lower() for name in layout.marker_names} if isinstance(layout, LabTemplate) else {
        name.strip().lower() for name in layout.names}
    names |= {prefix.lower() + name for prefix in HAND_PREFIX.values() for name in set(names)}
    return names | {name.strip().lower() for spec in specs for name in spec.marker_names}


def file_labels(take: Take, scene_names: set[str]) -> FileLabels:
    """Split the take's labelled columns (:func:`core.io.is_marker_label`) into those outside the scene
    (kept as they are) and those named like a scene label (evidence); placeholder columns are neither."""
    kept, names, evidence = [], [], {}
    for column, name in enumerate(take.marker_names):
        if not is_marker_label(name):
            continue
        if name.strip().lower() in scene_names:
            evidence[column] = name.strip().lower()
        else:
            kept.append(column)
            names.append(name.strip())
    return FileLabels(np.array(kept, dtype=np.int64), names, evidence)


def merge_file_labels(arrays: LabellingArrays, take: Take, known: FileLabels, relabel: bool = False) -> dict:
    """Bring what the file knows into a labelling of ``take`` (``arrays`` changed in place), unless
    ``relabel``: the kept labels are appended as labels of their own, and each evidence column's point
    goes to its label wherever the file has it (a label that had taken that point elsewhere loses it).
    Returns figures: ``file_label_samples`` (samples the file labels with scene names),
    ``disagreed_samples`` (of those, the labeller gave the label another point or none), ``kept_labels``,
    ``kept_samples``."""
    present = np.isfinite(take.marker_positions).all(axis=2)
    assignment = arrays.assignment
    lowered = [name.lower() for name in arrays.marker_names]
    file_samples = disagreed = 0
    for column, name in known.evidence.items():
        label = _evidence_label(lowered, name, assignment, column)
        if label < 0:
            continue
        frames = np.flatnonzero(present[:, column])
        file_samples += len(frames)
        differs = frames[assignment[frames, label] != column]
        disagreed += len(differs)
        if relabel or not len(differs):
            continue
        rows, others = np.nonzero(assignment[differs] == column)
        lost = differs[rows]
        assignment[lost, others] = -1
        arrays.confidence[lost, others] = np.nan
        arrays.residuals_mm[lost, others] = np.nan
        assignment[differs, label] = column
        arrays.confidence[differs, label] = np.nan
        arrays.residuals_mm[differs, label] = np.nan
        arrays.ghost_points[differs, column] = False
    columns, names = (known.kept_columns[:0], []) if relabel else (known.kept_columns, list(known.kept_names))
    kept = present[:, columns]
    arrays.marker_names = list(arrays.marker_names) + names
    arrays.assignment = np.concatenate([assignment, np.where(kept, columns[None, :], -1)], axis=1)
    extra = np.full((len(assignment), len(columns)), np.nan)
    arrays.confidence = np.concatenate([arrays.confidence, extra], axis=1)
    arrays.residuals_mm = np.concatenate([arrays.residuals_mm, extra], axis=1)
    arrays.ghost_points = arrays.ghost_points.copy()
    arrays.ghost_points[:, columns] &= ~kept
    return {"file_label_samples": int(file_samples), "disagreed_samples": int(disagreed),
            "kept_labels": names, "kept_samples": int(kept.sum())}


def _evidence_label(names: list[str], name: str, assignment: np.ndarray, column: int) -> int:
    """The label (index into ``names``, lower case) a file column named ``name`` stands for: the label of
    that name, else (an unprefixed hand name in a two-hand scene) the prefixed label the labeller gave
    that column most often; -1 when none."""
    if name in names:
        return names.index(name)
    candidates = [names.index(prefix.lower() + name) for prefix in HAND_PREFIX.values()
                  if prefix.lower() + name in names]
    if not candidates:
        return -1
    counts = [int((assignment[:, label] == column).sum()) for label in candidates]
    return candidates[int(np.argmax(counts))] if max(counts) > 0 else -1


def result_health(result: SceneLabelling, present: np.ndarray) -> list[HealthWarning]:
    """Warnings that need only the labelling ``result`` and ``present (F,P)`` (the points offered to the
    labeller), beside the labeller's own per-window ones (:func:`core.labelling.health.assess_labelling`):
    "low_labelled_share" of a hand over the whole stretch it is tracked, against the share the points
    present allow; "no_hand" when no hand labels half of its markers in :data:`HAND_FOUND_SHARE` of the
    frames (a hand fitted to stray points)."""
    frames = len(result.assignment)
    hands = [model for model in result.models if model.kind in ("right", "left")]
    if not frames or not hands:
        return []
    labelled = result.assignment >= 0
    allowed = np.minimum(1.0, present.sum(axis=1) / max(len(result.marker_names), 1))
    warnings: list[HealthWarning] = []
    found = False
    for model in hands:
        share = labelled[:, model.markers].mean(axis=1)
        found |= bool((share >= 0.5).mean() >= HAND_FOUND_SHARE)
        tracked = np.flatnonzero(share > 0)
        if not len(tracked):
            continue
        first, last = int(tracked[0]), int(tracked[-1])
        got, possible = share[first:last + 1].mean(), allowed[first:last + 1].mean()
        if possible > 0 and got < LOW_SHARE_RATIO * possible:
            warnings.append(HealthWarning(
                "low_labelled_share", model.name, first, last,
                f"the {model.name} hand labels {100 * got:.0f} % of its markers where the points present allow "
                f"{100 * possible:.0f} %: check the side and the layout"))
    if not found and any(model.init_frame >= 0 for model in hands):
        warnings = [HealthWarning("no_hand", "", 0, frames - 1, "no hand was found in the take (no hand model "
                                  "labels half of its markers in any stretch): is the layout right, is a hand in it?")]
    return warnings


def labelling_report(result: SceneLabelling, seconds: float, health: list[HealthWarning] | None = None) -> dict:
    """What a labelling found: per model its first tracked frame, per label the share of frames
    labelled and the mean residual (mm), the ghost points left, the frame rate reached, the noise σ
    estimated on the take (``noise_mm``, mm per axis, None when unknown) and the ``health`` warnings
    (default: the result's own) as dicts with 0-based inclusive frames."""
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
        "noise_mm": None if result.noise_mm is None else round(float(result.noise_mm), 3),
        "health": [warning.as_dict() for warning in (result.health if health is None else health)],
        "models": models,
        "per_label": {name: round(float(share), 4) for name, share in
                      zip(result.marker_names, labelled.mean(axis=0) if frames else [], strict=False)},
    }


def subject_calibration(model_kind: str, layout: MarkerLayout, calibration: dict) -> SubjectCalibration | None:
    """A hand's subject calibration report (``scales``, ``offsets_mm``) as a :class:`SubjectCalibration`
    of ``layout``; None when the report lacks them."""
    if "scales" not in calibration or "offsets_mm" not in calibration:
        return None
    return SubjectCalibration(model_kind, layout.name, tuple(layout.names), np.asarray(calibration["scales"], float),
                              np.asarray(calibration["offsets_mm"], float).reshape(len(layout.names), 3))


def subject_model(calibration: SubjectCalibration, layout: MarkerLayout) -> tuple[HandModel, MarkerSet]:
    """The template hand of the calibration's side with its subject calibration applied, and ``layout``'s
    markers on it (mm). InputError when the calibration was made with other markers than ``layout``'s."""
    if [name.lower() for name in calibration.marker_names] != [name.lower() for name in layout.names]:
        raise InputError(f"the subject calibration of the {calibration.side} hand was made with layout "
                         f"'{calibration.layout}', not '{layout.name}'")
    template = load_template(calibration.side)
    return calibrated_model(template, resolve_layout(template, layout), calibration.scales, calibration.offsets_mm)


@dataclass(frozen=True)
class SubjectHands:
    """The subject's hands a labelled take stores (its ``HAND_SUBJECT`` group), per side: hand models and
    calibrated marker sets, for the model fill and the solve; ``notes``: one line per calibration not used."""

    models: dict[str, HandModel]
    marker_sets: dict[str, MarkerSet]
    notes: list[str]


def subject_hands(parameters: dict, source: str | Path | None = None) -> SubjectHands:
    """The subject hands auto-label stored in a labelled take's ``parameters``; a calibration whose layout or
    template is not found here is left out with a note (the template hand is used instead)."""
    models, marker_sets, notes = {}, {}, []
    for subject in subject_calibrations(parameters, source):
        try:
            template = load_lab_template(subject.layout)
            layout = template.layout_for(subject.side) if template is not None else load_layout(subject.layout)
            models[subject.side], marker_sets[subject.side] = subject_model(subject, layout)
        except InputError as error:
            notes.append(f"the subject calibration of the {subject.side} hand is not used ({error})")
    return SubjectHands(models, marker_sets, notes)


def auto_label(take: Take, layout: str | MarkerLayout | LabTemplate = "dense", hands: str = "auto",
               objects: str | Path | list | None = None, online: bool = False,
               models: dict[str, HandModel] | None = None, relabel: bool = False,
               progress: Callable[[float], None] | None = None,
               cancelled: Callable[[], bool] | None = None) -> AutoLabelOutcome:
    """Label the raw points of ``take`` (see :func:`core.labelling.scene.label_scene`; ``hands`` "auto",
    "right", "left" or "both"), keep what its point names already say (module docstring; ``relabel``:
    label from scratch, ignoring them) and wrap the result as an undoable :class:`ApplyLabelling` for a review of
    this take. ``layout`` may be a lab template (or name one): its hands' own placements and names and its
    objects are used. Raises InputError (e.g. every point is labelled outside the scene) or CancelledError."""
    template = load_lab_template(layout) if isinstance(layout, str) else None
    layout = template or (load_layout(layout) if isinstance(layout, str) else layout)
    label_count = len(layout.marker_names) if isinstance(layout, LabTemplate) else len(layout.names)
    specs = load_scene_spec(objects) if isinstance(objects, str | Path) else list(objects or [])
    known = file_labels(take, scene_label_names(layout, specs))
    offered = take
    if len(known.kept_columns) and not relabel:
        positions = take.marker_positions.copy()
        positions[:, known.kept_columns] = np.nan
        left = int(np.isfinite(positions).all(axis=2).any(axis=0).sum())
        if left < MIN_OFFERED_SHARE * label_count:
            examples = ", ".join(known.kept_names[:3])
            raise InputError(f"only {left} point columns of the take are left to label: the other "
                             f"{len(known.kept_names)} are labelled with names outside layout '{layout.name}' "
                             f"({examples}…) and are kept; give the layout the take uses, or relabel from scratch")
        offered = replace(take, marker_positions=positions, parameters=dict(take.parameters))
    started = time.perf_counter()
    result = label_scene(offered, hands=hands, layout=layout, objects=specs or None, online=online, models=models,
                         progress=progress, cancelled=cancelled)
    seconds = time.perf_counter() - started
    present = np.isfinite(offered.marker_positions).all(axis=2)
    health = list(result.health)
    health += [warning for warning in result_health(result, present) if warning not in health]
    no_hand = any(warning.kind == "no_hand" and not warning.model for warning in health)
    tracks = hand_tracks(result, layout.name)
    arrays = LabellingArrays(list(result.marker_names), result.assignment.copy(), result.confidence.copy(),
                             result.residuals_mm.copy(), result.ghost_points.copy(), tracks,
                             rigid_bodies=result.rigid_bodies, health=health, noise_mm=result.noise_mm)
    if no_hand:
        _drop_hands(arrays, result)
    figures = merge_file_labels(arrays, take, known, relabel)
    described = "auto" if hands == "auto" else f"{hands} hand{'s' if hands == 'both' else ''}"
    command = ApplyLabelling(arrays, hands=arrays.hands, description=f"auto-label ({described}, {layout.name})")
    found = [] if no_hand else [model for model in result.models
                                if model.kind in ("right", "left") and model.hand_model is not None]
    report = labelling_report(result, seconds, health) | {"file_labels": figures,
                                                          "ghost_points": int(arrays.ghost_points.sum())}
    if no_hand:
        report["labelled_share"] = 0.0
        report["mean_residual_mm"] = None
    side_layout = layout.layout_for if isinstance(layout, LabTemplate) else (lambda _side: layout)
    subjects = [subject for subject in (subject_calibration(model.kind, side_layout(model.kind), model.calibration)
                                        for model in found if models is None or model.kind not in models)
                if subject is not None]
    return AutoLabelOutcome(command, result,
                            {model.kind: model.hand_model for model in found if model.hand_model is not None}, report,
                            {model.kind: model.marker_set for model in found if model.marker_set is not None},
                            subjects)


def _drop_hands(arrays: LabellingArrays, result: SceneLabelling) -> None:
    """Unlabel the hands' markers of ``arrays`` and forget their solves (no hand was found)."""
    for model in result.models:
        if model.kind in ("right", "left"):
            arrays.assignment[:, model.markers] = -1
            arrays.confidence[:, model.markers] = np.nan
            arrays.residuals_mm[:, model.markers] = np.nan
    for track in arrays.hands:
        track.joint_angles = np.full_like(track.joint_angles, np.nan)
