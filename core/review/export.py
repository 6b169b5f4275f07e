"""Exports of a review: labelled C3D (with provenance), TRC and CSV markers, joint angles as CSV, BVH and glTF
(the registered formats of :mod:`core.review.export_formats`); labelled C3D import.

Exports show the file's own frame numbers (``take.first_frame`` onwards) and never change the review. A
trimmed review (:attr:`ReviewTake.trim`) exports its range only, numbered as in the file; its events go into
the labelled C3D's ``EVENT`` group (:mod:`core.io.c3d_events`) and into an ``event`` column of the joint-angle
CSV (TRC has no place for them; BVH and glTF neither).
A review read from a labelled C3D keeps everything that file's provenance says when it is exported
again (e.g. by ``handmocap fill``): the codes of measured and filled samples, edit and ghost flags, the
measured residuals, the raw take it was labelled from (``SOURCE``), its hands (``HANDS``) and the names
of its unlabelled ``*n`` points.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from os import PathLike
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io import Take
from handmocap.core.io.c3d_events import GROUP as EVENT_GROUP
from handmocap.core.io.c3d_events import event_group
from handmocap.core.io.csv_file import write_csv
from handmocap.core.io.labelled_c3d import (
    GROUP,
    SUBJECT_GROUP,
    UNLABELLED_PREFIX,
    SubjectCalibration,
    read_labelled_c3d,
    subject_group,
    write_labelled_c3d,
)
from handmocap.core.io.trc import write_trc
from handmocap.core.model import HandModel
from handmocap.core.model.bvh import write_bvh
from handmocap.core.model.gltf import HandAnimation, save_gltf_hands
from handmocap.core.model.joint_angles import write_joint_angles_csv
from handmocap.core.model.provenance import MEASURED, MISSING
from handmocap.core.review.export_formats import (
    ExportFormat,
    ExportOptions,
    export_format,
    export_formats,
    register_export_format,
)
from handmocap.core.review.take import HandTrack, ReviewTake, detected_hands

UNLABELLED_CHOICES = ("all", "non-ghost", "none")
HAND_PREFIXES = {"right": "R_", "left": "L_"}
#: how an error message names a format's fixed units
UNIT_WORDS = {"m": "metres"}


def unlabelled_columns(review: ReviewTake, unlabelled: str = "all") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The raw columns to export as ``*<column>`` points: their indices ``(U,)``, positions ``(F, U, 3)`` mm
    as float32, the precision of the C3D file (the column's point where no label took it, NaN elsewhere;
    built a column at a time, so the export needs no float64 copy of them) and ghost flags ``(F, U)``.
    ``unlabelled``: "all" (ghosts too), "non-ghost" or "none"."""
    if unlabelled not in UNLABELLED_CHOICES:
        raise InputError(f"unlabelled points: use {', '.join(UNLABELLED_CHOICES)}, not '{unlabelled}'")
    free = review.unlabelled_points()
    if unlabelled == "non-ghost":
        free &= ~review.ghost
    if unlabelled == "none":
        free[:] = False
    columns = np.flatnonzero(free.any(axis=0))
    positions = np.empty((review.n_frames, len(columns), 3), dtype=np.float32)
    for index, column in enumerate(columns):
        positions[:, index] = np.where(free[:, column, None], review.take.marker_positions[:, column], np.nan)
    return columns, positions, review.ghost[:, columns] & free[:, columns]


def per_hand_path(path: str | PathLike[str], side: str) -> Path:
    """The file of the ``side`` hand when a take's two hands are written to one file each:
    ``OUT.bvh`` -> ``OUT_right.bvh``, ``OUT_left.bvh``."""
    path = Path(path)
    return path.with_name(f"{path.stem}_{side}{path.suffix}")


def export_review(review: ReviewTake, path: str | PathLike[str], format_name: str, *, units: str | None = None,
                  up: str | None = None, hand: str | None = None, fills: bool = True, model: HandModel | None = None,
                  subjects: list[SubjectCalibration] | None = None,
                  models: Mapping[str, HandModel] | None = None) -> list[Path]:
    """Write ``review`` as the registered format ``format_name`` (:mod:`core.review.export_formats`): "c3d"
    labelled C3D (mm, Z up, with provenance and ``subjects``), "trc" (``units``, ``up``), "csv" labelled points
    (mm), "angles-csv" joint angles, "bvh" (``units``, ``up``) and "gltf" (metres, Y up by the glTF
    specification) of the solved hands on their models (``models`` per side, or ``model`` for its side).
    ``hand`` ("right"/"left") exports that hand only; without it a take with two hands gives two BVH files
    (:func:`per_hand_path`) and one glTF with both hands. ``fills`` False leaves the fills out of the point
    formats. Returns the files written. InputError (one line) on options the format does not take."""
    chosen = export_format(format_name)
    review = review.trimmed()
    if not str(path).lower().endswith(chosen.suffixes):
        raise InputError(f"a {format_name} file name must end in {' or '.join(chosen.suffixes)}: {path}")
    if not chosen.axes and units not in (None, chosen.units) or not chosen.axes and up not in (None, chosen.up):
        raise InputError(f"{format_name} files are always in {UNIT_WORDS.get(chosen.units, chosen.units)} and "
                         f"{chosen.up.upper()} up; "
                         f"--units and --up apply to {_names(lambda other: other.axes)}")
    if chosen.joint_angles and not fills:
        raise InputError(f"--no-fills applies to the marker formats ({_names(lambda other: not other.joint_angles)}), "
                         "not to joint angles")
    if hand is not None and not chosen.joint_angles:
        raise InputError(f"--hand applies to the joint-angle formats ({_names(lambda other: other.joint_angles)})")
    hand_models = dict(models or {})
    if model is not None:
        hand_models.setdefault(model.side, model)
    options = ExportOptions(units or chosen.units, up or chosen.up, hand, fills, hand_models, subjects)
    return chosen.writer(review, Path(path), options)


def _names(test: Callable[[ExportFormat], bool]) -> str:
    """The names of the registered formats that pass ``test``, comma-separated."""
    return ", ".join(other.name for other in export_formats() if test(other))


def _tracks(review: ReviewTake, options: ExportOptions) -> list[HandTrack]:
    """The hands a joint-angle export writes (``options.hand``, else every solved one), each with a model."""
    tracks = [_hand_of_side(review, options.hand)] if options.hand is not None else _hands_to_export(review)
    for track in tracks:
        if track.side not in options.models:
            raise InputError(f"no hand model given for the {track.side} hand")
    return tracks


def _hands_to_export(review: ReviewTake) -> list[HandTrack]:
    """The hands of ``review`` that are solved somewhere (the first hand when none is, so the export says so)."""
    first = _hand_of_side(review, None)
    solved = [track for track in review.hands if np.isfinite(track.joint_angles).all(axis=1).any()]
    return solved or [first]


def _hand_of_side(review: ReviewTake, side: str | None) -> HandTrack:
    """The first hand of ``side`` ("right", "left"; None: the first hand); InputError when there is none."""
    if not review.hands:
        raise InputError("this take has no hand: its marker names match no layout (label it with a layout first: "
                         "handmocap label, or learn the lab's template: handmocap layout learn)")
    for track in review.hands:
        if side is None or track.side == side:
            return track
    raise InputError(f"this take has no {side} hand (it has: {', '.join(h.side for h in review.hands)})")


def export_labelled_c3d(review: ReviewTake, path: str | PathLike[str], unlabelled: str = "all",
                        subjects: list[SubjectCalibration] | None = None, fills: bool = True) -> None:
    """Write the review as a labelled C3D (``core.io.labelled_c3d``): the labels with their measured
    points and accepted fills, provenance per sample, edited samples, and the unlabelled raw points as
    ``*<column>`` (``unlabelled``: "all", "non-ghost" or "none"); ``subjects``: the hands' subject
    calibrations, written as the ``HAND_SUBJECT`` group (else the source's group, if any, is copied);
    ``fills`` False writes the filled samples as missing. The events are the ``EVENT`` group (the review's,
    replacing the file's). Atomic; InputError on failure."""
    review = review.trimmed()
    columns, positions, ghost = unlabelled_columns(review, unlabelled)
    earlier = review.take.parameters.get(GROUP, {})
    hands = [f"{hand.name}:{hand.side}:{hand.layout or ''}" for hand in review.hands] or earlier.get("HANDS")
    parameters = {name: values for name, values in review.take.parameters.items()
                  if name.upper() not in ("POINT", "ANALOG", "FORCE_PLATFORM", "ROTATION", "EZC3D", EVENT_GROUP)}
    if review.events:
        parameters[EVENT_GROUP] = event_group(review.events, review.take.frame_rate)
    if subjects:
        parameters[SUBJECT_GROUP] = subject_group(subjects)
    raw_names = review.take.marker_names
    names = [raw_names[column] if raw_names[column].startswith(UNLABELLED_PREFIX) else f"{UNLABELLED_PREFIX}{column}"
             for column in columns]
    labelled = review.labelled_positions() if fills else review.measured_positions()
    provenance = review.provenance if fills else np.where(review.provenance > 0, MISSING, review.provenance)
    write_labelled_c3d(path, review.label_names, labelled, provenance,
                       review.take.frame_rate, review.take.first_frame, edited=review.edited,
                       unlabelled=positions if len(columns) else None, unlabelled_names=names, ghost=ghost,
                       source=earlier.get("SOURCE") or review.take.source_path, hands=hands, parameters=parameters,
                       residuals_mm=review.residuals_mm)


def review_from_labelled_c3d(path: str | PathLike[str]) -> ReviewTake:
    """A review from a labelled C3D (ours or any labelled C3D): labels, measured points, accepted fills
    (by the PROVENANCE codes), edit flags, and the ``*n`` points as unlabelled raw points (ghost flags
    kept), the measured residuals the file stores, and its hands (unsolved) when their layout's markers are
    all labels. The raw take of the review has the fills removed (they are not measurements); its
    parameters keep the file's ``SOURCE`` and ``HANDS`` for :func:`export_labelled_c3d`."""
    data = read_labelled_c3d(path)
    take, count = data.take, data.n_labels
    fills = np.zeros((take.n_frames, take.n_markers), dtype=bool)
    fills[:, :count] = data.provenance > 0
    raw_positions = np.where(fills[:, :, None], np.nan, take.marker_positions)
    carried = {key: value for key, value in (("SOURCE", data.source), ("HANDS", data.hands)) if value}
    parameters = {**take.parameters, GROUP: carried} if carried else take.parameters
    raw = Take(marker_names=list(take.marker_names), marker_positions=raw_positions, frame_rate=take.frame_rate,
               first_frame=take.first_frame, vendor=take.vendor, source_units=take.source_units,
               source_path=take.source_path, parameters=parameters)
    review = ReviewTake.unlabelled(raw, list(take.marker_names[:count]), labelled_hands(take.marker_names[:count],
                                                                                       data.hands or [],
                                                                                       take.n_frames))
    measured = data.provenance == MEASURED
    review.assignment = np.where(measured, np.arange(count)[None, :], -1).astype(np.int64)
    review.provenance = np.where(measured, MEASURED, np.where(data.provenance > 0, data.provenance, MISSING)
                                 ).astype(np.int8)
    review.filled_positions = np.where((data.provenance > 0)[:, :, None], take.marker_positions[:, :count], np.nan)
    review.edited = data.edited.copy()
    review.ghost[:, count:] = data.ghost
    if data.residuals_mm is not None:
        review.residuals_mm = data.residuals_mm.copy()
    review.__post_init__()
    return review


def labelled_hands(label_names: list[str], hands: list[str], frames: int) -> list[HandTrack]:
    """Unsolved tracks of the hands of a labelled C3D: its ``"name:side:layout"`` ``hands`` (the ``HANDS``
    parameter this program writes) give the layout and the side of a hand whose names do not say it; without
    them, or when their layout is unknown here, the hands the names show (:func:`detected_hands`)."""
    parts = [(text.split(":") + ["", ""])[:3] for text in hands]
    entries = [(name, side, layout) for name, side, layout in parts if side in HAND_PREFIXES]
    names = {side: name or side for name, side, _ in entries}
    hint = entries[0][1] if len(entries) == 1 else None
    tracks: list[HandTrack] = []
    layout_name = next((layout for _, _, layout in entries if layout), None)
    if layout_name:
        try:
            tracks = [track for track in detected_hands(label_names, frames, layout_name, hint) if track.side in names]
        except InputError:
            tracks = []
    if not tracks:
        tracks = detected_hands(label_names, frames, None, hint)
    for track in tracks:
        track.name = names.get(track.side, track.name)
    return tracks


def _hand(review: ReviewTake, hand: int | str) -> HandTrack:
    if isinstance(hand, str):
        for track in review.hands:
            if track.name == hand:
                return track
        raise InputError(f"no hand '{hand}' in this take")
    if not 0 <= hand < len(review.hands):
        raise InputError(f"no hand {hand} in this take ({len(review.hands)} solved)")
    return review.hands[hand]


def _prefix(review: ReviewTake, track: HandTrack) -> str:
    if len(review.hands) < 2:
        return ""
    return "R_" if track.side == "right" else "L_"


def export_joint_angles_csv(review: ReviewTake, path: str | PathLike[str], hand: str | None = None) -> None:
    """Every hand's joint angles (``hand``: that side's only) as one CSV: ``frame, time_s`` then per hand the 26
    parameters (``wrist_tx_mm``..., angles in degrees; columns prefixed ``R_``/``L_`` with two hands). Unsolved
    samples are empty cells. Atomic; InputError when no hand is solved or the file cannot be written."""
    review = review.trimmed()
    if not review.hands:
        raise InputError("this take has no solved hand; nothing to export")
    tracks = review.hands if hand is None else [_hand_of_side(review, hand)]
    hands = [(_prefix(review, track), track.joint_angles) for track in tracks]
    events: dict[int, str] = {}
    for event in review.events or []:
        events[event.frame_number] = "; ".join(filter(None, [events.get(event.frame_number), event.name]))
    write_joint_angles_csv(path, hands, review.take.first_frame, review.take.frame_rate, events=events or None)


def export_bvh(review: ReviewTake, path: str | PathLike[str], model: HandModel, hand: int | str = 0,
               units: str = "mm", up: str = "z") -> None:
    """One hand's joint angles as BVH (``core.model.bvh``) on ``model``'s rest skeleton (the subject's
    calibrated model, or the template; it must be of the hand's side) in ``units`` with ``up`` ("z" or
    "y"). Joint names are prefixed ``R_``/``L_`` when the take has two hands."""
    review = review.trimmed()
    track = _hand(review, hand)
    if model.side != track.side:
        raise InputError(f"the {track.name} hand is a {track.side} hand; the model is a {model.side} hand")
    write_bvh(path, model.skeleton, track.joint_angles, review.take.frame_rate, prefix=_prefix(review, track),
              units=units, up=up)


def export_gltf(review: ReviewTake, path: str | PathLike[str], model: HandModel, hand: int | str = 0) -> None:
    """One hand as a skinned glTF 2.0 (``.glb``/``.gltf``) on ``model`` with its joint angles as the
    animation (``core.model.gltf``: metres, Y up, times in seconds from the take's first frame)."""
    export_gltf_hands(review, path, {hand: model})


def export_gltf_hands(review: ReviewTake, path: str | PathLike[str], models: Mapping[int | str, HandModel]) -> None:
    """Hands of ``review`` (``{hand name or index: its model}``) as one skinned glTF 2.0 file with their joint
    angles as one animation (:func:`core.model.gltf.save_gltf_hands`). InputError when a hand is not solved in
    any frame or its model is of the other side."""
    review = review.trimmed()
    hands = []
    for hand, model in models.items():
        track = _hand(review, hand)
        if model.side != track.side:
            raise InputError(f"the {track.name} hand is a {track.side} hand; the model is a {model.side} hand")
        if not np.isfinite(track.joint_angles).all(axis=1).any():
            raise InputError(f"the {track.name} hand is not solved in any frame; nothing to animate")
        hands.append((model, HandAnimation(track.joint_angles, review.take.frame_rate)))
    save_gltf_hands(hands, path)


def export_trc(review: ReviewTake, path: str | PathLike[str], units: str = "mm", up: str = "z",
               fills: bool = True) -> None:
    """The labelled points as TRC (``core.io.trc``; OpenSim: ``units="m"``, ``up="y"``); without
    ``fills`` the filled samples are left empty (only measured points)."""
    write_trc(labelled_take(review, fills), path, units=units, up=up)


def export_points_csv(review: ReviewTake, path: str | PathLike[str], fills: bool = True) -> None:
    """The labelled points as CSV in mm (``core.io.csv_file``: ``frame, time_s``, then x, y, z per label;
    missing samples empty); without ``fills`` only the measured points."""
    write_csv(labelled_take(review, fills), path)


def labelled_take(review: ReviewTake, fills: bool = True) -> Take:
    """A take of the labels: ``(F, M, 3)`` mm, measured points and (with ``fills``) accepted fills (the trimmed
    range of a trimmed take)."""
    review = review.trimmed()
    positions = review.labelled_positions() if fills else review.measured_positions()
    return Take(marker_names=list(review.label_names), marker_positions=np.array(positions, dtype=np.float64),
                frame_rate=review.take.frame_rate, first_frame=review.take.first_frame, vendor=review.take.vendor,
                source_path=review.take.source_path)


def _write_c3d(review: ReviewTake, path: Path, options: ExportOptions) -> list[Path]:
    export_labelled_c3d(review, path, subjects=options.subjects, fills=options.fills)
    return [path]


def _write_trc(review: ReviewTake, path: Path, options: ExportOptions) -> list[Path]:
    export_trc(review, path, options.units, options.up, options.fills)
    return [path]


def _write_points_csv(review: ReviewTake, path: Path, options: ExportOptions) -> list[Path]:
    export_points_csv(review, path, options.fills)
    return [path]


def _write_angles_csv(review: ReviewTake, path: Path, options: ExportOptions) -> list[Path]:
    export_joint_angles_csv(review, path, options.hand)
    return [path]


def _write_bvh(review: ReviewTake, path: Path, options: ExportOptions) -> list[Path]:
    """One BVH per hand (:func:`per_hand_path` when there are several)."""
    tracks = _tracks(review, options)
    written = []
    for track in tracks:
        target = path if len(tracks) == 1 else per_hand_path(path, track.side)
        export_bvh(review, target, options.models[track.side], track.name, options.units, options.up)
        written.append(target)
    return written


def _write_gltf(review: ReviewTake, path: Path, options: ExportOptions) -> list[Path]:
    export_gltf_hands(review, path, {track.name: options.models[track.side] for track in _tracks(review, options)})
    return [path]


register_export_format(ExportFormat(
    name="c3d", label="Labelled C3D (markers, provenance)", suffixes=(".c3d",), name_tag="_labelled",
    batch_ending=".c3d", writer=_write_c3d))
register_export_format(ExportFormat(
    name="trc", label="TRC markers (OpenSim)", suffixes=(".trc",), name_tag="_markers", batch_ending=".trc",
    writer=_write_trc, axes=True))
register_export_format(ExportFormat(
    name="csv", label="CSV markers", suffixes=(".csv",), name_tag="_markers", batch_ending=".csv",
    writer=_write_points_csv))
register_export_format(ExportFormat(
    name="angles-csv", label="Joint angles (CSV)", suffixes=(".csv",), name_tag="_angles",
    batch_ending=".angles.csv", writer=_write_angles_csv, joint_angles=True))
register_export_format(ExportFormat(
    name="bvh", label="BVH joint angles (Blender, MotionBuilder)", suffixes=(".bvh",), name_tag="_angles",
    batch_ending=".bvh", writer=_write_bvh, axes=True, joint_angles=True, per_hand=True))
register_export_format(ExportFormat(
    name="gltf", label="glTF skinned hand with its animation", suffixes=(".glb", ".gltf"), name_tag="_hand",
    batch_ending=".glb", writer=_write_gltf, units="m", up="y", joint_angles=True))
