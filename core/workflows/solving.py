"""Solve the hands of a labelled take over the whole take: which hands it holds, which model each is solved on
(the subject's hand that auto-label calibrated and stored in the take, else the template hand) and the IK."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from handmocap.core.errors import InputError
from handmocap.core.ik import IKResult
from handmocap.core.io import Take
from handmocap.core.io.labelled_c3d import subject_calibrations
from handmocap.core.model import HandColumns, MarkerLayout, detect_hands, hand_layout, load_template, marker_columns
from handmocap.core.model.lab_template import LabTemplate
from handmocap.core.prior import PosturePrior
from handmocap.core.workflows.labelling import subject_model
from handmocap.core.workflows.resolve import hand_marker_set, solve_labelled_take


@dataclass(frozen=True)
class SolvedHand:
    """One hand of a take solved: its columns in the take, the IK result (joint angles ``(F, J, 3)`` rad,
    residuals ``(F,)`` mm) and, in words, the model it was solved on."""

    hand: HandColumns
    result: IKResult
    model: str


def take_hands(take: Take, layout: str | Path | MarkerLayout | LabTemplate | None = None,
               side: str | None = None) -> list[HandColumns]:
    """The hands of labelled ``take`` to solve (right first): all it holds, or only ``side`` ("right"/"left";
    a hand whose side its names do not tell counts as that side). InputError when there is none."""
    subjects = subject_calibrations(take.parameters, take.source_path)
    hint = side or (subjects[0].side if len(subjects) == 1 else None)
    hands = detect_hands(take.marker_names, layout, hint, required=True)
    if side is None:
        return hands
    chosen = [hand for hand in hands if hand.side == side] or [hand for hand in hands if not hand.side_from_names]
    if not chosen:
        raise InputError(f"the take has no {side} hand (it has: {', '.join(hand.side for hand in hands)})")
    return chosen[:1]


def solve_take(take: Take, hands: list[HandColumns], template_only: bool = False,
               prior: PosturePrior | None = None, method: str = "layered",
               progress: Callable[[float], None] | None = None,
               cancelled: Callable[[], bool] | None = None) -> list[SolvedHand]:
    """IK of each of ``hands`` (:func:`take_hands`) over the whole labelled ``take``, on the subject's calibrated
    hand when the take stores one that fits the hand's layout (unless ``template_only``), else on the template.
    ``progress`` gets the fraction done over all hands. Raises InputError or CancelledError."""
    subjects = {subject.side: subject for subject in subject_calibrations(take.parameters, take.source_path)}
    solved = []
    for number, hand in enumerate(hands):
        subject = subjects.get(hand.side)
        model, calibrated, what = load_template(hand.side), None, f"the {hand.side} template hand"
        if subject is not None and not template_only:
            full = hand_layout(hand.layout_name, hand.side)
            if (marker_columns(list(subject.marker_names), full.names) >= 0).all():
                model, calibrated = subject_model(subject, full)
                what = f"the subject's {hand.side} hand calibrated by auto-label"
        markers = hand_marker_set(hand, list(take.marker_names), model, calibrated)
        part = None if progress is None else (
            lambda fraction, number=number: progress((number + fraction) / len(hands)))
        result = solve_labelled_take(take, model, markers, prior, method, progress=part, cancelled=cancelled)
        solved.append(SolvedHand(hand, result, what))
    return solved
