"""Gap-fill accuracy on a real take: hide known stretches of finger markers, fill, compare with the truth."""

from __future__ import annotations

import numpy as np

from core.errors import InputError
from core.gaps.check import FILL_METHODS, ModelContext, fill_gap
from core.gaps.fills import SPLINE_CONTEXT
from core.io import Take
from core.model import HandModel, MarkerLayout


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
                      methods: tuple[str, ...] = FILL_METHODS, margin: int = SPLINE_CONTEXT) -> dict:
    """Mean and worst-frame fill error (mm) of each method per gap length on ``n_trials`` hidden stretches
    per length.

    Each trial hides ``length`` measured frames of one of ``markers`` (default: the finger markers of
    the layout), chosen at random among stretches with ``margin`` measured frames on each side; every
    method fills the same stretches (the model fill solves its IK with the stretch hidden). Returns
    ``{"lengths": [...], "mean_error_mm": {method: {length: mm}}, "worst_error_mm": {method: {length:
    mm}}, "trials": {method: {length: count}}}``: the mean over every hidden frame and the largest error
    in any of them; a method counts only the trials it applies to (NaN when none).
    """
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
    :func:`core.batch.evaluate_hidden_gaps`) as a text table: one row per method, "mean / worst" mm per length."""
    lengths = evaluation["lengths"]
    lines = ["method  " + "".join(f"{f'{length} fr mean / worst':>22}" for length in lengths)]
    for method, means in evaluation["mean_error_mm"].items():
        worst = evaluation["worst_error_mm"][method]
        lines.append(f"{method:<8}" + "".join(f"{f'{means[length]:.2f} / {worst[length]:.1f}':>22}"
                                              for length in lengths))
    return "\n".join(lines)
