"""The review's actions, its Edit, Review and Export menus and its toolbar."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QComboBox, QLabel, QMenu, QToolBar

from handmocap.app.gui.actions import make_action
from handmocap.app.gui.review.part import ReviewPart

SCOPE_TITLES = {"fragment": "to end of fragment", "range": "in the marked range", "take": "whole take"}



class ReviewActions(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: builds its actions and menus."""

    def _build_actions(self) -> None:
        host = self.host

        def action(text: str, slot: Callable, shortcut: str | None = None, tooltip: str | None = None):
            return make_action(host, text, slot, shortcut, tooltip=tooltip)

        self.auto_label_action = action("&Auto-label…", self.choose_auto_label, "auto_label")
        self.undo_action = action("&Undo", self.undo, "undo")
        self.redo_action = action("&Redo", self.redo, "redo")
        self.undo_action.setIconText("Undo")     # the toolbar stays short; the menu and tooltip say what
        self.redo_action.setIconText("Redo")
        self.assign_action = action("&Assign label…", self.choose_label_to_assign, "assign")
        self.swap_action = action("S&wap labels…", self.choose_label_to_swap, "swap")
        self.ghost_action = action("Mark as &ghost", self.mark_ghost, "ghost")
        self.unlabel_action = action("&Unlabel", self.unlabel, "unlabel")
        self.range_in_action = action("Set range &start here", self.set_range_in, "range_in")
        self.range_out_action = action("Set range &end here", self.set_range_out, "range_out")
        self.clear_range_action = action("&Clear range", self.clear_range, "clear_range")
        self.next_problem_action = action("&Next problem", lambda: self.go_to_problem(True), "next_problem")
        self.previous_problem_action = action("&Previous problem", lambda: self.go_to_problem(False),
                                              "previous_problem")
        self.rigid_body_action = action("Define &rigid body from selected points…", self.choose_rigid_body_name,
                                        "rigid_body", "Ctrl+click three or more points of an object in the 3D "
                                        "view, then name it: auto-label then tracks it as a rigid body")
        self.fill_all_action = action("&Fill short gaps…", lambda: self.fill_all(self.gap_list.max_length_box.value()),
                                      "fill_short_gaps")
        self.add_event_action = action("Add &event here…", self.choose_event_to_add, "add_event")
        self.remove_event_action = action("Remo&ve event here", self.remove_event_here,
                                          tooltip="Remove the event at the current frame")
        self.next_event_action = action("Next e&vent", lambda: self.go_to_event(True), "next_event")
        self.previous_event_action = action("Previous ev&ent", lambda: self.go_to_event(False), "previous_event")
        self.trim_action = action("&Trim to the marked range", self.trim_to_range, "trim",
                                  "Trim the take to the range marked with I and O: the frames outside are no longer "
                                  "shown, played or exported (undo brings them back)")
        self.untrim_action = action("&Keep the whole take", self.keep_whole_take,
                                    tooltip="Undo the trim: show, play and export every frame again")
        self.cancel_job_action = action("Cancel review &job", self.jobs.cancel)
        self.export_c3d_action = action("Labelled &C3D…", self.choose_export_c3d)
        self.export_csv_action = action("Joint angles (CS&V)…", self.choose_export_csv)
        self.export_bvh_action = action("Joint angles (&BVH)…", self.choose_export_bvh)

        self.edit_menu = QMenu("&Edit", host)
        for item in (self.undo_action, self.redo_action, None, self.assign_action, self.swap_action,
                     self.unlabel_action, self.ghost_action, None, self.range_in_action, self.range_out_action,
                     self.clear_range_action, None, self.trim_action, self.untrim_action):
            self.edit_menu.addSeparator() if item is None else self.edit_menu.addAction(item)
        self.events_menu = QMenu("&Go to event", host)
        self.review_menu = QMenu("&Review", host)
        for item in (self.auto_label_action, self.cancel_job_action, self.rigid_body_action, None,
                     self.next_problem_action,
                     self.previous_problem_action, None, self.fill_all_action, None, self.add_event_action,
                     self.remove_event_action, self.next_event_action, self.previous_event_action):
            self.review_menu.addSeparator() if item is None else self.review_menu.addAction(item)
        self.review_menu.addMenu(self.events_menu)
        self.export_menu = QMenu("E&xport", host)
        for item in (self.export_c3d_action, self.export_csv_action, self.export_bvh_action):
            self.export_menu.addAction(item)

        toolbar = self.toolbar = QToolBar("Review", host)
        toolbar.setObjectName("review-toolbar")
        toolbar.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        toolbar.addAction(self.auto_label_action)
        toolbar.addSeparator()
        toolbar.addAction(self.undo_action)
        toolbar.addAction(self.redo_action)
        toolbar.addSeparator()
        toolbar.addAction(self.assign_action)
        toolbar.addAction(self.swap_action)
        toolbar.addAction(self.unlabel_action)
        toolbar.addAction(self.ghost_action)
        toolbar.addWidget(QLabel(" Scope "))
        self.scope_box = QComboBox(host)
        for scope, title in SCOPE_TITLES.items():
            self.scope_box.addItem(title, scope)
        self.scope_box.setToolTip("Which frames an edit changes: from the current frame to the end of the "
                                  "point's fragment, the range marked with I and O, or the whole take")
        toolbar.addWidget(self.scope_box)
        self.range_label = QLabel("", host)
        toolbar.addWidget(self.range_label)
        toolbar.addSeparator()
        toolbar.addAction(self.previous_problem_action)
        toolbar.addAction(self.next_problem_action)
        self.problem_label = QLabel("", host)
        toolbar.addWidget(self.problem_label)
