"""Process takes… on takes open in the window (issue 23 item 1): the result is applied through the open
document as one undoable, journalled step per take; every take's state is listed and counted truthfully."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

if not os.environ.get("DISPLAY"):
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

pytest.importorskip("pytestqt")
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "batch"))

from batch_study import make_study  # noqa: E402

from handmocap.app.gui.application import Application  # noqa: E402
from handmocap.app.gui.batch_panel import BatchPanel  # noqa: E402
from handmocap.app.gui.document import TakeDocument  # noqa: E402
from handmocap.core.batch.state import read_state  # noqa: E402
from handmocap.core.session.session import Session  # noqa: E402


def _open(app: Application, take_id: str) -> TakeDocument:
    opened = app.session.open_take(take_id)
    document = TakeDocument(take=opened.review.take, title=opened.entry.name, layout_name=opened.entry.layout,
                            open_take=opened, session_take_id=take_id)
    app.open_document(document)
    app.show(document)
    return document


def _panel(app: Application, qtbot) -> BatchPanel:
    panel = BatchPanel(app)
    qtbot.addWidget(panel)
    panel.layout_box.setCurrentText("glove-13")
    panel.hands_box.setCurrentText("right")
    for step in ("calibrate", "fill", "solve"):
        panel.steps[step].setChecked(False)
    for kind, box in panel.exports.items():
        box.setChecked(kind == "c3d")
    panel.workers.setValue(1)
    return panel


def _rows(panel: BatchPanel) -> list[tuple[str, str]]:
    return [(panel.table.item(row, 1).text(), panel.table.item(row, 2).text()) for row in range(panel.table.rowCount())]


def test_open_takes_get_the_result_as_one_undoable_step(tmp_path, qtbot):
    make_study(tmp_path, 3)
    app = Application()
    app.set_session(Session.open(tmp_path / "session"))
    first, second, third = (entry.id for entry in app.session.takes)
    opened = [_open(app, first), _open(app, second)]          # two of the three takes open in the window
    panel = _panel(app, qtbot)
    panel.start()
    qtbot.waitUntil(lambda: panel._thread is None, timeout=240_000)
    rows = _rows(panel)
    assert [state for state, _ in rows] == ["done", "done", "done"], (rows, panel.status.text())
    assert "applied to the open take as one step" in rows[0][1] and "applied" not in rows[2][1]
    assert panel.status.text().startswith("3 done (2 applied to takes open here)"), panel.status.text()
    assert "of 3 takes" in panel.status.text()
    for document in opened:
        assert document.has_labels()
        assert document.stack.undo_text().startswith("batch ") and document.stack.index == 1
        document.undo()                                      # one step takes the whole batch result back
        assert not document.has_labels()
        document.redo()
        assert document.has_labels()
    state = read_state(app.session.folder, [first, second, third])
    assert all(state[take]["state"] == "done" for take in (first, second, third))
    assert all(entry.state == "exported" for entry in app.session.takes)

    panel.start()                                            # nothing left to do: every take is up to date
    qtbot.waitUntil(lambda: panel._thread is None, timeout=120_000)
    assert [state for state, _ in _rows(panel)] == ["up to date"] * 3, panel.status.text()
    assert panel.status.text().startswith("0 done, 3 up to date — of 3 takes"), panel.status.text()


def test_an_open_take_edited_meanwhile_is_not_changed(tmp_path, qtbot):
    make_study(tmp_path, 1)
    app = Application()
    app.set_session(Session.open(tmp_path / "session"))
    document = _open(app, app.session.takes[0].id)
    panel = _panel(app, qtbot)
    panel.exports["c3d"].setChecked(False)
    panel.steps["export"].setChecked(False)
    panel.start()
    document.review.changed()                                # as an edit made while the batch runs
    qtbot.waitUntil(lambda: panel._thread is None, timeout=240_000)
    (state, reason), = _rows(panel)
    assert state == "skipped" and "edited while it was processed" in reason
    assert not document.has_labels() and document.stack.index == 0
    assert panel.status.text().startswith("0 done, 1 skipped"), panel.status.text()
