"""An open take in the application: the take, its layout choice and its IK result."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.ik import IKResult, match_layout
from core.io import Take
from core.model import best_layout_for, load_layout


@dataclass(eq=False)
class TakeDocument:
    """One take shown in the main window. ``solve_request`` is the id of the solve whose result
    may still be applied (0: none pending)."""

    take: Take
    title: str
    layout_name: str | None = None
    result: IKResult | None = None
    solve_request: int = 0
    auto_solve: bool = False
    _columns: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.layout_name is None:
            self.layout_name = best_layout_for(self.take.marker_names)

    @property
    def markers_seen(self) -> np.ndarray:
        """Observed markers per frame ``(F,)``."""
        return (~self.take.missing_mask).sum(axis=1)

    @property
    def observed_fraction(self) -> np.ndarray:
        """Share of frames each marker is observed in ``(M,)``."""
        return 1.0 - self.take.missing_fraction_per_marker

    def hand_columns(self) -> np.ndarray:
        """Take columns of the layout's markers (all columns when no layout matches)."""
        if self.layout_name is None:
            return np.arange(self.take.n_markers)
        columns = match_layout(self.take.marker_names, load_layout(self.layout_name))
        return columns[columns >= 0]

    def set_result(self, result: IKResult) -> None:
        """Attach an IK result; its markers are matched to the take's columns by name."""
        self.result = result
        layout_columns = match_layout(self.take.marker_names, load_layout(self.layout_name))
        self._columns = layout_columns

    def residuals_per_take_marker(self, frame: int) -> np.ndarray | None:
        """IK residual (mm) of each take marker at ``frame`` ``(M_take,)`` (NaN: none), or None."""
        if self.result is None or self._columns is None:
            return None
        residuals = np.full(self.take.n_markers, np.nan)
        present = self._columns >= 0
        residuals[self._columns[present]] = self.result.residuals_mm[frame, present]
        return residuals

    def effector_targets(self, frame: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Effector positions ``(K,3)`` and the measured positions of their markers ``(K,3)`` mm."""
        if self.result is None or self._columns is None:
            return None
        targets = np.full((len(self._columns), 3), np.nan)
        present = self._columns >= 0
        targets[present] = self.take.marker_positions[frame, self._columns[present]]
        return self.result.effector_positions[frame], targets
