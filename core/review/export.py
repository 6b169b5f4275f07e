"""Exports of a review: labelled C3D (with provenance), joint angles as CSV and BVH; labelled C3D import.

Exports show the file's own frame numbers (``take.first_frame`` onwards) and never change the review.
"""

from __future__ import annotations

from os import PathLike

import numpy as np

from core.errors import InputError
from core.io import Take
from core.io.bvh import write_bvh
from core.io.joint_angles import write_joint_angles_csv
from core.io.labelled_c3d import (
    SUBJECT_GROUP,
    UNLABELLED_PREFIX,
    SubjectCalibration,
    read_labelled_c3d,
    subject_group,
    write_labelled_c3d,
)
from core.model import HandModel
from core.model.provenance import MEASURED, MISSING
from core.review.take import HandTrack, ReviewTake

UNLABELLED_CHOICES = ("all", "non-ghost", "none")


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


def export_labelled_c3d(review: ReviewTake, path: str | PathLike[str], unlabelled: str = "all",
                        subjects: list[SubjectCalibration] | None = None) -> None:
    """Write the review as a labelled C3D (``core.io.labelled_c3d``): the labels with their measured
    points and accepted fills, provenance per sample, edited samples, and the unlabelled raw points as
    ``*<column>`` (``unlabelled``: "all", "non-ghost" or "none"); ``subjects``: the hands' subject
    calibrations, written as the ``HAND_SUBJECT`` group (else the source's group, if any, is copied).
    Atomic; InputError on failure."""
    columns, positions, ghost = unlabelled_columns(review, unlabelled)
    hands = [f"{hand.name}:{hand.side}:{hand.layout or ''}" for hand in review.hands]
    parameters = {name: values for name, values in review.take.parameters.items()
                  if name.upper() not in ("POINT", "ANALOG", "FORCE_PLATFORM", "ROTATION", "EZC3D")}
    if subjects:
        parameters[SUBJECT_GROUP] = subject_group(subjects)
    write_labelled_c3d(path, review.label_names, review.labelled_positions(), review.provenance,
                       review.take.frame_rate, review.take.first_frame, edited=review.edited,
                       unlabelled=positions if len(columns) else None,
                       unlabelled_names=[f"{UNLABELLED_PREFIX}{column}" for column in columns], ghost=ghost,
                       source=review.take.source_path, hands=hands, parameters=parameters)


def review_from_labelled_c3d(path: str | PathLike[str]) -> ReviewTake:
    """A review from a labelled C3D (ours or any labelled C3D): labels, measured points, accepted fills
    (by the PROVENANCE codes), edit flags, and the ``*n`` points as unlabelled raw points (ghost flags
    kept). The raw take of the review has the fills removed (they are not measurements)."""
    data = read_labelled_c3d(path)
    take, count = data.take, data.n_labels
    fills = np.zeros((take.n_frames, take.n_markers), dtype=bool)
    fills[:, :count] = data.provenance > 0
    raw_positions = np.where(fills[:, :, None], np.nan, take.marker_positions)
    raw = Take(marker_names=list(take.marker_names), marker_positions=raw_positions, frame_rate=take.frame_rate,
               first_frame=take.first_frame, vendor=take.vendor, source_units=take.source_units,
               source_path=take.source_path, parameters=take.parameters)
    review = ReviewTake.unlabelled(raw, list(take.marker_names[:count]))
    measured = data.provenance == MEASURED
    review.assignment = np.where(measured, np.arange(count)[None, :], -1).astype(np.int64)
    review.provenance = np.where(measured, MEASURED, np.where(data.provenance > 0, data.provenance, MISSING)
                                 ).astype(np.int8)
    review.filled_positions = np.where((data.provenance > 0)[:, :, None], take.marker_positions[:, :count], np.nan)
    review.edited = data.edited.copy()
    review.ghost[:, count:] = data.ghost
    review.__post_init__()
    return review


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


def export_joint_angles_csv(review: ReviewTake, path: str | PathLike[str]) -> None:
    """Every hand's joint angles as one CSV: ``frame, time_s`` then per hand the 26 parameters
    (``wrist_tx_mm``..., angles in degrees; columns prefixed ``R_``/``L_`` with two hands). Unsolved
    samples are empty cells. Atomic; InputError when no hand is solved or the file cannot be written."""
    if not review.hands:
        raise InputError("this take has no solved hand; nothing to export")
    hands = [(_prefix(review, track), track.joint_angles) for track in review.hands]
    write_joint_angles_csv(path, hands, review.take.first_frame, review.take.frame_rate)


def export_bvh(review: ReviewTake, path: str | PathLike[str], model: HandModel, hand: int | str = 0,
               units: str = "mm") -> None:
    """One hand's joint angles as BVH (``core.io.bvh``) on ``model``'s rest skeleton (the subject's
    calibrated model, or the template; it must be of the hand's side). Joint names are prefixed
    ``R_``/``L_`` when the take has two hands."""
    track = _hand(review, hand)
    if model.side != track.side:
        raise InputError(f"the {track.name} hand is a {track.side} hand; the model is a {model.side} hand")
    write_bvh(path, model.skeleton, track.joint_angles, review.take.frame_rate, prefix=_prefix(review, track),
              units=units)
