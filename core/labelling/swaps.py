"""Neighbouring-marker swaps, tested as explicit hypotheses over fragments (issue 10, Maycock et al.
2015 §III-D: "labels of neighbouring fingers are easily confused").

A tracker that takes two neighbouring markers' points the wrong way round (ring and middle fingertip,
a fingertip and its own middle marker), or gives a marker its hidden neighbour's point (a finger
shift), keeps them so for as long as they stay in view: the IK bends
the hand to fit, and a subject calibration on those frames even moves the markers to make it fit. A
swap shows as residuals on the two markers well above the hand's typical residual; it is settled by
solving the IK both ways on frames sampled over the fragment (the stretch where both markers are
labelled and each keeps to one unambiguously linked point trajectory) and keeping the
labelling of clearly lower energy. Fragments are tested in both directions of time alike (the test
uses the whole fragment), so a swap that started at an initialisation is repaired as well as one
that started at a crossing.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit

from handmocap.core.labelling.take_statistics import unambiguous_links

NEIGHBOURS = 3
"""Each marker is tested against its this many nearest markers on the hand (mean posture of the prior)."""
SUSPECT_RATIO = 1.25
"""A fragment is tested when the two markers' mean residual there exceeds this times the hand's typical one."""
ENERGY_RATIO = 0.75
"""The swapped labelling is kept when its IK energy over the sampled frames is below this share of the
labelling as found, and lower by more than 4 σ² per sampled frame (a clear preference, not a coin
toss between two equally poor fits)."""
SAMPLE_FRAMES = 6
"""Frames of a fragment the IK is solved on, both ways."""
MIN_FRAGMENT_FRAMES = 5
"""Shorter fragments are not tested (a swap of a few frames at a crossing costs little, and the IK
evidence of so few frames is weak)."""


def neighbour_pairs(rest_positions: np.ndarray, count: int = NEIGHBOURS) -> list[tuple[int, int]]:
    """Pairs (a < b) of markers among each marker's ``count`` nearest in ``rest_positions (K,3)`` mm."""
    distances = np.linalg.norm(rest_positions[:, None] - rest_positions[None], axis=2)
    np.fill_diagonal(distances, np.inf)
    pairs = {(min(a, b), max(a, b)) for a in range(len(rest_positions))
             for b in np.argsort(distances[a])[:count].tolist()}
    return sorted(pairs)


def point_tracklets(positions: np.ndarray, block: int = 2048) -> np.ndarray:
    """``(F,P)`` an id per measured point of ``positions (F,P,3)`` mm (-1 where absent): points linked
    frame to frame where the link is unambiguous (:func:`core.labelling.take_statistics.unambiguous_links`)
    share an id, so one id is one stretch of one physical marker as far as the points alone can tell."""
    frames, count = positions.shape[:2]
    links = np.full((max(frames - 1, 0), count), -1, dtype=np.int64)
    for start in range(0, frames - 1, block):
        stop = min(start + block, frames - 1)
        links[start:stop] = unambiguous_links(positions[start:stop], positions[start + 1:stop + 1])
    present = np.isfinite(positions).all(axis=2)
    return _chain_ids(links, present)


@njit(cache=True)
def _chain_ids(links: np.ndarray, present: np.ndarray) -> np.ndarray:
    frames, count = present.shape
    ids = np.full((frames, count), -1, dtype=np.int64)
    next_id = 0
    for frame in range(frames):
        for column in range(count):
            if present[frame, column] and ids[frame, column] < 0:
                ids[frame, column] = next_id
                next_id += 1
        if frame + 1 < frames:
            for column in range(count):
                target = links[frame, column]
                if ids[frame, column] >= 0 and target >= 0 and present[frame + 1, target]:
                    ids[frame + 1, target] = ids[frame, column]
    return ids


def pair_fragments(first: np.ndarray, second: np.ndarray, tracklets: np.ndarray) -> list[tuple[int, int]]:
    """Frame ranges ``[start, stop)`` where at least one of two markers is labelled (``first``/``second
    (F,)`` point columns, -1 none) and each keeps to one tracklet of ``tracklets (F,P)``
    (:func:`point_tracklets`) or stays unlabelled: the stretches over which exchanging the two labels
    (or moving the one label to the other marker) is one hypothesis. Ranges shorter than
    :data:`MIN_FRAGMENT_FRAMES` are left out."""
    frames = np.arange(len(first))
    key_first = np.where(first >= 0, tracklets[frames, np.maximum(first, 0)], -1)
    key_second = np.where(second >= 0, tracklets[frames, np.maximum(second, 0)], -1)
    either = (first >= 0) | (second >= 0)
    change = np.ones(len(first) + 1, dtype=bool)
    change[1:-1] = (key_first[1:] != key_first[:-1]) | (key_second[1:] != key_second[:-1])
    edges = np.flatnonzero(change)
    return [(int(start), int(stop)) for start, stop in zip(edges[:-1], edges[1:], strict=True)
            if either[start] and stop - start >= MIN_FRAGMENT_FRAMES]


def repair_swaps(assignment: np.ndarray, residuals: np.ndarray, tracklets: np.ndarray, pairs: list[tuple[int, int]],
                 energy: Callable[[int, np.ndarray], float], floor_mm: float, every_fragment: bool = False
                 ) -> list[tuple[int, int, int, int]]:
    """Test and repair swaps of a hand's markers (both labelled: the labels exchanged; one labelled: its
    label moved to the other marker). ``assignment (F,K)`` point column per marker (-1 none),
    edited in place; ``residuals (F,K)`` mm of that labelling; ``tracklets (F,P)`` of
    :func:`point_tracklets`; ``energy(frame, index (K,))`` the IK
    energy (mm², summed over the markers) of the hand solved with those labels in that frame; ``floor_mm``
    the noise radius: the swapped energy must be lower by more than a quarter of its square (4 σ²) per
    sampled frame (a
    fragment is suspect when its residual exceeds :data:`SUSPECT_RATIO` × the hand's median, which
    already holds the noise); ``every_fragment``: test every fragment, not only
    those whose residual is suspect (a short window labelled with the uncalibrated template, whose
    residuals are high everywhere). Returns the swaps made as (a, b, start, stop)."""
    finite = residuals[np.isfinite(residuals)]
    if not len(finite):
        return []
    suspect_mm = 0.0 if every_fragment else SUSPECT_RATIO * float(np.median(finite))
    repaired = []
    for a, b in pairs:
        for start, stop in pair_fragments(assignment[:, a], assignment[:, b], tracklets):
            span = slice(start, stop)
            pair_residuals = residuals[span][:, [a, b]]
            pair_residual = float(np.nanmean(pair_residuals)) if np.isfinite(pair_residuals).any() else 0.0
            if not pair_residual > suspect_mm:
                continue
            sample = np.unique(np.linspace(start, stop - 1, min(SAMPLE_FRAMES, stop - start)).round().astype(int))
            as_found = swapped = 0.0
            for frame in sample:
                index = assignment[frame].copy()
                as_found += energy(int(frame), index)
                index[[a, b]] = index[[b, a]]
                swapped += energy(int(frame), index)
            if swapped < ENERGY_RATIO * as_found and as_found - swapped > len(sample) * (floor_mm / 2.0) ** 2:
                assignment[span, a], assignment[span, b] = assignment[span, b].copy(), assignment[span, a].copy()
                repaired.append((a, b, start, stop))
    return repaired


def unify_tracklets(assignment: np.ndarray, tracklets: np.ndarray, energy: Callable[[int, np.ndarray], float]
                    ) -> int:
    """One physical point trajectory carries one label: where a tracklet (:func:`point_tracklets`) is
    labelled with a marker on most of its frames and with another marker on a stretch while that
    marker is unlabelled there (a neighbour took the point while its own marker was lost), the stretch is
    given to the majority marker when the IK fits at least as well so (sampled frames). ``assignment
    (F,K)`` point column per marker, edited in place. Returns the samples moved."""
    frames, markers = np.nonzero(assignment >= 0)
    columns = assignment[frames, markers]
    ids = tracklets[frames, columns]
    keep = ids >= 0
    frames, markers, ids = frames[keep], markers[keep], ids[keep]
    count = assignment.shape[1]
    keys, counts = np.unique(ids * count + markers, return_counts=True)
    key_ids = keys // count
    distinct_ids, labels_per_id = np.unique(key_ids, return_counts=True)
    multi = distinct_ids[labels_per_id > 1]
    moved = 0
    for tracklet in multi:
        mine = key_ids == tracklet
        majority = int(keys[mine][np.argmax(counts[mine])] % count)
        on_it = ids == tracklet
        for other in np.unique(markers[on_it & (markers != majority)]):
            stretch = np.sort(frames[on_it & (markers == other)])
            stretch = stretch[assignment[stretch, majority] < 0]
            if not len(stretch):
                continue
            sample = stretch[np.unique(np.linspace(0, len(stretch) - 1, min(SAMPLE_FRAMES, len(stretch)))
                                       .round().astype(int))]
            as_found = moved_energy = 0.0
            for frame in sample:
                index = assignment[frame].copy()
                as_found += energy(int(frame), index)
                index[majority], index[other] = index[other], -1
                moved_energy += energy(int(frame), index)
            if moved_energy <= as_found:
                assignment[stretch, majority] = assignment[stretch, other]
                assignment[stretch, other] = -1
                moved += len(stretch)
    return moved
