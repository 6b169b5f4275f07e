"""What some fills need besides the gap marker's trajectory: a hand model matched to the take
(:class:`ModelContext`, the model fill) and donor markers (:func:`choose_donors`, the pattern and rigid-body
fills)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.ik import match_layout, solve_positions
from handmocap.core.model import HandModel, MarkerLayout, MarkerSet, resolve_layout
from handmocap.core.prior import load_default_prior

#: frames on each side of a gap over which a donor's distance to the gap marker must stay steady
DONOR_WINDOW = 20


@dataclass(frozen=True, eq=False)
class ModelContext:
    """A hand model, a layout resolved on it, and the take column of each layout marker (-1 absent)."""

    model: HandModel
    layout: MarkerLayout
    markers: MarkerSet
    columns: np.ndarray

    @classmethod
    def for_take(cls, marker_names: list[str], model: HandModel, layout: MarkerLayout,
                 markers: MarkerSet | None = None) -> ModelContext:
        """Match ``layout`` to a take's ``marker_names`` by name, with ``markers`` (the subject's calibrated
        ones) or the layout resolved on ``model``."""
        return cls(model, layout, markers if markers is not None else resolve_layout(model, layout),
                   match_layout(marker_names, layout))

    def layout_index(self, marker: int) -> int:
        """Index in the layout of take column ``marker``; InputError when the layout lacks it."""
        found = np.flatnonzero(self.columns == marker)
        if not found.size:
            raise InputError(f"model fill: take marker {marker} is not in layout '{self.layout.name}'")
        return int(found[0])

    def layout_positions(self, positions: np.ndarray) -> np.ndarray:
        """(F, M_layout, 3) mm in layout order from take positions (F, M, 3); NaN for absent markers."""
        result = np.full((len(positions), len(self.columns), 3), np.nan)
        present = self.columns >= 0
        result[:, present] = positions[:, self.columns[present]]
        return result

    def solve(self, layout_positions: np.ndarray) -> np.ndarray:
        """Joint angles (F, 26) by layered IK of ``layout_positions (F, M_layout, 3)`` mm."""
        return solve_positions(layout_positions, self.model, self.markers, load_default_prior()).joint_angles


def choose_donors(positions: np.ndarray, marker: int, start: int, length: int, count: int,
                  method: str) -> np.ndarray:
    """``count`` donor columns for a gap: measured from the frame before to the frame after the gap, and
    with the steadiest distance to the gap marker over ``DONOR_WINDOW`` frames on each side, (count,)."""
    end = start + length
    if start < 1 or end >= len(positions):
        raise InputError(f"{method} fill needs observed frames on both sides of the gap")
    valid = np.isfinite(positions[start - 1:end + 1]).all(axis=(0, 2))
    valid[marker] = False
    candidates = np.flatnonzero(valid)
    if len(candidates) < count:
        raise InputError(f"{method} fill needs {count} donor marker(s) observed through the gap "
                         f"(frames {start - 1}..{end}); {len(candidates)} are")
    frames = np.r_[max(0, start - DONOR_WINDOW):start, end:min(len(positions), end + DONOR_WINDOW)]
    distances = np.linalg.norm(positions[frames][:, candidates] - positions[frames, marker][:, None], axis=2)
    samples = np.isfinite(distances).sum(axis=0)
    spread = np.where(samples >= 3, np.nanstd(np.where(samples >= 3, distances, 0.0), axis=0), np.inf)
    return candidates[np.argsort(spread, kind="stable")[:count]]
