"""Gap detection: runs of missing samples per marker (0-based frames)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handmocap.core.io import Take


@dataclass(frozen=True)
class Gap:
    """Missing frames ``start .. start + length - 1`` of marker column ``marker`` (``name``).

    ``open`` is True when the run touches the first or last frame of the take (observed on one side only).
    """

    marker: int
    name: str
    start: int
    length: int
    open: bool = False

    @property
    def end(self) -> int:
        """First frame after the gap (exclusive end)."""
        return self.start + self.length


def find_gaps(take: Take) -> list[Gap]:
    """Every run of missing samples that has an observed sample on at least one side, by marker then frame.

    A marker missing in every frame has no gap (nothing to fill from).
    """
    missing = take.missing_mask
    n_frames = missing.shape[0]
    padded = np.zeros((missing.shape[1], n_frames + 2), dtype=np.int8)
    padded[:, 1:-1] = missing.T
    change = np.diff(padded, axis=1)
    starts = np.argwhere(change == 1)
    ends = np.argwhere(change == -1)
    gaps = []
    for (marker, start), (_, end) in zip(starts.tolist(), ends.tolist(), strict=True):
        if start == 0 and end == n_frames:
            continue
        gaps.append(Gap(marker, take.marker_names[marker], start, end - start,
                        open=start == 0 or end == n_frames))
    return gaps
