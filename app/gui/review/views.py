"""The review's whole-take views (label table, marker lanes, gap panel) and how they follow the
application's events: another take shown, a change of its review, another selection, jobs."""

from __future__ import annotations

from typing import cast

import numpy as np
from PySide6.QtCore import QObject, Qt, QTimer
from PySide6.QtWidgets import QScrollArea, QSplitter

from handmocap.app.gui.application import CurrentDocumentChanged, DocumentClosing, JobsChanged, SelectionChanged
from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.colours import label_colours
from handmocap.app.gui.review.part import ReviewPart
from handmocap.core.review.events import Change, ReviewChanged
from handmocap.widgets.fill_preview import FillPreview
from handmocap.widgets.gap_list import GapList
from handmocap.widgets.marker_lanes import MarkerLanes, lanes_from_review
from handmocap.widgets.review_table import ReviewTable


class ReviewViews(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: builds the views and keeps them up to date."""

    def _build_views(self) -> None:
        owner = cast(QObject, self)          # the controller: a QObject
        self._views_timer = QTimer(owner)    # the whole-take views after a change, once the change is drawn
        self._views_timer.setSingleShot(True)
        self._views_timer.setInterval(0)
        self._views_timer.timeout.connect(self._refresh_views)
        host = self.host
        self.table = ReviewTable(host)
        self.table.marker_selected.connect(self.select_label)
        self.lanes = MarkerLanes(host)
        self.lanes.frame_clicked.connect(self.app.set_frame)
        self.lanes.marker_clicked.connect(self.select_label)
        self.lanes.stretch_clicked.connect(self._stretch_clicked)
        self.lanes.link_x(self.timeline.plot.getPlotItem().vb)
        self.gap_list = GapList(host)
        self.preview = FillPreview(host)
        gaps = QScrollArea(host)             # the gap table, check and fill-all need more height than a small
        gaps.setWidgetResizable(True)        # screen has: they scroll, the preview beside them stays in view
        gaps.setFrameShape(QScrollArea.Shape.NoFrame)
        gaps.setWidget(self.gap_list)
        self.gaps_panel = QSplitter(Qt.Orientation.Horizontal, host)
        self.gaps_panel.addWidget(gaps)
        self.gaps_panel.addWidget(self.preview)
        self.gaps_panel.setStretchFactor(0, 3)    # the list's columns and buttons first; the preview the rest
        self.gaps_panel.setStretchFactor(1, 1)
        self.gaps_panel.setSizes([450, 200])
        self.gaps_panel.setChildrenCollapsible(False)
        self.gap_list.gap_selected.connect(self._gap_selected)
        self.gap_list.method_changed.connect(lambda _gap, method: self.preview.set_selected(method))
        self.gap_list.preview_requested.connect(self._preview_requested)
        self.gap_list.accept_requested.connect(self.accept_fill)
        self.gap_list.reject_requested.connect(self.reject_gap)
        self.gap_list.fill_all_requested.connect(self.fill_all)

    def _app_changed(self, event: object) -> None:
        """Follow the application: another take shown, a take closing, a change of the shown take's review,
        another selection."""
        if isinstance(event, CurrentDocumentChanged):
            self._show_document(event.document)
        elif isinstance(event, DocumentClosing) and event.document is self.document:
            self.stop()
        elif isinstance(event, ReviewChanged) and event.operation != "clean":
            if event.operation != "attach":       # a re-solve attached to an edit leaves the gaps as they are
                self._previews = {}
            if event.what & Change.TIMELINE:
                self._show_timeline_marks()
            if event.what & ~Change.TIMELINE:
                self._refresh(structure=event.structure)
            else:
                self.update_enabled()
        elif isinstance(event, SelectionChanged):
            self._show_selection()
        elif isinstance(event, JobsChanged):
            self.update_enabled()

    def _show_document(self, document: TakeDocument | None) -> None:
        """Show the review of ``document`` (None: no take is shown any more, the views are cleared)."""
        self._rejected = set()
        self._previews = {}
        self._unsolved, self._carried = {}, {}
        if document is not None:
            self._refresh(structure=True)
            self._show_timeline_marks()
            if document.review is not None and document.review.health:
                self.status_message.emit(document.review.health_summary(), 0)
            return
        self.stop()
        self.lanes.set_lanes([], np.zeros((0, 0), dtype=np.int8))
        self.gap_list.set_gaps([], [], 1)
        self.preview.clear()
        self.viewport.set_trails([])
        self.viewport.set_loose_points(None)
        self.viewport.set_rigid_bodies(None)
        self.update_enabled()

    def _refresh(self, structure: bool = False) -> None:
        """Redraw the review views; ``structure``: labels or hands may have changed (then at once). Otherwise
        the views of the whole take (lanes, label table, gap list, problem count) follow once the window has
        drawn the change (an undo on a 20 000-frame take shows in the 3D view at once; the whole-take views
        take a few hundred ms more): changes in between are drawn once. :meth:`flush_views` brings them up
        to date now."""
        review = self.review
        if review is None:
            return
        if structure or self.lanes.n_markers != review.n_labels or self.lanes.n_frames != review.n_frames:
            self._views_timer.stop()
            self._refresh_views(structure=True)
            return
        document = self.document
        if document is not None and document.has_solved_hands() and self.viewport.hand_count() != len(review.hands):
            self._set_hand_meshes()     # the first solve of a hand: the view showed another surface
        self.update_enabled()
        self._views_timer.start()

    def flush_views(self) -> None:
        """Bring the whole-take views up to date now if a change is waiting to be shown in them."""
        if self._views_timer.isActive():
            self._views_timer.stop()
            self._refresh_views()

    def _refresh_views(self, structure: bool = False) -> None:
        """The whole-take views of the review: lanes, label table, gap list and problem count."""
        review = self.review
        if review is None:
            return
        take = review.take
        colours = label_colours(review.n_labels)
        stats = review.marker_stats()
        states = lanes_from_review(review.lane_states(), review.provenance)
        if structure:
            self.lanes.set_lanes(review.label_names, states, take.first_frame, take.frame_rate)
            self.table.set_markers(stats, colours)
            self._set_hand_meshes()
        else:
            x_range = self.lanes.x_range()
            self.lanes.set_states(states)
            self.lanes.set_x_range(*x_range)
            self.table.update_stats(stats)
        self.lanes.set_frame(self.app.frame)
        if self.selection.label >= 0:
            self.lanes.set_selected_marker(self.selection.label)
        self._refresh_gaps()
        self._refresh_problem_count()
        self.update_enabled()

    def update_enabled(self) -> None:
        document, review, busy = self.document, self.review, self.jobs.is_busy()
        stack = None if document is None else document.stack
        selection = self.selection
        self.auto_label_action.setEnabled(review is not None and not busy)
        self.rigid_body_action.setEnabled(review is not None and len(selection.rigid_points) >= 3)
        self.cancel_job_action.setEnabled(busy)
        # never disabled by a job: undo cancels the review job running on the take and undoes at once
        self.undo_action.setEnabled(stack is not None and stack.can_undo())
        self.redo_action.setEnabled(stack is not None and stack.can_redo())
        self.undo_action.setText(f"&Undo {stack.undo_text()}" if stack is not None and stack.can_undo() else "&Undo")
        self.redo_action.setText(f"&Redo {stack.redo_text()}" if stack is not None and stack.can_redo() else "&Redo")
        editable = (document is not None and document.has_labels()
                    and not (busy and self._job_kind == "auto-label"))
        for action in (self.assign_action, self.swap_action, self.ghost_action, self.unlabel_action,
                       self.next_problem_action, self.previous_problem_action, self.fill_all_action,
                       self.export_c3d_action):
            action.setEnabled(editable)
        for action in (self.export_csv_action, self.export_bvh_action):
            action.setEnabled(document is not None and document.has_solved_hands())
        for action in (self.add_event_action, self.remove_event_action, self.next_event_action,
                       self.previous_event_action):
            action.setEnabled(review is not None)
        self.trim_action.setEnabled(review is not None and selection.range_in is not None
                                    and selection.range_out is not None)
        self.untrim_action.setEnabled(review is not None and review.trim is not None)
        text = ""
        if selection.range_in is not None or selection.range_out is not None:
            first = review.take.first_frame if review is not None else 0
            start = "…" if selection.range_in is None else str(selection.range_in + first)
            stop = "…" if selection.range_out is None else str(selection.range_out + first)
            text = f" range {start}–{stop} "
        self.range_label.setText(text)

    def _show_selection(self) -> None:
        """Show the selection everywhere: table row, lane, the selected point, its trail, the points picked
        for a rigid body, the marked range."""
        if self.review is None:
            return
        label, column = self.selection.label, self.selection.column
        self.table.select_marker(label)
        self.lanes.set_selected_marker(label)
        self.viewport.set_selected_marker(column if column >= 0 else None)
        self.update_enabled()
        self.draw_frame(self.app.frame)
        self.viewport.request_render()
