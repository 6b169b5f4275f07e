"""Swap suspects from each marker's own speed (issue 23 item 3): a vendor-labelled take whose fingers move
fast at 60 Hz shows none, while swaps of neighbouring markers put into it are all found."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from handmocap.core.io import load_take
from handmocap.core.review import ReviewTake

ART_TAKE = "c3d/sample_37__ART-Human_hands_real_no6dof.c3d"


def _with_swaps(take, seed: int, count: int):
    """``take`` with ``count`` swaps of a marker and its nearest neighbour (5 to 50 frames long)."""
    rng = np.random.default_rng(seed)
    positions = take.marker_positions.copy()
    swaps = []
    while len(swaps) < count:
        frame, first = int(rng.integers(10, take.n_frames - 60)), int(rng.integers(take.n_markers))
        distances = np.linalg.norm(positions[frame] - positions[frame, first], axis=1)
        distances[first] = np.inf
        distances[~np.isfinite(distances)] = np.inf
        if not np.isfinite(distances).any():
            continue
        second, length = int(np.argmin(distances)), int(rng.integers(5, 50))
        positions[frame:frame + length, [first, second]] = positions[frame:frame + length, [second, first]]
        swaps.append((frame, first, second))
    return replace(take, marker_positions=positions), swaps


def test_a_vendor_labelled_take_has_no_swap_suspect_and_swaps_put_in_are_found(shared_data):
    path = shared_data / ART_TAKE
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    take = load_take(path)
    assert ReviewTake.from_labelled_take(take).problems(["swap"]) == []     # was 63 "jump of 12 mm"
    found = total = 0
    for seed in range(4):
        swapped, swaps = _with_swaps(take, seed, 8)
        suspects = ReviewTake.from_labelled_take(swapped).problems(["swap"])
        for frame, first, second in swaps:
            total += 1
            found += any(abs(problem.start - frame) <= 1 and {problem.label, problem.other} & {first, second}
                         for problem in suspects)
    assert found == total, f"{found} of {total} swaps found"


def test_a_one_frame_spike_is_no_swap_suspect(real_recording):
    positions = real_recording.marker_positions.copy()
    positions[1200, 3] += (0.0, 0.0, 25.0)                                 # one frame off by 25 mm, then back
    review = ReviewTake.from_labelled_take(replace(real_recording, marker_positions=positions))
    assert not [problem for problem in review.problems(["swap"]) if 1199 <= problem.start <= 1201]
