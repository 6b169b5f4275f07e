"""Views follow the model: an edit made on the document itself (no controller, no refresh call) shows in
the review views, its undo and redo too; the application object announces takes, selection, jobs, the
current frame and the changes of the session folder, and the views follow those too."""

import numpy as np
import pytest
from PySide6.QtWidgets import QApplication

from handmocap.app.gui.application import (
    Application,
    CurrentDocumentChanged,
    DocumentClosed,
    DocumentClosing,
    DocumentOpened,
    FrameChanged,
    Job,
    JobsChanged,
    SelectionChanged,
    SessionFolderChanged,
    SessionPart,
)
from handmocap.app.gui.document import TakeDocument
from handmocap.core.io import save_take
from handmocap.core.review import AcceptFills, GapFill, Unlabel
from handmocap.core.review.events import Change, ReviewChanged
from handmocap.core.session import Session
from handmocap.core.simulate import simulate_take
from handmocap.widgets.marker_lanes import EDITED
from handmocap.widgets.review_table import OBSERVED_COLUMN

pytestmark = pytest.mark.gui

FRAMES = 80


@pytest.fixture
def labelled_document():
    return TakeDocument(simulate_take(layout="dense", n_frames=FRAMES, seed=6, noise_mm=0.3).take, "labelled")


def test_review_views_follow_an_edit_its_undo_and_its_redo(window, labelled_document):
    """The 3D view follows a change at once; the whole-take views (table, lanes) once the window turned."""
    settle = QApplication.processEvents
    window.add_document(labelled_document)
    window.timeline.set_frame(30)
    controller, document = window.review, labelled_document
    label, name = 5, document.review.label_names[5]
    column = int(document.review.assignment[30, label])
    assert controller.table.model.value(label, OBSERVED_COLUMN) == pytest.approx(100.0)
    assert window.viewport.marker_names()[column] == name
    document.push(Unlabel(label=name, scope="range", start=20, stop=60))   # straight on the model
    assert window.viewport.marker_names()[column] == f"*{column}"        # the 3D view: the point lost its label
    assert controller.undo_action.text() == f"&Undo unlabel '{name}' at frames 21-60"
    settle()
    assert controller.table.model.value(label, OBSERVED_COLUMN) == pytest.approx(100.0 * (FRAMES - 40) / FRAMES)
    assert (controller.lanes.states()[20:60, label] == EDITED).all()
    document.undo()
    assert window.viewport.marker_names()[column] == name
    assert controller.redo_action.isEnabled() and controller.undo_action.text() == "&Undo"
    settle()
    assert controller.table.model.value(label, OBSERVED_COLUMN) == pytest.approx(100.0)
    assert (controller.lanes.states()[20:60, label] != EDITED).all()
    document.redo()
    assert window.viewport.marker_names()[column] == f"*{column}"
    fill = GapFill(name, 20, "linear", np.tile(document.review.take.marker_positions[19, column], (40, 1)))
    document.push(AcceptFills([fill]))
    settle()
    assert controller.table.model.value(label, 2) == pytest.approx(100.0 * 40 / FRAMES)     # Filled %
    assert not window.messages, window.messages


def test_only_the_shown_take_reaches_the_views(window, labelled_document):
    other = TakeDocument(labelled_document.take, "other")
    window.add_document(labelled_document)
    window.add_document(other)
    assert window.document is other
    name = labelled_document.review.label_names[2]
    labelled_document.push(Unlabel(label=name, scope="take"))          # a take that is not shown
    QApplication.processEvents()
    assert window.review.table.model.value(2, OBSERVED_COLUMN) == pytest.approx(100.0)
    window.take_box.setCurrentIndex(0)
    assert window.review.table.model.value(2, OBSERVED_COLUMN) == 0.0


def test_application_announces_takes_selection_jobs_and_the_shown_take_edits(labelled_document):
    app, heard = Application(), []
    app.add_listener(heard.append)
    other = TakeDocument(labelled_document.take, "other")
    app.open_document(labelled_document)
    app.open_document(other)
    app.show(labelled_document)
    assert heard == [DocumentOpened(labelled_document), DocumentOpened(other),
                     CurrentDocumentChanged(labelled_document, None)]
    app.select(3, 7)
    assert heard[-1] == SelectionChanged() and (app.selection.label, app.selection.column) == (3, 7)
    labelled_document.push(Unlabel(label=labelled_document.review.label_names[3], scope="take"))
    assert heard[-1] == ReviewChanged("do", (0, FRAMES), Change.LABELS | Change.FILLS | Change.SOLVE)
    app.show(other)
    assert heard[-1] == CurrentDocumentChanged(other, labelled_document) and app.selection.label == -1
    labelled_document.undo()                                        # no longer shown: not passed on
    assert heard[-1] == CurrentDocumentChanged(other, labelled_document)
    app.job_started("solve", Job("solve", other, lambda: None))
    assert heard[-1] == JobsChanged() and app.is_busy()
    app.job_ended("solve")
    assert not app.is_busy()
    del heard[:]
    assert app.close_document(other) is None
    assert heard == [DocumentClosing(other), DocumentClosed(other, 1),
                     CurrentDocumentChanged(labelled_document, other)]
    assert app.documents == [labelled_document]


def test_views_follow_the_current_frame_of_the_application(window, labelled_document):
    other = TakeDocument(labelled_document.take, "other")
    window.add_document(labelled_document)
    heard = []
    window.app.add_listener(heard.append)
    window.app.set_frame(40)                                   # no view is told: they follow the event
    assert heard == [FrameChanged(40)]
    assert window.timeline.frame == 40 and window.review.lanes.frame == 40
    window.review.lanes.frame_clicked.emit(12)                 # a view sets the frame: all follow
    assert window.app.frame == 12 and window.timeline.frame == 12
    window.timeline.set_frame(25)
    assert window.app.frame == 25 and window.review.lanes.frame == 25
    window.app.set_frame(10_000)                               # clamped to the take
    assert window.app.frame == FRAMES - 1 == window.timeline.frame
    window.add_document(other)                                 # each take keeps its frame
    assert window.app.frame == 0 == window.timeline.frame
    window.app.show(labelled_document)
    assert window.app.frame == FRAMES - 1 == window.timeline.frame


def test_session_browser_follows_changes_of_the_session_folder(window, labelled_document, tmp_path):
    path = tmp_path / "walk.c3d"
    save_take(labelled_document.take, path)
    session = Session.create(tmp_path / "session")
    app, heard = window.app, []
    app.set_session(session)
    app.add_listener(heard.append)
    entry = app.add_take(path, labelled_document.take)         # through the application, not the controller
    assert heard == [SessionFolderChanged(SessionPart.TAKES, entry.id)]
    browser = window.sessions.browser
    assert [row.id for row in browser.rows()] == [entry.id]
    app.set_take_state(entry.id, "reviewed")
    assert heard[-1] == SessionFolderChanged(SessionPart.TAKE_STATE, entry.id)
    assert browser.rows()[0].state == "reviewed" == session.take(entry.id).state
    app.record_export(entry.id, "csv", str(tmp_path / "walk.csv"))
    assert browser.rows()[0].state == "exported"
    app.remove_take(entry.id)
    assert heard[-1] == SessionFolderChanged(SessionPart.TAKES, entry.id) and browser.rows() == []
    app.set_session(None)
    session.close()


def test_the_application_object_and_the_events_need_no_qt():
    import subprocess
    import sys
    from pathlib import Path

    code = ("import sys, handmocap.app.gui.application, handmocap.core.review.events; "
            "bad = [m for m in ('PySide6', 'pyvista', 'pyqtgraph', 'handmocap.widgets') if m in sys.modules]; "
            "print(bad); sys.exit(1 if bad else 0)")
    root = Path(__file__).resolve().parents[2]
    completed = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, timeout=120)
    assert completed.returncode == 0, completed.stdout + completed.stderr
