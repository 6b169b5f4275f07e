"""Measure the labeller on a lab's own labelled take (``handmocap evaluate label --take``).

The take's labels are the truth. Its labelled points are stripped of their names and shuffled in every
frame (plus ghosts, when asked), labelled again with the lab's layout or template (or with a template
learned from the take's first frames, ``learn_on``: then only the frames after them are labelled), and
every labelled marker is compared with its true point. Figures per hand and object: correct, wrong and
missed shares of the samples where the marker is present, the longest run of frames a marker held a
wrong point and which marker it was; for objects also the share of their points given a hand label.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io import Take, is_marker_label
from handmocap.core.labelling.scene import label_scene
from handmocap.core.labelling.templates import learn_template
from handmocap.core.model import MarkerLayout
from handmocap.core.model.lab_template import LabTemplate


def stripped_take(take: Take, columns: np.ndarray, seed: int, ghost_rate: float = 0.0) -> tuple[Take, np.ndarray]:
    """The take's ``columns`` as unlabelled points, shuffled per frame, with ghosts in ``ghost_rate`` of the
    frames: the take and ``point_marker (F,P)``, the index into ``columns`` of each point (-1 ghost)."""
    from handmocap.core.simulate.take import _ghosts, _shuffled_points

    rng = np.random.default_rng([seed, 21])
    positions = take.marker_positions[:, columns]
    observed = np.concatenate([positions, _ghosts(positions, ghost_rate, rng)], axis=1) if ghost_rate else positions
    points, point_marker = _shuffled_points(observed, positions.shape[1], rng)
    stripped = Take(marker_names=[f"point_{index:03d}" for index in range(points.shape[1])], marker_positions=points,
                    frame_rate=take.frame_rate, first_frame=take.first_frame, vendor=take.vendor)
    return stripped, point_marker


def _longest_run(flags: np.ndarray) -> tuple[int, int]:
    """Longest run of True along axis 0 of ``flags (F,M)`` and its column (-1 when none)."""
    longest, where = 0, -1
    run = np.zeros(flags.shape[1], dtype=np.int64)
    for row in flags:
        run = np.where(row, run + 1, 0)
        if run.max(initial=0) > longest:
            longest, where = int(run.max()), int(run.argmax())
    return longest, where


def evaluate_take_labelling(take: Take, layout: str | MarkerLayout | LabTemplate | None = None,
                            learn_on: int | None = None, hands: str = "auto", seed: int = 0,
                            ghost_rate: float = 0.0, online: bool = False,
                            progress: Callable[[float], None] | None = None) -> dict:
    """Strip, shuffle and relabel ``take`` (module docstring) and compare with its own labels.

    ``layout``: the layout or template to label with; without one a template is learned from the first
    ``learn_on`` frames (default: half the take) and the frames after them are labelled. Returns a JSON-ready
    dict: ``groups`` (per hand side and object: markers, samples, correct/wrong/missed %, longest wrong run
    and its marker; objects: ``taken_as_hand_pct``), the ``overall`` figures, frames, seconds and the
    template's learning report when one was learned. :class:`InputError` when the take has no labels or
    ``learn_on`` leaves no frame."""
    labelled = [index for index, name in enumerate(take.marker_names) if is_marker_label(name)]
    if not labelled:
        raise InputError(f"{take.source_path or 'the take'}: no labelled markers to measure the labeller against; "
                         "give a take the lab labelled")
    learned_report = None
    evaluated = take
    if layout is None or learn_on is not None:
        first = take.n_frames // 2 if learn_on is None else int(learn_on)
        if not 0 < first < take.n_frames:
            raise InputError(f"--learn-on must be between 1 and {take.n_frames - 1} frames, got {first}")
        if layout is None:
            learned = learn_template([replace(take, marker_positions=take.marker_positions[:first])],
                                     name="learned for evaluation")
            layout, learned_report = learned.template, learned.report
        evaluated = replace(take, marker_positions=take.marker_positions[first:], first_frame=take.first_frame + first)
    columns = np.array(labelled, dtype=np.int64)
    stripped, point_marker = stripped_take(evaluated, columns, seed, ghost_rate)
    start = time.perf_counter()
    result = label_scene(stripped, hands, layout, online=online, progress=progress)
    seconds = time.perf_counter() - start
    names = [take.marker_names[index] for index in columns]
    lookup = {name.strip().lower(): index for index, name in enumerate(names)}
    truth_of_marker = np.array([lookup.get(name.strip().lower(), -1) for name in result.marker_names])
    groups = _group_figures(result, point_marker, truth_of_marker, names)
    total = {key: sum(group[key] for group in groups.values()) for key in ("samples", "correct", "wrong", "missed")}
    overall = {key + "_pct": round(100.0 * total[key] / max(total["samples"], 1), 3) for key in
               ("correct", "wrong", "missed")}
    unmatched = [name for name, truth in zip(result.marker_names, truth_of_marker, strict=True) if truth < 0]
    return {"frames": int(evaluated.n_frames), "frames_learned_on": int(take.n_frames - evaluated.n_frames),
            "labelled_markers": len(names), "seconds": round(seconds, 2),
            "frames_per_second": round(evaluated.n_frames / max(seconds, 1e-9), 1),
            "overall": {**overall, "samples": total["samples"]}, "groups": groups,
            "labels_not_in_take": unmatched, "template": learned_report}


def _group_figures(result, point_marker: np.ndarray, truth_of_marker: np.ndarray, names: list[str]) -> dict:
    """Per model of ``result``: the figures of :func:`evaluate_take_labelling` (counts and percentages)."""
    frames = point_marker.shape[0]
    true_point = np.full((frames, len(names)), -1, dtype=np.int64)
    rows, points = np.nonzero(point_marker >= 0)
    true_point[rows, point_marker[rows, points]] = points
    hand_taken = np.zeros(point_marker.shape, dtype=bool)
    for model in result.models:
        if model.kind != "object":
            assignment = result.assignment[:, model.markers]
            rows, markers = np.nonzero(assignment >= 0)
            hand_taken[rows, assignment[rows, markers]] = True
    groups: dict[str, dict] = {}
    for model in result.models:
        indices = np.arange(len(result.marker_names))[model.markers]
        indices = indices[truth_of_marker[indices] >= 0]
        if not len(indices):
            continue
        assignment = result.assignment[:, indices]
        truth = true_point[:, truth_of_marker[indices]]
        present = truth >= 0
        correct = present & (assignment == truth)
        wrong = (assignment >= 0) & (assignment != truth)
        missed = present & (assignment < 0)
        samples = int(present.sum())
        longest, column = _longest_run(wrong)
        figures = {"markers": len(indices), "samples": samples, "correct": int(correct.sum()),
                   "wrong": int(wrong.sum()), "missed": int(missed.sum()),
                   "correct_pct": round(100.0 * correct.sum() / max(samples, 1), 3),
                   "wrong_pct": round(100.0 * wrong.sum() / max(samples, 1), 3),
                   "missed_pct": round(100.0 * missed.sum() / max(samples, 1), 3),
                   "longest_wrong_frames": longest,
                   "longest_wrong_marker": result.marker_names[indices[column]] if column >= 0 else None}
        if model.kind == "object":
            own = np.isin(point_marker, truth_of_marker[indices])
            figures["taken_as_hand_pct"] = round(100.0 * (own & hand_taken).sum() / max(own.sum(), 1), 3)
        groups[model.name] = figures
    return groups
