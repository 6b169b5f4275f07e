"""Trajectory continuity: extend a labelled marker trajectory into the unlabelled points next to it.

A marker's labelled samples end where the per-frame tracker lost it (its model estimate was too far
from the point, e.g. a fingertip reappearing after a long occlusion while the prior guessed the
finger wrong). The measured point usually continues smoothly on either side, so, as in Vicon's and
Qualisys' trajectory-based labelling, the trajectory is extended frame by frame into a free point
(one no marker took) that lies within ``link_mm`` of the constant-velocity extrapolation of its last
two samples, provided no other free point is within ``2 · link_mm`` of that extrapolation
(ambiguous: stop). At 100 Hz the extrapolation error of a hand marker is a fraction of a millimetre,
so a ghost — which appears tens of millimetres from any marker and never continues one — is not
linked. Forward extension is causal (usable online); backward extension needs the whole take.
"""

from __future__ import annotations

import numpy as np
from numba import njit

FIRST_LINK_FACTOR = 3.0
"""A free point's second sample is linked within this times ``link_mm`` of its first (no velocity is
known yet: a fingertip moving 0.5 m/s moves 5 mm per frame at 100 Hz); later samples within ``link_mm``
of the constant-velocity extrapolation."""


def _free_points(points: np.ndarray, assignment: np.ndarray) -> np.ndarray:
    """``(F, P)`` True for a measured point of ``points (F,P,3)`` that no marker of ``assignment (F,M)`` took."""
    free = np.isfinite(points).all(axis=2)
    label_frames, label_markers = np.nonzero(assignment >= 0)
    free[label_frames, assignment[label_frames, label_markers]] = False
    return free


def _continuation(candidates: np.ndarray, last: np.ndarray, previous: np.ndarray | None, gate_mm: float
                  ) -> tuple[int, float] | None:
    """Which of the points ``candidates (C,3)`` mm continues a trajectory at ``last (3,)`` (``previous
    (3,)`` the sample before it, or None): the nearest to the constant-velocity extrapolation, within
    ``gate_mm``, with no other candidate within ``2 · gate_mm``. Returns its index and the margin (mm,
    next-nearest distance minus its own, at most 1000), or None."""
    if not len(candidates):
        return None
    predicted = last if previous is None else 2.0 * last - previous
    distances = np.sqrt(((candidates - predicted) ** 2).sum(axis=1))
    order = np.argsort(distances)[:2]
    nearest = distances[order[0]]
    runner_up = distances[order[1]] if len(order) > 1 else np.inf
    if nearest > gate_mm or runner_up < 2.0 * gate_mm:
        return None
    return int(order[0]), float(min(runner_up, 1e3) - nearest)


def extend_trajectories(points: np.ndarray, assignment: np.ndarray, columns: np.ndarray, link_mm: float,
                        backward: bool = True) -> list[tuple[int, int, int, float]]:
    """Extend the labelled samples of the markers ``columns`` of ``assignment (F,M)`` (point column per
    marker, -1 missing; edited in place) into free points of ``points (F,P,3)`` mm.

    Returns the added samples as ``(frame, marker, point column, margin_mm)`` where the margin is the
    distance of the next-nearest free point minus that of the linked one."""
    frames = len(points)
    free = _free_points(points, assignment)
    added: list[tuple[int, int, int, float]] = []
    directions = (1, -1) if backward else (1,)
    for marker in columns:
        for direction in directions:
            labelled = assignment[:, marker] >= 0
            # frames where a labelled stretch ends in this direction
            ends = np.flatnonzero(labelled[:-1] & ~labelled[1:]) if direction == 1 else \
                np.flatnonzero(~labelled[:-1] & labelled[1:]) + 1
            for end in ends.tolist():
                last = points[end, assignment[end, marker]]
                before = end - direction
                previous = points[before, assignment[before, marker]] if 0 <= before < frames and \
                    assignment[before, marker] >= 0 else None
                frame = end + direction
                while 0 <= frame < frames and assignment[frame, marker] < 0:
                    candidates = np.flatnonzero(free[frame])
                    link = _continuation(points[frame, candidates], last, previous, link_mm)
                    if link is None:
                        break
                    column = int(candidates[link[0]])
                    assignment[frame, marker] = column
                    free[frame, column] = False
                    added.append((frame, int(marker), column, link[1]))
                    previous, last = last, points[frame, column]
                    frame += direction
    return added


def free_fragments(points: np.ndarray, assignment: np.ndarray, link_mm: float, min_frames: int
                   ) -> list[tuple[int, np.ndarray]]:
    """Trajectories of the free points (those no marker took) of ``points (F,P,3)``: each a first frame
    and the point column per frame ``(L,)``, linked frame to frame like :func:`extend_trajectories`
    (unambiguous constant-velocity continuation within ``link_mm``; the second sample within
    :data:`FIRST_LINK_FACTOR` × ``link_mm`` of the first); only those of at least
    ``min_frames`` frames are returned, in the order they ended (those open at the last frame last)."""
    free = _free_points(points, assignment)
    ended, first, length, sample_fragment, sample_column = _link_free_points(
        np.ascontiguousarray(points, dtype=np.float64), free, float(link_mm), FIRST_LINK_FACTOR)
    columns = sample_column[np.argsort(sample_fragment, kind="stable")]      # each fragment's samples in frame order
    starts = np.concatenate([[0], np.cumsum(length)])
    return [(int(first[fragment]), columns[starts[fragment]:starts[fragment + 1]])
            for fragment in ended.tolist() if length[fragment] >= min_frames]


@njit(cache=True, inline="always")
def _nearest_two(points: np.ndarray, candidates: np.ndarray, predicted: np.ndarray) -> tuple[int, float, float]:
    """Of the points ``points[candidates] (C,3)``: the index into ``candidates`` of the nearest to
    ``predicted (3,)`` (-1 none), its distance and the next-nearest distance (mm; inf when missing)."""
    best, nearest, runner_up = -1, np.inf, np.inf
    for k in range(candidates.shape[0]):
        column = candidates[k]
        dx = points[column, 0] - predicted[0]
        dy = points[column, 1] - predicted[1]
        dz = points[column, 2] - predicted[2]
        distance = np.sqrt(dx * dx + dy * dy + dz * dz)
        if distance < nearest:
            best, nearest, runner_up = k, distance, nearest
        elif distance < runner_up:
            runner_up = distance
    return best, nearest, runner_up


@njit(cache=True)
def _link_free_points(points: np.ndarray, free: np.ndarray, link_mm: float, first_factor: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The frame-to-frame linking of :func:`free_fragments` over ``free (F,P)`` samples of ``points (F,P,3)``:
    each open fragment, in order, takes the :func:`_continuation` of its last samples among the frame's free
    points unless an earlier fragment took that point; a point no fragment took starts one. Returns the
    fragments in the order they ended (K,), each fragment's first frame and length, and per sample (S,) its
    fragment and point column (in the order linked)."""
    frames, width = free.shape
    capacity = max(int(free.sum()), 1)
    sample_fragment = np.empty(capacity, dtype=np.int64)
    sample_column = np.empty(capacity, dtype=np.int64)
    first = np.empty(capacity, dtype=np.int64)
    length = np.zeros(capacity, dtype=np.int64)
    ended = np.empty(capacity, dtype=np.int64)
    open_ids = np.empty(width, dtype=np.int64)
    open_previous = np.empty((width, 3))
    open_last = np.empty((width, 3))
    open_moving = np.zeros(width, dtype=np.bool_)      # a fragment with two samples has a velocity
    next_ids = np.empty(width, dtype=np.int64)
    next_previous = np.empty((width, 3))
    next_last = np.empty((width, 3))
    next_moving = np.zeros(width, dtype=np.bool_)
    candidates = np.empty(width, dtype=np.int64)
    used = np.zeros(width, dtype=np.bool_)
    n_open = n_samples = n_fragments = n_ended = 0
    for frame in range(frames):
        n_candidates = 0
        for column in range(width):
            used[column] = False
            if free[frame, column]:
                candidates[n_candidates] = column
                n_candidates += 1
        n_next = 0
        for track in range(n_open):
            gate = link_mm if open_moving[track] else first_factor * link_mm
            predicted = 2.0 * open_last[track] - open_previous[track] if open_moving[track] else open_last[track]
            best, nearest, runner_up = _nearest_two(points[frame], candidates[:n_candidates], predicted)
            linked = best >= 0 and nearest <= gate and runner_up >= 2.0 * gate and not used[candidates[best]]
            fragment = open_ids[track]
            if not linked:
                ended[n_ended] = fragment
                n_ended += 1
                continue
            column = candidates[best]
            used[column] = True
            sample_fragment[n_samples], sample_column[n_samples] = fragment, column
            n_samples += 1
            length[fragment] += 1
            next_ids[n_next] = fragment
            next_previous[n_next] = open_last[track]
            next_last[n_next] = points[frame, column]
            next_moving[n_next] = True
            n_next += 1
        for k in range(n_candidates):
            column = candidates[k]
            if used[column]:
                continue
            first[n_fragments], length[n_fragments] = frame, 1
            sample_fragment[n_samples], sample_column[n_samples] = n_fragments, column
            n_samples += 1
            next_ids[n_next] = n_fragments
            next_last[n_next] = points[frame, column]
            next_moving[n_next] = False
            n_next += 1
            n_fragments += 1
        n_open = n_next
        open_ids[:n_open] = next_ids[:n_open]
        open_previous[:n_open] = next_previous[:n_open]
        open_last[:n_open] = next_last[:n_open]
        open_moving[:n_open] = next_moving[:n_open]
    for track in range(n_open):
        ended[n_ended] = open_ids[track]
        n_ended += 1
    return (ended[:n_ended], first[:n_fragments], length[:n_fragments], sample_fragment[:n_samples],
            sample_column[:n_samples])
