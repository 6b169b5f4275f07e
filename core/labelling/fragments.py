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
    ``min_frames`` frames are returned."""
    free = _free_points(points, assignment)
    open_tracks: list[list] = []          # [first frame, columns, previous point, last point]
    done: list[tuple[int, np.ndarray]] = []
    for frame in range(len(points)):
        candidates = np.flatnonzero(free[frame])
        used: set[int] = set()
        still_open = []
        for track in open_tracks:
            # no velocity yet after one sample: the point may have moved a marker's frame-to-frame distance
            gate = FIRST_LINK_FACTOR * link_mm if track[2] is None else link_mm
            link = _continuation(points[frame, candidates], track[3], track[2], gate)
            column = None if link is None else int(candidates[link[0]])
            if column is not None and column not in used:
                used.add(column)
                track[1].append(column)
                track[2], track[3] = track[3], points[frame, column]
                still_open.append(track)
            elif len(track[1]) >= min_frames:
                done.append((track[0], np.array(track[1])))
        for unlinked in candidates.tolist():
            if unlinked not in used:
                still_open.append([frame, [unlinked], None, points[frame, unlinked]])
        open_tracks = still_open
    done += [(track[0], np.array(track[1])) for track in open_tracks if len(track[1]) >= min_frames]
    return done
