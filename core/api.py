"""The Python API: what the ``handmocap`` commands do, as functions on plain data, re-exported by ``handmocap``.

A take is a :class:`Take` (``marker_positions (F, M, 3)`` mm, ``marker_names``, ``frame_rate`` Hz); each step
returns a take for the next, and a dataclass with what it found. The long steps take ``progress`` (called
with the fraction done, 0..1) and ``cancelled`` (polled; True stops the work with :class:`CancelledError`),
as the command line and the window run them. Bad input raises :class:`InputError` with a one-line message.

    import handmocap
    raw = handmocap.read_take("take.csv", rate=120)
    labelled = handmocap.label(raw, "dense")
    filled = handmocap.fill(labelled.take, max_gap=60)
    hands = handmocap.solve(filled.take)
    handmocap.export(filled.take, "take.bvh", "bvh")
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import wraps
from os import PathLike
from pathlib import Path

import numpy as np

from handmocap.core.blas import blas_threads_limited
from handmocap.core.errors import CancelledError, InputError
from handmocap.core.evaluation.take_labelling import evaluate_take_labelling
from handmocap.core.ik import IKResult
from handmocap.core.io import Take, load_take, save_take
from handmocap.core.io.labelled_c3d import SUBJECT_GROUP, subject_calibrations, subject_group
from handmocap.core.labelling.templates import learn_template as learn_lab_template
from handmocap.core.model import MarkerLayout, load_template
from handmocap.core.model.lab_template import LabTemplate, save_lab_template
from handmocap.core.model.skeleton import PARAM_NAMES
from handmocap.core.review import ReviewTake
from handmocap.core.review.export import export_review, labelled_take
from handmocap.core.review.export_formats import export_format
from handmocap.core.simulate import simulate_take as simulate
from handmocap.core.workflows.filling import fill_review_gaps, find_review_gaps, gap_groups
from handmocap.core.workflows.labelling import auto_label, subject_hands
from handmocap.core.workflows.resolve import solve_unsolved_hands
from handmocap.core.workflows.solving import solve_take, take_hands

PathArg = str | PathLike[str]
Progress = Callable[[float], None] | None
Cancelled = Callable[[], bool] | None

__all__ = [
    "CancelledError", "FilledGap", "FillResult", "InputError", "LabTemplate", "LabelResult", "SolvedHand", "Take",
    "evaluate_labelling", "export", "fill", "label", "learn_template", "read_take", "save_take",
    "save_template", "simulate_take", "solve",
]


def _one_blas_thread(function: Callable) -> Callable:
    """Run ``function`` with the BLAS thread count the program uses (:mod:`core.blas`), restored after."""

    @wraps(function)
    def run(*args, **kwargs):
        with blas_threads_limited():
            return function(*args, **kwargs)

    return run


@dataclass(frozen=True)
class LabelResult:
    """What :func:`label` found. ``take``: the labelled take (one column per label, NaN where a label has no
    point; the subject's hand calibration in its parameters, as a labelled C3D stores it); ``report``: the
    figures ``handmocap label --report`` writes (``labelled_share``, ``mean_residual_mm``, ``noise_mm``,
    ``health`` warnings, per model)."""

    take: Take
    report: dict


@dataclass(frozen=True)
class FilledGap:
    """One gap :func:`fill` filled: the label, its first and last frame (the file's numbering) and the method."""

    label: str
    first_frame: int
    last_frame: int
    method: str


@dataclass(frozen=True)
class FillResult:
    """What :func:`fill` did. ``take``: the take with the gaps filled; ``filled``: each filled gap;
    ``gaps``: every gap found; ``missing_samples``: label samples still missing."""

    take: Take
    filled: list[FilledGap]
    gaps: int
    missing_samples: int


@dataclass(frozen=True)
class SolvedHand:
    """One hand :func:`solve` solved. ``joint_angles (F, 26)``: the hand's parameters per frame, named by
    ``parameter_names`` (the wrist's translation in mm, then rotations in rad; NaN where unsolved);
    ``residuals_mm (F, M)``: each of ``markers``' distance to its model marker (NaN where unobserved);
    ``model``: in words, the hand model it was solved on; ``result``: the IK result (``save``, ``save_csv``)."""

    side: str
    joint_angles: np.ndarray
    parameter_names: tuple[str, ...]
    residuals_mm: np.ndarray
    markers: list[str]
    model: str
    result: IKResult


def read_take(path: PathArg, rate: float | None = None) -> Take:
    """Read a take in any format the program reads (C3D, TRC, Qualisys TSV, Vicon Nexus CSV, Motive CSV, NOKOV
    CSV, our CSV/NPZ; the format is recognised by content). ``rate``: the frame rate (Hz) when the file does
    not say it or says it wrong, as ``--rate``."""
    return load_take(path, frame_rate=rate)


def simulate_take(frames: int = 600, seed: int = 0, layout: str = "dense", noise_mm: float = 0.3,
                  ghost_rate: float = 0.0, occlusion: bool = True, unlabelled: bool = False) -> Take:
    """A simulated take of one right hand (deterministic per ``seed``), as ``handmocap generate``: labelled
    with ``layout``'s names, or ``unlabelled`` points shuffled per frame with ghosts and occlusion."""
    return simulate(layout=layout, n_frames=frames, seed=seed, noise_mm=noise_mm, ghost_rate=ghost_rate,
                    occlusion=occlusion, unlabelled=unlabelled).take


@_one_blas_thread
def learn_template(takes: Sequence[Take | PathArg], name: str = "lab", rate: float | None = None,
                   progress: Progress = None, cancelled: Cancelled = None) -> LabTemplate:
    """Learn a lab's labelling template from its labelled takes (``Take`` objects or files read at ``rate``),
    as ``handmocap layout learn``: hands and sides, digit chains, placement, distance statistics, rigid
    objects. Pass it to :func:`label` or save it with :func:`save_template`."""
    read = [take if isinstance(take, Take) else load_take(take, frame_rate=rate) for take in takes]
    return learn_lab_template(read, name=name, progress=progress, cancelled=cancelled).template


def save_template(template: LabTemplate, path: PathArg) -> None:
    """Write a learned template as JSON (what ``--layout`` and the window's Auto-label read)."""
    save_lab_template(template, Path(path))


@_one_blas_thread
def label(take: Take, layout: str | PathArg | MarkerLayout | LabTemplate = "dense", hands: str = "auto",
          objects: str | PathArg | None = None, relabel: bool = False,
          progress: Progress = None, cancelled: Cancelled = None) -> LabelResult:
    """Auto-label ``take``'s points, as ``handmocap label``. ``layout``: a shipped layout's name, a layout or
    template file, or a :class:`LabTemplate`; ``hands``: "auto", "right", "left" or "both"; ``objects``: a
    scene spec file of rigid props; ``relabel``: ignore the labels the file already has."""
    if isinstance(layout, PathLike):
        layout = str(layout)
    outcome = auto_label(take, layout, hands, str(objects) if objects is not None else None, relabel=relabel,
                         progress=progress, cancelled=cancelled)
    review = ReviewTake.unlabelled(take)
    outcome.command.do(review)
    labelled = labelled_take(review)
    if outcome.subjects:
        labelled = replace(labelled, parameters={SUBJECT_GROUP: subject_group(outcome.subjects)})
    return LabelResult(labelled, outcome.report)


def _review(take: Take) -> ReviewTake:
    """The review of a labelled take (the hands its names show); InputError when it has no labels."""
    review = ReviewTake.from_labelled_take(take)
    if not review.n_labels:
        raise InputError("the take has no labelled points; label it first")
    return review


@_one_blas_thread
def fill(take: Take, max_gap: int, method: str = "auto", progress: Progress = None,
         cancelled: Cancelled = None) -> FillResult:
    """Fill the gaps of a labelled take of at most ``max_gap`` frames, as ``handmocap fill``: ``method`` "auto"
    (per gap, the best of the methods on hidden stretches of its own marker) or one method by name (linear,
    spline, pattern, rigid, model, pca)."""
    review = _review(take)
    hands = subject_hands(take.parameters, take.source_path)
    groups = gap_groups(review, hands.models, hands.marker_sets)
    gaps = find_review_gaps(review, groups)
    command = fill_review_gaps(review, groups, max_gap, method, progress, cancelled)
    filled = []
    if command is not None:
        command.do(review)
        filled = [FilledGap(fill.label, fill.start + take.first_frame,
                            fill.stop - 1 + take.first_frame, fill.method) for fill in command.fills]
    result = replace(labelled_take(review), parameters=dict(take.parameters))
    return FillResult(result, filled, len(gaps), int((review.provenance == -1).sum()))


@_one_blas_thread
def solve(take: Take, layout: str | PathArg | MarkerLayout | LabTemplate | None = None, side: str | None = None,
          method: str = "layered", progress: Progress = None, cancelled: Cancelled = None) -> dict[str, SolvedHand]:
    """Inverse kinematics of each hand of a labelled take over the whole take, as ``handmocap solve``: per side
    ("right", "left"), on the subject's calibrated hand when the take stores one, else the template hand.
    ``layout``: the layout or template the take is labelled with (recognised from the names when None)."""
    solved = solve_take(take, take_hands(take, str(layout) if isinstance(layout, PathLike) else layout, side),
                        method=method, progress=progress, cancelled=cancelled)
    return {hand.hand.side: SolvedHand(hand.hand.side, hand.result.joint_angles, PARAM_NAMES,
                                       hand.result.residuals_mm, list(hand.result.marker_names), hand.model,
                                       hand.result) for hand in solved}


@_one_blas_thread
def export(take: Take, path: PathArg, format: str = "c3d", units: str | None = None, up: str | None = None,
           hand: str | None = None, progress: Progress = None, cancelled: Cancelled = None) -> list[Path]:
    """Write a labelled take as ``format`` (``handmocap export --format``: c3d, trc, csv, bvh, gltf, ...),
    solving first the hands a format of joint angles needs. Returns the files written (one per hand for a
    BVH of two hands)."""
    chosen = export_format(format)
    review = _review(take)
    models = {}
    if chosen.joint_angles:
        hands = subject_hands(take.parameters, take.source_path)
        solve_unsolved_hands(review, hands.models, hands.marker_sets, progress, cancelled)
        models = hands.models
    hand_models = {track.side: models.get(track.side) or load_template(track.side) for track in review.hands}
    return export_review(review, path, format, units=units, up=up, hand=hand, models=hand_models,
                         subjects=subject_calibrations(take.parameters, take.source_path) or None)


@_one_blas_thread
def evaluate_labelling(take: Take, layout: str | PathArg | MarkerLayout | LabTemplate | None = None,
                       learn_on: int | None = None, hands: str = "auto", seed: int = 0, ghost_rate: float = 0.0,
                       progress: Progress = None) -> dict:
    """Strip, shuffle and relabel a lab's labelled take and compare with its own labels, as ``handmocap
    evaluate label --take``: per hand and object correct / wrong / missed %, the longest wrong run. Without
    ``layout`` a template is learned on the first ``learn_on`` frames (default half) and the rest is scored."""
    return evaluate_take_labelling(take, str(layout) if isinstance(layout, PathLike) else layout, learn_on,
                                   hands=hands, seed=seed, ghost_rate=ghost_rate, progress=progress)
