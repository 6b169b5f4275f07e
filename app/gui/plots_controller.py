"""The trajectory plots (:class:`widgets.trajectory_plots.TrajectoryPlots`) following the application: the
selected label and the pinned ones of the shown take, its current frame and marked range, and every
edit of its review.

The plots show the pinned labels (the Pin button keeps the selected one) and the selected label, each in
its label colour. A click in the plots makes that frame current, a drag marks the I/O range, as the I and
O keys do. Traces are computed once per label and review version; while the plots are hidden nothing is
computed, they catch up when shown.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QObject
from PySide6.QtWidgets import QWidget

from handmocap.app.gui.application import (
    Application,
    CurrentDocumentChanged,
    DocumentClosed,
    FrameChanged,
    SelectionChanged,
)
from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.colours import label_colours
from handmocap.core.review.events import Change, ReviewChanged
from handmocap.widgets.trajectory_plots import Trace, TrajectoryPlots, make_trace

REDRAWN_BY = Change.LABELS | Change.FILLS | Change.STRUCTURE   # a solve alone moves no marker


class PlotsController(QObject):
    """Feeds :attr:`plots` from the application (module docstring)."""

    def __init__(self, app: Application, host: QWidget) -> None:
        super().__init__(host)
        self.app = app
        self.plots = TrajectoryPlots(host)
        self.plots.frame_clicked.connect(app.set_frame)
        self.plots.range_selected.connect(app.mark_range)
        self.plots.pin_clicked.connect(self.toggle_pin)
        self.plots.clear_pins_clicked.connect(self.clear_pins)
        self.plots.shown.connect(self._catch_up)
        self._pins: dict[TakeDocument, list[int]] = {}
        self._traces: dict[int, tuple[int, Trace]] = {}     # label -> (review version, its trace)
        self._stale = False
        app.add_listener(self._follow)

    @property
    def labels(self) -> list[int]:
        """The labels plotted: the pinned ones, then the selected one."""
        document = self.app.document
        if document is None or document.review is None:
            return []
        labels = [label for label in self._pins.get(document, []) if label < document.review.n_labels]
        selected = self.app.selection.label
        return labels + ([selected] if 0 <= selected < document.review.n_labels and selected not in labels else [])

    def toggle_pin(self) -> None:
        """Pin the selected label (it stays plotted when another is selected), or unpin it."""
        document, label = self.app.document, self.app.selection.label
        if document is None or label < 0:
            return
        pins = self._pins.setdefault(document, [])
        if label in pins:
            pins.remove(label)
        else:
            pins.append(label)
        self.refresh()

    def clear_pins(self) -> None:
        if self.app.document is not None:
            self._pins.pop(self.app.document, None)
        self.refresh()

    def _follow(self, event: object) -> None:
        if isinstance(event, FrameChanged):
            self.plots.set_frame(event.frame)
        elif isinstance(event, SelectionChanged):
            selection = self.app.selection
            self.plots.set_range(selection.range_in, selection.range_out)
            if [trace.name for trace in self.plots.traces] != self._names():
                self.refresh()
        elif isinstance(event, ReviewChanged) and event.operation != "clean" and event.what & REDRAWN_BY:
            self.refresh()
        elif isinstance(event, CurrentDocumentChanged):
            self._traces = {}
            document = event.document
            if document is None:
                self.plots.set_take(0, 1, 100.0)
            else:
                take = document.take
                self.plots.set_take(take.n_frames, take.first_frame, take.frame_rate)
                self.plots.set_frame(self.app.frame)
            self.refresh()
        elif isinstance(event, DocumentClosed):
            self._pins.pop(event.document, None)

    def _names(self) -> list[str]:
        review = self.app.document.review if self.app.document is not None else None
        return [review.label_names[label] for label in self.labels] if review is not None else []

    def refresh(self) -> None:
        """Plot the labels' traces now (later, when the plots are hidden); nothing is redrawn when they are
        the same as drawn (an edit of other labels)."""
        if not self.plots.isVisible():
            self._stale = True
            return
        self._stale = False
        traces = [self._trace(label) for label in self.labels]
        drawn = self.plots.traces
        if len(traces) != len(drawn) or any(new is not old for new, old in zip(traces, drawn, strict=True)):
            self.plots.set_traces(traces)

    def _catch_up(self) -> None:
        if self._stale:
            self.refresh()

    def _trace(self, label: int) -> Trace:
        """The trace of ``label`` in the shown review, computed again only when the review changed and
        with it the label's samples or swap suspects."""
        document = self.app.document
        review = None if document is None else document.review
        assert review is not None, "no review shown"     # self.labels are labels of the shown review
        cached = self._traces.get(label)
        if cached is not None and cached[0] == review.version:
            return cached[1]
        swaps = [(problem.start, problem.stop) for problem in review.problems(("swap",))
                 if label in (problem.label, problem.other)]
        red, green, blue = (int(round(255 * channel)) for channel in label_colours(review.n_labels)[label])
        colour = (red, green, blue)
        trace = make_trace(review.label_names[label], colour, review.labelled_positions()[:, label],
                           review.provenance[:, label], review.unfilled_gaps()[:, label], swaps,
                           review.take.frame_rate)
        if cached is not None and _same(cached[1], trace):
            trace = cached[1]
        self._traces[label] = (review.version, trace)
        return trace


def _same(old: Trace, new: Trace) -> bool:
    """Whether two traces of one label draw the same."""
    return (old.name == new.name and old.gaps == new.gaps and old.fills == new.fills and old.swaps == new.swaps
            and np.array_equal(old.positions, new.positions, equal_nan=True))
