"""Accuracy of an automatic labelling against the ground truth of a simulated (or hand-labelled) take."""

from __future__ import annotations

import numpy as np

from handmocap.core.labelling.result import SceneLabelling


def _longest_run(flags: np.ndarray) -> int:
    """Longest run of True along axis 0 of ``flags (F,M)``, over all columns."""
    longest = 0
    run = np.zeros(flags.shape[1], dtype=np.int64)
    for row in flags:
        run = np.where(row, run + 1, 0)
        longest = max(longest, int(run.max(initial=0)))
    return longest


def labelling_accuracy(result: SceneLabelling, truth_point_marker: np.ndarray) -> dict[str, float]:
    """Compare ``result`` (a scene labelling, or anything with its ``assignment (F,M)`` and
    ``ghost_points (F,P)``) with the true marker index per point ``truth_point_marker (F,P)`` (-1 ghost or padding).

    Keys: ``correct_share`` share of observed hand-marker samples (a marker present as a point in a
    frame) labelled with their own point; ``missed_share`` share of them left unlabelled;
    ``wrong_share`` share of them labelled with another point; ``ghost_labelled_share`` share of
    the measured ghost points given a hand label; ``longest_swap_frames`` most consecutive frames a
    marker held a wrong point; ``observed_samples`` and ``ghost_points`` the denominators.
    """
    truth = np.asarray(truth_point_marker)
    frames, marker_count = result.assignment.shape
    true_column = np.full((frames, marker_count), -1, dtype=np.int64)
    frame_index, column_index = np.nonzero(truth >= 0)
    true_column[frame_index, truth[frame_index, column_index]] = column_index
    observed = true_column >= 0
    labelled = result.assignment >= 0
    correct = observed & (result.assignment == true_column)
    taken_truth = np.take_along_axis(truth, np.maximum(result.assignment, 0), axis=1)
    wrong = labelled & (taken_truth != np.arange(marker_count))
    labelled_points = np.zeros(truth.shape, dtype=bool)
    label_frames, label_markers = np.nonzero(labelled)
    labelled_points[label_frames, result.assignment[label_frames, label_markers]] = True
    ghosts = (truth < 0) & (result.ghost_points | labelled_points)
    observed_count, ghost_count = int(observed.sum()), int(ghosts.sum())
    return {
        "correct_share": float(correct.sum() / max(observed_count, 1)),
        "missed_share": float((observed & ~labelled).sum() / max(observed_count, 1)),
        "wrong_share": float((observed & wrong).sum() / max(observed_count, 1)),
        "ghost_labelled_share": float((ghosts & labelled_points).sum() / max(ghost_count, 1)),
        "longest_swap_frames": _longest_run(wrong),
        "observed_samples": observed_count,
        "ghost_points": ghost_count,
    }
