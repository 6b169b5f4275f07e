"""Session ▸ Process takes…: the panel edits and saves a pipeline, runs the batch live, lists each take's
state and announces the finished takes so the session browser follows."""

from __future__ import annotations

import os

import pytest

if not os.environ.get("DISPLAY"):
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

pytest.importorskip("pytestqt")

from batch_study import make_study  # noqa: E402

from handmocap.app.gui.application import Application, SessionFolderChanged, SessionPart  # noqa: E402
from handmocap.app.gui.batch_panel import BatchPanel  # noqa: E402
from handmocap.core.batch.pipeline import load_pipeline  # noqa: E402
from handmocap.core.session.session import Session  # noqa: E402


def test_panel_runs_the_batch_and_the_browser_hears_it(tmp_path, qtbot):
    make_study(tmp_path, 2)
    app, heard = Application(), []
    app.set_session(Session.open(tmp_path / "session"))
    app.add_listener(lambda event: heard.append(event) if isinstance(event, SessionFolderChanged) else None)
    panel = BatchPanel(app)
    qtbot.addWidget(panel)
    panel.layout_box.setCurrentText("glove-13")
    panel.hands_box.setCurrentText("right")
    for step in ("calibrate", "fill", "solve", "export"):
        panel.steps[step].setChecked(False)
    panel.workers.setValue(1)
    pipeline = panel.pipeline()
    panel.set_pipeline(pipeline)
    from handmocap.core.batch.pipeline import save_pipeline

    save_pipeline(panel.pipeline(), tmp_path / "saved.toml")
    assert load_pipeline(tmp_path / "saved.toml") == pipeline and pipeline.steps == ("label",)
    panel.start()
    qtbot.waitUntil(lambda: panel._thread is None, timeout=120_000)
    states = [panel.table.item(row, 1).text() for row in range(panel.table.rowCount())]
    assert states == ["done", "done"], panel.status.text()
    assert {event.take_id for event in heard if event.what == SessionPart.TAKE_STATE} == \
        {entry.id for entry in app.session.takes}
    assert all(entry.state == "labelled" for entry in app.session.takes)  # the browser's rows read these


def test_bad_pipeline_is_one_line_in_the_panel(tmp_path, qtbot):
    make_study(tmp_path, 1)
    app = Application()
    app.set_session(Session.open(tmp_path / "session"))
    panel = BatchPanel(app)
    qtbot.addWidget(panel)
    for box in panel.exports.values():
        box.setChecked(False)
    panel.start()
    assert panel._thread is None and "needs at least one" in panel.status.text()
