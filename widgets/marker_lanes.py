"""Marker lanes: one horizontal lane per marker over the take's frames, coloured by the state of each
sample (observed, gap, filled by which method, low confidence, edited), like Motive's Tracks view or
QTM's trajectory info. Clicking a lane emits the frame, the marker and the stretch of equal state
under the click; hovering shows the marker, the frame and that stretch.

State codes ``(F,M)`` int8 follow the provenance codes of :mod:`core.model.provenance` (-1 missing,
0 measured, 1..6 filled by the built-in fill method of that code, :mod:`core.gaps.methods`) and add
:data:`LOW_CONFIDENCE` and :data:`EDITED` (measured samples the labelling is unsure about, and samples the
operator edited) and :data:`NO_DATA` (before a marker's first or after its last sample: nothing to show).
:func:`lane_states` builds them from provenance and masks; :func:`lanes_from_review` from
:meth:`core.session.ReviewTake.lane_states` and provenance.

Drawing is one image (a colour per lane and screen column). When more frames than pixels are
visible, each column shows the most important state of its frames (gap > low confidence > edited >
filled > observed), so a one-frame gap never disappears when the whole take is in view.
The x axis shows the file's frame numbers, like :class:`widgets.timeline.TimelineWidget`; signals
carry 0-based frames.
"""

from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg
from pyqtgraph.GraphicsScene.mouseEvents import MouseClickEvent
from PySide6.QtCore import QPointF, QRectF, Qt, QTimer, Signal
from PySide6.QtGui import QBrush, QColor, QCursor, QFont, QFontMetrics, QPen
from PySide6.QtWidgets import (
    QGraphicsRectItem,
    QHBoxLayout,
    QLabel,
    QScrollBar,
    QToolTip,
    QVBoxLayout,
    QWidget,
)

from handmocap.core.gaps import fill_method, fill_methods
from handmocap.core.model.provenance import MEASURED, MISSING
from handmocap.core.review import LANE_EDITED, LANE_FILLED, LANE_GAP, LANE_LOW_CONFIDENCE, LANE_NONE, LANE_OBSERVED
from handmocap.widgets.cached_drawing import paint_from_cache

NO_DATA = -2                  # before the first or after the last sample of the marker
GAP = MISSING                 # -1: no sample (not filled)
OBSERVED = MEASURED           # 0: measured, labelled
LOW_CONFIDENCE = 7            # measured, but the label is uncertain
EDITED = 8                    # changed by the operator
STATE_CODES = (NO_DATA, GAP, OBSERVED, *(method.code for method in fill_methods()), LOW_CONFIDENCE, EDITED)

BACKGROUND = (30, 32, 36)     # the timeline's plot background
CURSOR_PEN = (255, 200, 60)   # the timeline's cursor
SELECTION_COLOUR = (255, 200, 60)
OBSERVED_COLOUR = (92, 104, 120)
NO_DATA_COLOUR = (40, 43, 48)
GAP_COLOUR = (232, 66, 56)
LOW_CONFIDENCE_COLOUR = (250, 158, 36)
EDITED_COLOUR = (232, 232, 240)


def filled_text(method: str) -> str:
    """How the GUI names a fill in running text: "filled (rigid body)", "filled (PCA)" (the method's label, lower
    case unless it is an acronym)."""
    label = fill_method(method).label
    return f"filled ({label if label.isupper() else label.lower()})"


STATE_COLOURS: dict[int, tuple[int, int, int]] = {
    NO_DATA: NO_DATA_COLOUR, GAP: GAP_COLOUR, OBSERVED: OBSERVED_COLOUR,
    **{method.code: method.colour for method in fill_methods()},
    LOW_CONFIDENCE: LOW_CONFIDENCE_COLOUR, EDITED: EDITED_COLOUR,
}
STATE_NAMES: dict[int, str] = {
    NO_DATA: "no data", GAP: "gap", OBSERVED: "observed",
    **{method.code: filled_text(method.name) for method in fill_methods()},
    LOW_CONFIDENCE: "low confidence", EDITED: "edited",
}
MIN_LANE_PX = 14.0            # lanes never get thinner: more markers than fit scroll vertically
MAX_LANE_PX = 22.0            # nor thicker: few markers leave room below
SCROLL_LANES = 3              # lanes per wheel step (Shift+wheel, or the wheel over the names)


def state_ranks(states: np.ndarray) -> np.ndarray:
    """Importance rank ``(F,M)`` uint8 of each state code, for the screen columns that hold several
    frames (higher wins): no data 0 < observed 2 < fills 3..8 < edited 9 < low confidence 10 < gap 11.

    Byte arithmetic instead of a table look-up (five times faster on 100k × 60): ``code + 2`` as a
    byte gives no data 0, gap 1, observed 2, fills 3..8, low confidence 9, edited 10; then low
    confidence and edited swap (9 ^ 3 = 10) and the gap goes to the top."""
    ranks = np.asarray(states, dtype=np.int8).view(np.uint8) + np.uint8(2)
    ranks ^= ((ranks - np.uint8(9)) < 2).view(np.uint8) * np.uint8(3)
    ranks[ranks == 1] = 11
    return ranks


#: rank of each state code (see :func:`state_ranks`)
STATE_RANKS: dict[int, int] = {code: int(state_ranks(np.array([code]))[0]) for code in STATE_CODES}
_RGBA_OF_RANK = np.zeros((max(STATE_RANKS.values()) + 1, 4), dtype=np.uint8)
for _code, _rank in STATE_RANKS.items():
    _RGBA_OF_RANK[_rank] = (*STATE_COLOURS[_code], 255)
#: review lane code (``core.session.LANE_*``) -> lane state here; filled samples take their provenance
_FROM_REVIEW = {LANE_NONE: NO_DATA, LANE_OBSERVED: OBSERVED, LANE_GAP: GAP, LANE_LOW_CONFIDENCE: LOW_CONFIDENCE,
                LANE_EDITED: EDITED}


def lane_states(provenance: np.ndarray, low_confidence: np.ndarray | None = None,
                edited: np.ndarray | None = None, no_data_outside: bool = True) -> np.ndarray:
    """Lane state codes ``(F,M)`` int8 from the provenance ``(F,M)`` of :func:`core.gaps.fill_all` (-1
    missing, 0 measured, 1..6 filled), ``low_confidence (F,M)`` bool (marks measured samples only) and
    ``edited (F,M)`` bool (marks every sample that is not missing). With ``no_data_outside``, missing
    frames before a marker's first and after its last sample are :data:`NO_DATA`, not gaps (as
    :meth:`core.session.ReviewTake.lane_states` does)."""
    provenance = np.asarray(provenance)
    if provenance.ndim != 2:
        raise ValueError(f"provenance must be (frames, markers), got shape {provenance.shape}")
    states = provenance.astype(np.int8)
    if no_data_outside and states.size:
        present = provenance != GAP
        inside = np.maximum.accumulate(present, axis=0) & np.maximum.accumulate(present[::-1], axis=0)[::-1]
        states[~inside] = NO_DATA
    if low_confidence is not None:
        states[np.asarray(low_confidence, dtype=bool) & (provenance == OBSERVED)] = LOW_CONFIDENCE
    if edited is not None:
        states[np.asarray(edited, dtype=bool) & (provenance != GAP)] = EDITED
    return states


def lanes_from_review(lanes: np.ndarray, provenance: np.ndarray) -> np.ndarray:
    """Lane state codes ``(F,M)`` int8 from a review's lanes (``core.session.ReviewTake.lane_states()``,
    ``LANE_*`` codes) and its ``provenance (F,M)`` (which gives the method of each filled sample)."""
    lanes, provenance = np.asarray(lanes), np.asarray(provenance)
    if lanes.shape != provenance.shape or lanes.ndim != 2:
        raise ValueError(f"lanes {lanes.shape} and provenance {provenance.shape} must be the same (F, M) shape")
    table = np.zeros(max(_FROM_REVIEW.keys() | {LANE_FILLED}) + 1, dtype=np.int8)
    for code, state in _FROM_REVIEW.items():
        table[code] = state
    states = table[lanes]
    filled = lanes == LANE_FILLED
    states[filled] = provenance[filled]
    return states


def css(colour: tuple[int, ...]) -> str:
    """``#rrggbb`` of an RGB byte triple."""
    return "#{:02x}{:02x}{:02x}".format(*colour[:3])


def legend_html(states: tuple[int, ...] = STATE_CODES[1:]) -> str:
    """Rich-text legend: a coloured square and the name of each state."""
    return "&nbsp; ".join(f'<span style="color:{css(STATE_COLOURS[s])}">■</span>&nbsp;'
                               f'{STATE_NAMES[s].replace(" ", "&nbsp;")}'
                               for s in states)


def _column_max(ranks: np.ndarray, per_column: int) -> np.ndarray:
    """Maximum over consecutive blocks of ``per_column`` rows of ``ranks (n,M)``, ``(ceil(n/k),M)``."""
    whole = len(ranks) // per_column
    blocks = ranks[:whole * per_column].reshape(whole, per_column, ranks.shape[1]).max(axis=1)
    if whole * per_column == len(ranks):
        return blocks
    return np.concatenate([blocks, ranks[whole * per_column:].max(axis=0, keepdims=True)])


class _LaneViewBox(pg.ViewBox):
    """Wheel zooms time; Shift+wheel (or the wheel over the marker names) scrolls the lanes."""

    def __init__(self, lanes: MarkerLanes) -> None:
        super().__init__(enableMenu=False)
        self._lanes = lanes

    def wheelEvent(self, ev, axis=None) -> None:  # noqa: ANN001 - pyqtgraph signature
        if axis == 1 or ev.modifiers() & Qt.KeyboardModifier.ShiftModifier:
            self._lanes.scroll_lanes(-SCROLL_LANES if ev.delta() > 0 else SCROLL_LANES)
            ev.accept()
            return
        super().wheelEvent(ev, axis=0)


class MarkerLanes(QWidget):
    """A lane per marker over the frames of one take; see the module docstring.

    Signals carry 0-based frames and marker columns: :attr:`frame_clicked`, :attr:`marker_clicked`,
    :attr:`stretch_clicked` ``(marker, first, last)`` (inclusive) and :attr:`x_range_changed` (file
    frame numbers, when the operator pans or zooms; :meth:`set_x_range` does not emit it).
    """

    frame_clicked = Signal(int)
    marker_clicked = Signal(int)
    stretch_clicked = Signal(int, int, int)
    x_range_changed = Signal(float, float)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._names: list[str] = []
        self._states = np.zeros((0, 0), dtype=np.int8)
        self._ranks = np.zeros((0, 0), dtype=np.uint8)
        self._first_frame = 1
        self._frame_rate = 100.0
        self._frame = 0
        self._selected = -1
        self._first_lane = 0.0
        self._span = 1.0
        self._scrollable = False
        self._image_key: tuple[int, int, int] | None = None
        self._frames_per_column = 1
        self._setting_range = False
        self._build()
        self.set_lanes([], np.zeros((0, 0), dtype=np.int8))

    # ------------------------------------------------------------------------------------ building
    def _build(self) -> None:
        self.legend_label = QLabel(legend_html(), self)
        self.legend_label.setContentsMargins(6, 2, 6, 2)
        self.legend_label.setToolTip("Colours of the lanes. Zoomed out, a screen column shows the most important\n"
                                     "state of its frames: gap > low confidence > edited > filled > observed.")
        self.summary_label = QLabel(self)
        self.summary_label.setContentsMargins(6, 2, 6, 2)
        self.summary_label.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)

        self.view_box = _LaneViewBox(self)
        self.name_axis = pg.AxisItem("left")
        self.plot = pg.PlotWidget(self, viewBox=self.view_box, axisItems={"left": self.name_axis})
        self.plot.setBackground(BACKGROUND)
        self.plot.setMouseEnabled(x=True, y=False)
        self.plot.setMenuEnabled(False)
        self.plot.hideButtons()
        self.plot.setMinimumHeight(120)
        item = self.plot.getPlotItem()
        item.showGrid(x=True, y=False, alpha=0.18)
        self.view_box.invertY(True)
        self.view_box.setDefaultPadding(0.0)
        font = QFont(self.font())
        font.setPointSizeF(max(7.0, font.pointSizeF() - 1.0))
        self.name_axis.setStyle(tickFont=font, tickLength=0, autoExpandTextSpace=False, hideOverlappingLabels=True)
        self.name_axis.setTextPen(pg.mkPen((205, 210, 218)))
        self._name_font = font

        self._image = pg.ImageItem(axisOrder="col-major", autoDownsample=False)
        self.plot.addItem(self._image)
        self._separators = pg.PlotCurveItem(pen=pg.mkPen(BACKGROUND, width=2), connect="pairs")
        self.plot.addItem(self._separators)
        paint_from_cache(self._image, self._separators)
        self._selection = QGraphicsRectItem()
        selection_pen = QPen(QColor(*SELECTION_COLOUR))
        selection_pen.setCosmetic(True)
        selection_pen.setWidthF(2.0)
        self._selection.setPen(selection_pen)
        self._selection.setBrush(QBrush(Qt.BrushStyle.NoBrush))    # a tint would change the states' colours
        self._selection.setZValue(5)
        self._selection.hide()
        self.plot.addItem(self._selection)
        self._cursor = pg.InfiniteLine(angle=90, movable=False, pen=pg.mkPen(CURSOR_PEN, width=2))
        self._cursor.setZValue(10)
        self.plot.addItem(self._cursor)

        self._refresh_timer = QTimer(self)
        self._refresh_timer.setSingleShot(True)
        self._refresh_timer.setInterval(0)
        self._refresh_timer.timeout.connect(self._refresh_image)
        self.view_box.sigXRangeChanged.connect(self._x_range_changed)
        self.view_box.sigResized.connect(self._layout_lanes)
        self.plot.scene().sigMouseClicked.connect(self._clicked)
        self.plot.scene().sigMouseMoved.connect(self._hovered)

        self.scroll_bar = QScrollBar(Qt.Orientation.Vertical, self)
        self.scroll_bar.valueChanged.connect(self._scrolled)
        self.scroll_bar.hide()

        self.header = QWidget(self)
        self.header.setObjectName("lanes-header")
        self.header.setStyleSheet(f"#lanes-header {{ background: {css(BACKGROUND)}; }} "
                                  "#lanes-header QLabel { color: #cdd2da; }")
        self.legend_label.setWordWrap(True)
        header = QHBoxLayout(self.header)
        header.setContentsMargins(0, 0, 0, 0)
        # the summary gives way (cut) when the dock is narrow; the legend wraps
        self.summary_label.setMinimumWidth(1)
        header.addWidget(self.legend_label, 1)
        header.addWidget(self.summary_label)
        body = QHBoxLayout()
        body.setContentsMargins(0, 0, 0, 0)
        body.setSpacing(0)
        body.addWidget(self.plot, 1)
        body.addWidget(self.scroll_bar)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(0)
        layout.addWidget(self.header)
        layout.addLayout(body, 1)

    # ------------------------------------------------------------------------------------- public
    @property
    def n_frames(self) -> int:
        """Frames of the shown take."""
        return self._states.shape[0]

    @property
    def n_markers(self) -> int:
        """Lanes shown."""
        return len(self._names)

    @property
    def first_frame(self) -> int:
        """The file's number of frame 0."""
        return self._first_frame

    @property
    def frame(self) -> int:
        """0-based frame of the cursor."""
        return self._frame

    def states(self) -> np.ndarray:
        """The state codes ``(F,M)`` int8 shown (read-only view)."""
        view = self._states.view()
        view.flags.writeable = False
        return view

    def set_lanes(self, names: list[str], states: np.ndarray, first_frame: int = 1,
                  frame_rate: float = 100.0) -> None:
        """Show a take: marker ``names (M,)``, state codes ``states (F,M)`` (see :func:`lane_states`), the
        file's number of frame 0 and the frame rate (Hz, for the tooltip's times). Shows the whole take,
        keeps no selection, puts the cursor on frame 0."""
        states = self._checked(states, len(names))
        self._names = list(names)
        self._first_frame, self._frame_rate = int(first_frame), float(frame_rate)
        self._selected = -1
        self._first_lane = 0.0
        self._assign_states(states)
        width = max(self.n_frames, 1)
        self._setting_range = True
        try:
            self.view_box.setLimits(xMin=self._first_frame - 0.5 - 0.02 * width,
                                    xMax=self._first_frame - 0.5 + 1.02 * width,
                                    minXRange=min(10.0, width), maxXRange=1.04 * width + 1)
            self.view_box.setXRange(self._first_frame - 0.5, self._first_frame - 0.5 + width, padding=0)
        finally:
            self._setting_range = False
        longest = max((QFontMetrics(self._name_font).horizontalAdvance("▸ " + n) for n in self._names), default=40)
        self.name_axis.setWidth(min(max(longest + 12, 48), 220))
        self.name_axis.setTicks([[(i + 0.5, name) for i, name in enumerate(self._names)], []])
        self._frame = 0
        self._cursor.setValue(self._first_frame)
        self._selection.hide()
        self._layout_lanes()

    def set_states(self, states: np.ndarray) -> None:
        """New state codes ``(F,M)`` for the same markers and frames (after a fill, an edit, a relabel)."""
        states = self._checked(states, len(self._names))
        if states.shape[0] != self.n_frames:
            raise ValueError(f"states have {states.shape[0]} frames, the lanes {self.n_frames}")
        self._assign_states(states)

    def set_frame(self, frame: int) -> None:
        """Put the cursor on 0-based ``frame``; no signal."""
        self._frame = int(frame)
        self._cursor.setValue(self._first_frame + self._frame)

    def set_selected_marker(self, marker: int) -> None:
        """Highlight lane ``marker`` (-1: none) and scroll it into view; no signal."""
        self._selected = marker if 0 <= marker < self.n_markers else -1
        self.name_axis.setTicks([[(i + 0.5, ("▸ " if i == self._selected else "") + name)
                                  for i, name in enumerate(self._names)], []])
        if self._selected < 0:
            self._selection.hide()
            return
        self._selection.setRect(QRectF(self._first_frame - 0.5, self._selected, max(self.n_frames, 1), 1.0))
        self._selection.show()
        if not self._first_lane <= self._selected <= self._first_lane + self._span - 1:
            self.scroll_to_lane(self._selected - max(0.0, math.floor(self._span / 2)))

    def selected_marker(self) -> int:
        """The highlighted lane, -1 when none."""
        return self._selected

    def x_range(self) -> tuple[float, float]:
        """Shown frame range (file numbers)."""
        low, high = self.view_box.viewRange()[0]
        return float(low), float(high)

    def set_x_range(self, first: float, last: float) -> None:
        """Show frames ``first .. last`` (file numbers, as the timeline's plot); no :attr:`x_range_changed`."""
        self._setting_range = True
        try:
            self.view_box.setXRange(first, last, padding=0)
        finally:
            self._setting_range = False
        self._refresh_image()

    def show_frames(self, first: int, last: int, margin: float = 0.5) -> None:
        """Zoom to 0-based frames ``first .. last`` with ``margin`` times their length on each side (at
        least 10 frames); emits :attr:`x_range_changed` so linked views follow."""
        pad = max(10.0, margin * (last - first + 1))
        low = self._first_frame + first - 0.5 - pad
        high = self._first_frame + last + 0.5 + pad
        self.view_box.setXRange(low, high, padding=0)

    def link_x(self, view_box: pg.ViewBox) -> None:
        """Keep the shown frame range equal to another pyqtgraph view box's (e.g. the timeline's plot, in
        file frame numbers) both ways: panning or zooming either moves the other. Unlike pyqtgraph's
        ``setXLink`` the ranges are equal even when the views have different widths or axes."""
        view_box.sigXRangeChanged.connect(lambda _box, x_range: self.set_x_range(*x_range))
        self.x_range_changed.connect(lambda low, high: view_box.setXRange(low, high, padding=0))
        self.set_x_range(*view_box.viewRange()[0])

    def visible_lanes(self) -> tuple[int, int]:
        """First and last (inclusive) lane at least partly in view."""
        last = min(self.n_markers, math.ceil(self._first_lane + self._span)) - 1
        return int(self._first_lane), int(last)

    def scroll_lanes(self, lanes: int) -> None:
        """Scroll the lanes by ``lanes`` (positive: down)."""
        self.scroll_to_lane(self._first_lane + lanes)

    def scroll_to_lane(self, lane: float) -> None:
        """Make ``lane`` the top lane in view (clamped)."""
        top = float(np.clip(lane, 0.0, max(0.0, self.n_markers - self._span)))
        if self._scrollable or top == 0.0:
            self._first_lane = top
            self.scroll_bar.blockSignals(True)
            self.scroll_bar.setValue(int(round(top)))
            self.scroll_bar.blockSignals(False)
            self._apply_y_range()

    def stretch_at(self, marker: int, frame: int) -> tuple[int, int, int]:
        """``(state, first, last)``: the run of equal state of ``marker`` holding 0-based ``frame``."""
        column = self._states[:, marker]
        state = column[frame]
        before = np.flatnonzero(column[:frame] != state)
        after = np.flatnonzero(column[frame:] != state)
        first = int(before[-1]) + 1 if before.size else 0
        last = frame + int(after[0]) - 1 if after.size else self.n_frames - 1
        return int(state), first, last

    def describe(self, marker: int, frame: int, stretch_frame: int | None = None) -> str:
        """Tooltip text of ``marker`` at 0-based ``frame``: name, frame (file number), time, and the
        stretch of equal state holding ``stretch_frame`` (default ``frame``), in file numbers."""
        state, first, last = self.stretch_at(marker, frame if stretch_frame is None else stretch_frame)
        length = last - first + 1
        frames = (f"frame {self._first_frame + first}" if length == 1
                  else f"frames {self._first_frame + first}–{self._first_frame + last}")
        return (f"<b>{self._names[marker]}</b> · frame {self._first_frame + frame} "
                f"({frame / self._frame_rate:.2f} s)<br>"
                f'<span style="color:{css(STATE_COLOURS[state])}">■</span> {STATE_NAMES[state]}: '
                f"{frames} ({length} frame{'s' if length != 1 else ''})")

    def hit(self, view_x: float, view_y: float) -> tuple[int, int, int] | None:
        """What a click at view coordinates (file frame number, lane) picks: ``(marker, frame, snapped)``
        0-based, ``snapped`` being the frame of the most important state within the screen column
        under the point (the nearest such frame); None outside the lanes."""
        marker = math.floor(view_y)
        if not 0 <= marker < self.n_markers or self.n_frames == 0:
            return None
        frame = int(round(view_x)) - self._first_frame
        if not -0.5 <= view_x - self._first_frame + 0.5 <= self.n_frames:
            return None
        frame = int(np.clip(frame, 0, self.n_frames - 1))
        reach = self._frames_per_column // 2
        low, high = max(0, frame - reach), min(self.n_frames, frame + reach + 1)
        ranks = self._ranks[low:high, marker]
        best = np.flatnonzero(ranks == ranks.max()) + low
        return marker, frame, int(best[np.argmin(np.abs(best - frame))])

    # ------------------------------------------------------------------------------------ private
    @staticmethod
    def _checked(states: np.ndarray, n_markers: int) -> np.ndarray:
        states = np.asarray(states)
        if states.size == 0:
            return np.zeros((states.shape[0] if states.ndim == 2 else 0, n_markers), dtype=np.int8)
        if states.ndim != 2 or states.shape[1] != n_markers:
            raise ValueError(f"states must be (frames, {n_markers}), got shape {states.shape}")
        low, high = int(states.min()), int(states.max())
        if low < min(STATE_CODES) or high > max(STATE_CODES):
            raise ValueError(f"unknown lane state code {low if low < min(STATE_CODES) else high}")
        return np.ascontiguousarray(states, dtype=np.int8)

    def _assign_states(self, states: np.ndarray) -> None:
        self._states = states
        self._ranks = state_ranks(states)
        self._image_key = None
        if self.n_markers and self.n_frames:
            sep = np.arange(1, self.n_markers, dtype=float)
            x = np.empty(2 * len(sep))
            x[0::2], x[1::2] = self._first_frame - 0.5, self._first_frame - 0.5 + self.n_frames
            self._separators.setData(x, np.repeat(sep, 2))
            missing = states == GAP
            gaps = int(np.count_nonzero(missing[0])) + int(np.count_nonzero(missing[1:] > missing[:-1]))
            measured = np.count_nonzero(states == OBSERVED) + np.count_nonzero(states >= LOW_CONFIDENCE)
            observed = 100.0 * measured / states.size
            self.summary_label.setText(f"{self.n_markers} markers · {self.n_frames} frames · "
                                       f"{observed:.1f} % observed · {gaps} unfilled gaps")
            self.summary_label.setToolTip(self.summary_label.text())
        else:
            self._separators.setData([], [])
            self.summary_label.setText("no take")
        self._refresh_image()

    def _layout_lanes(self) -> None:
        height = max(self.view_box.height(), 1.0)
        if self.n_markers * MIN_LANE_PX <= height:
            self._span = max(float(self.n_markers), height / MAX_LANE_PX, 1.0)
            self._first_lane = 0.0
            self._scrollable = False
            self.scroll_bar.hide()
        else:
            self._scrollable = True
            self._span = height / MIN_LANE_PX
            whole = max(1, int(self._span))
            self.scroll_bar.blockSignals(True)
            self.scroll_bar.setRange(0, max(0, self.n_markers - whole))
            self.scroll_bar.setPageStep(whole)
            self.scroll_bar.blockSignals(False)
            self.scroll_bar.show()
            self._first_lane = float(np.clip(self._first_lane, 0.0, self.n_markers - self._span))
            self.scroll_bar.blockSignals(True)
            self.scroll_bar.setValue(int(round(self._first_lane)))
            self.scroll_bar.blockSignals(False)
        self._apply_y_range()
        self._refresh_image()

    def _apply_y_range(self) -> None:
        self.view_box.setYRange(self._first_lane, self._first_lane + self._span, padding=0)

    def _scrolled(self, value: int) -> None:
        self._first_lane = float(min(value, max(0.0, self.n_markers - self._span)))
        self._apply_y_range()

    def _x_range_changed(self) -> None:
        # redrawn once the range settles (and never from inside the view box's own signal)
        self._refresh_timer.start()
        if not self._setting_range:
            self.x_range_changed.emit(*self.x_range())

    def _refresh_image(self) -> None:
        """Draw the visible frames: full resolution when they fit the width, else ``k`` frames per
        column reduced to their most important state."""
        n_frames, n_markers = self._states.shape
        if n_frames == 0 or n_markers == 0:
            self._image.clear()
            self._image_key = None
            return
        low, high = self.x_range()
        start = int(np.clip(math.floor(low - self._first_frame + 0.5), 0, n_frames - 1))
        stop = int(np.clip(math.ceil(high - self._first_frame + 0.5), start + 1, n_frames))
        columns = max(int(self.view_box.width()), 16)
        per_column = max(1, math.ceil((stop - start) / columns))
        key = (start, stop, per_column)
        if key == self._image_key:
            return
        self._image_key = key
        self._frames_per_column = per_column
        ranks = self._ranks[start:stop]
        if per_column > 1:
            ranks = _column_max(ranks, per_column)
        self._image.setImage(_RGBA_OF_RANK[ranks], autoLevels=False, levels=(0, 255))
        self._image.setRect(QRectF(self._first_frame - 0.5 + start, 0.0, len(ranks) * per_column, n_markers))

    def _view_point(self, scene_pos: QPointF) -> QPointF | None:
        if not self.view_box.sceneBoundingRect().contains(scene_pos):
            return None
        return self.view_box.mapSceneToView(scene_pos)

    def _clicked(self, event: MouseClickEvent) -> None:
        if event.button() != Qt.MouseButton.LeftButton:
            return
        point = self._view_point(event.scenePos())
        picked = None if point is None else self.hit(point.x(), point.y())
        if picked is None:
            return
        marker, frame, snapped = picked
        _state, first, last = self.stretch_at(marker, snapped)
        self.set_selected_marker(marker)
        self.set_frame(frame)
        self.marker_clicked.emit(marker)
        self.frame_clicked.emit(frame)
        self.stretch_clicked.emit(marker, first, last)

    def _hovered(self, scene_pos: QPointF) -> None:
        point = self._view_point(scene_pos)
        picked = None if point is None else self.hit(point.x(), point.y())
        text = "" if picked is None else self.describe(*picked)
        self.plot.setToolTip(text)
        if QToolTip.isVisible():
            QToolTip.showText(QCursor.pos(), text, self.plot)
