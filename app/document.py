"""An open take in the application: the take, its layout choice, its IK result and its solve request."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from core.ik import IKResult
from core.io import Take
from core.model import best_layout_for, load_layout, marker_columns


@dataclass(eq=False)
class TakeDocument:
    """One take shown in the main window.

    ``solve_request`` is the id of the solve whose result may still be applied (0: none pending); a
    result arriving with another id is stale and dropped. ``auto_solve``: solve it as soon as the
    solver is free (demo takes, ``--solve``). ``current_frame``: where the operator left it (0-based).
    ``side``: the hand the next solve fits ("right" or "left"); the result knows its own.
    """

    take: Take
    title: str
    layout_name: str | None = None
    result: IKResult | None = None
    solve_request: int = 0
    auto_solve: bool = False
    current_frame: int = 0
    side: str = "right"
    _columns: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.layout_name is None:
            self.layout_name = best_layout_for(self.take.marker_names)

    @cached_property
    def markers_seen(self) -> np.ndarray:
        """Observed markers per frame ``(F,)``."""
        return (~self.take.missing_mask).sum(axis=1)

    @cached_property
    def observed_fraction(self) -> np.ndarray:
        """Share of frames each marker is observed in ``(M,)``."""
        return 1.0 - self.take.missing_fraction_per_marker

    def hand_columns(self) -> np.ndarray:
        """Take columns of the chosen layout's markers (all columns when no layout matches)."""
        if self.layout_name is None:
            return np.arange(self.take.n_markers)
        columns = self.columns_of(load_layout(self.layout_name).names)
        return columns[columns >= 0] if (columns >= 0).any() else np.arange(self.take.n_markers)

    def columns_of(self, names: list[str]) -> np.ndarray:
        """Take column of each marker name, -1 where the take lacks it ``(len(names),)``."""
        return marker_columns(self.take.marker_names, names)

    def set_result(self, result: IKResult) -> None:
        """Attach an IK result; its markers are matched to the take's columns by name."""
        self._columns = self.columns_of(result.marker_names)
        self.result = result

    def residuals_per_take_marker(self, frame: int) -> np.ndarray | None:
        """IK residual (mm) of each take marker at ``frame`` ``(M_take,)`` (NaN: none), or None."""
        if self.result is None or self._columns is None:
            return None
        residuals = np.full(self.take.n_markers, np.nan)
        present = self._columns >= 0
        residuals[self._columns[present]] = self.result.residuals_mm[frame, present]
        return residuals

    def mean_residual_per_frame(self) -> np.ndarray | None:
        """Mean IK residual over the observed markers of each frame ``(F,)`` mm (NaN: none), or None."""
        if self.result is None:
            return None
        residuals = self.result.residuals_mm
        observed = np.isfinite(residuals)
        counts = observed.sum(axis=1)
        sums = np.where(observed, residuals, 0.0).sum(axis=1)
        return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)

    def effector_targets(self, frame: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Effector positions ``(K,3)`` and the measured positions of their markers ``(K,3)`` mm."""
        if self.result is None or self._columns is None:
            return None
        targets = np.full((len(self._columns), 3), np.nan)
        present = self._columns >= 0
        targets[present] = self.take.marker_positions[frame, self._columns[present]]
        return self.result.effector_positions[frame], targets
