"""Gap-fill accuracy on a real take: hide known stretches of finger markers, fill, compare with the truth."""

from __future__ import annotations

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.gaps import ModelContext, fill_gap, fill_method_names
from handmocap.core.gaps.fills import SPLINE_CONTEXT
from handmocap.core.io import Take
from handmocap.core.model import HandModel, MarkerLayout, load_template
from handmocap.core.review import ReviewTake
from handmocap.core.workflows import fill_review_gaps, gap_groups


def finger_marker_names(context: ModelContext) -> list[str]:
    """Names of the layout markers present in the take and carried mostly by a finger joint (not the wrist)."""
    markers = context.markers
    dominant = markers.influence_joints[np.arange(len(markers.names)), markers.influence_weights.argmax(axis=1)]
    return [name for name, joint, column in zip(markers.names, dominant, context.columns, strict=True)
            if joint != 0 and column >= 0]


GAP_LENGTHS = (10, 20, 40, 80)


def marker_columns(take: Take, context: ModelContext, markers: list[str] | None = None) -> list[int]:
    """Take columns of ``markers`` (default: the finger markers of the context's layout); InputError when
    one is not in the take."""
    names = markers if markers is not None else finger_marker_names(context)
    lookup = {name: index for index, name in enumerate(take.marker_names)}
    absent = [name for name in names if name not in lookup]
    if absent or not names:
        raise InputError(f"markers not in the take: {', '.join(absent) or 'none given'}")
    return [lookup[name] for name in names]


def evaluate_gap_fill(take: Take, model: HandModel, layout: MarkerLayout, lengths: tuple[int, ...] = GAP_LENGTHS,
                      markers: list[str] | None = None, n_trials: int = 30, seed: int = 0,
                      methods: tuple[str, ...] | None = None, margin: int = SPLINE_CONTEXT) -> dict:
    """Mean and worst-frame fill error (mm) of each method per gap length on ``n_trials`` hidden stretches
    per length.

    Each trial hides ``length`` measured frames of one of ``markers`` (default: the finger markers of
    the layout), chosen at random among stretches with ``margin`` measured frames on each side; every
    method fills the same stretches (the model fill solves its IK with the stretch hidden). Returns
    ``{"lengths": [...], "mean_error_mm": {method: {length: mm}}, "worst_error_mm": {method: {length:
    mm}}, "trials": {method: {length: count}}}``: the mean over every hidden frame and the largest error
    in any of them; a method counts only the trials it applies to (NaN when none). ``methods``: default every
    registered one (:func:`core.gaps.fill_method_names`).
    """
    methods = fill_method_names() if methods is None else methods
    context = ModelContext.for_take(take.marker_names, model, layout)
    columns = marker_columns(take, context, markers)
    observed = ~take.missing_mask
    rng = np.random.default_rng(seed)
    positions = take.marker_positions
    errors: dict[str, dict[int, list[np.ndarray]]] = {method: {length: [] for length in lengths} for method in methods}
    for length in lengths:
        size = length + 2 * margin
        windows = np.array([(column, start + margin) for column in columns
                            for start in np.flatnonzero(np.convolve(observed[:, column], np.ones(size, dtype=int),
                                                                    mode="valid") == size)], dtype=np.int64)
        if not len(windows):
            raise InputError(f"no measured stretch of {size} frames to hide for gaps of {length} frames")
        picks = rng.choice(len(windows), size=min(n_trials, len(windows)), replace=False)
        for column, start in windows[picks]:
            hidden = positions.copy()
            hidden[start:start + length, column] = np.nan
            truth = positions[start:start + length, column]
            for method in methods:
                try:
                    values = fill_gap(hidden, int(column), int(start), length, method, context)
                except InputError:
                    continue
                errors[method][length].append(np.linalg.norm(values - truth, axis=1))
    return {
        "lengths": list(lengths),
        "mean_error_mm": {method: {length: float(np.mean(values)) if values else float("nan")
                                   for length, values in per_length.items()}
                          for method, per_length in errors.items()},
        "worst_error_mm": {method: {length: float(np.max(values)) if values else float("nan")
                                    for length, values in per_length.items()}
                           for method, per_length in errors.items()},
        "trials": {method: {length: len(values) for length, values in per_length.items()}
                   for method, per_length in errors.items()},
    }


def format_gap_fill_table(evaluation: dict) -> str:
    """An evaluation with ``lengths``, ``mean_error_mm`` and ``worst_error_mm`` (:func:`evaluate_gap_fill`,
    :func:`core.workflows.evaluate_hidden_gaps`) as a text table: one row per method, "mean / worst" mm per length."""
    lengths = evaluation["lengths"]
    lines = ["method  " + "".join(f"{f'{length} fr mean / worst':>22}" for length in lengths)]
    for method, means in evaluation["mean_error_mm"].items():
        worst = evaluation["worst_error_mm"][method]
        lines.append(f"{method:<8}" + "".join(f"{f'{means[length]:.2f} / {worst[length]:.1f}':>22}"
                                              for length in lengths))
    return "\n".join(lines)


def hide_gaps(take: Take, columns: list[int], length: int, count: int, rng: np.random.Generator,
              margin: int = SPLINE_CONTEXT) -> tuple[Take, list[tuple[int, int]]]:
    """A copy of ``take`` with up to ``count`` gaps of ``length`` frames hidden at random in ``columns``,
    each inside measured samples with ``margin`` measured frames on each side (gaps of different markers
    may overlap in time), and the hidden ``(column, start)`` pairs."""
    positions = take.marker_positions.copy()
    hidden: list[tuple[int, int]] = []
    size = length + 2 * margin
    for _ in range(50 * count):
        if len(hidden) == count or take.n_frames < size:
            break
        column = int(columns[rng.integers(len(columns))])
        start = int(rng.integers(margin, take.n_frames - length - margin + 1))
        if np.isfinite(positions[start - margin:start + length + margin, column]).all():
            positions[start:start + length, column] = np.nan
            hidden.append((column, start))
    return Take(marker_names=list(take.marker_names), marker_positions=positions, frame_rate=take.frame_rate,
                first_frame=take.first_frame, vendor=take.vendor), hidden


def evaluate_hidden_gaps(take: Take, layout: MarkerLayout, lengths: tuple[int, ...] = GAP_LENGTHS, n_gaps: int = 30,
                         seed: int = 0, methods: tuple[str, ...] = ("auto", "pca"),
                         markers: list[str] | None = None) -> dict:
    """Fill error of ``handmocap fill --method M`` on ``n_gaps`` gaps hidden at once per length.

    For each length, :func:`hide_gaps` hides the gaps in ``markers`` (default: the finger markers of
    ``layout``) of the labelled ``take``; each method fills the review of that take with
    :func:`fill_review_gaps` (maximum gap: the length), as the command line does. Returns
    ``{"lengths", "mean_error_mm": {method: {length: mm}}, "worst_error_mm": {...}, "gaps": {length:
    hidden}, "unfilled": {method: {length: count}}, "chosen": {method: {length: {fill method: count}}}}``:
    mean over the hidden frames that were filled and the largest error in any of them.
    """
    context = ModelContext.for_take(take.marker_names, load_template(), layout)
    columns = marker_columns(take, context, markers)
    rng = np.random.default_rng(seed)
    result: dict = {"lengths": list(lengths), "mean_error_mm": {}, "worst_error_mm": {}, "gaps": {}, "unfilled": {},
                    "chosen": {}}
    for method in methods:
        for key in ("mean_error_mm", "worst_error_mm", "unfilled", "chosen"):
            result[key][method] = {}
    for length in lengths:
        hidden_take, hidden = hide_gaps(take, columns, length, n_gaps, rng)
        result["gaps"][length] = len(hidden)
        truth = take.marker_positions
        for method in methods:
            review = ReviewTake.from_labelled_take(hidden_take)
            command = fill_review_gaps(review, gap_groups(review), length, method)
            if command is not None:
                command.do(review)
            filled = review.labelled_positions()
            errors = np.concatenate([np.linalg.norm(filled[start:start + length, column]
                                                    - truth[start:start + length, column], axis=1)
                                     for column, start in hidden])
            done = np.isfinite(errors)
            result["mean_error_mm"][method][length] = float(errors[done].mean()) if done.any() else float("nan")
            result["worst_error_mm"][method][length] = float(errors[done].max()) if done.any() else float("nan")
            result["unfilled"][method][length] = int((~done).reshape(len(hidden), length).all(axis=1).sum())
            keys = {(review.label_names[column], start) for column, start in hidden}
            chosen: dict[str, int] = {}
            for fill in command.fills if command is not None else []:
                if (fill.label, fill.start) in keys:
                    chosen[fill.method] = chosen.get(fill.method, 0) + 1
            result["chosen"][method][length] = chosen
    return result
