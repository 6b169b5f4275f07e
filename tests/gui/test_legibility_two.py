"""Legibility, round two (issue 23): at 1366×768 the Gaps dock shows Accept / Reject and whole headers, the
fill preview's axis names do not overlap, take names stay told apart, the layout list's tick boxes show on the
dark theme, the camera's sync buttons say what they do, plain words in the tables (the precise term in the
tooltip), and the batch report's plot names the takes."""

from __future__ import annotations

import pytest
from PySide6.QtGui import QFont, QFontMetrics, QPalette
from PySide6.QtWidgets import QApplication

from handmocap.app.gui.document import TakeDocument
from handmocap.core.simulate import simulate_take
from handmocap.widgets.session_browser import distinct_elided

pytestmark = pytest.mark.gui


def test_take_names_shortened_stay_told_apart(qtbot):
    metrics = QFontMetrics(QFont())
    names = ["simulated grasps (dense, labelled)", "simulated raw take (dense, unlabelled)",
             "simulated take with a camera (dense, labelled)", "DFKI glove recording (real)"]
    width = metrics.horizontalAdvance("simulated grasps (d")
    shown = [distinct_elided(name, names, metrics, width) for name in names]
    assert len(set(shown)) == len(names), shown
    assert shown[0].startswith("…grasps") and shown[1].startswith("…raw take"), shown
    assert all(metrics.horizontalAdvance(text) <= width for text in shown), shown
    assert distinct_elided("short", names, metrics, width) == "short"


def test_the_gaps_dock_at_1366x768_shows_its_buttons_and_whole_headers(window, qtbot):
    window.resize(1366, 768)
    take = simulate_take(layout="dense", n_frames=400, seed=5, noise_mm=0.3, occlusion=True).take
    window.add_document(TakeDocument(take, "gaps"))
    controller = window.review
    window.gaps_dock.raise_()
    qtbot.waitUntil(lambda: bool(controller.gap_list.rows()), timeout=10_000)
    controller.gap_list.table.selectRow(0)
    QApplication.processEvents()
    for button in (controller.gap_list.preview_button, controller.gap_list.accept_button,
                   controller.gap_list.reject_button, controller.gap_list.fill_all_button):
        assert button.isVisible() and not button.visibleRegion().isEmpty(), button.text()
        assert button.visibleRegion().boundingRect().width() == button.width(), f"{button.text()} is cut off"
    header = controller.gap_list.table.horizontalHeader()
    metrics = header.fontMetrics()
    model = controller.gap_list.model
    for column in range(model.columnCount() - 1):          # the last one takes what is left (it may scroll)
        text = model.headerData(column, 1, 0)
        assert header.sectionSize(column) >= metrics.horizontalAdvance(text), text
    # the fill preview's axis names are level labels, one per plot: nothing rotated to overlap
    preview = controller.preview
    assert all(plot.getAxis("left").labelText == "" for plot in preview.plots)


def test_layout_list_tick_boxes_show_on_the_dark_theme(qtbot):
    from handmocap.app.gui.layout_view import LayoutWindow
    from handmocap.app.gui.palette import apply_dark_palette

    app = QApplication.instance()
    before = app.palette()
    apply_dark_palette(app)
    try:
        view = LayoutWindow()
        qtbot.addWidget(view)
        palette = view.layout_list.palette()
        outline = palette.color(QPalette.ColorRole.Window).darker(140)     # Fusion's check box outline
        base = palette.color(QPalette.ColorRole.Base)
        assert abs(outline.lightness() - base.lightness()) > 40
        view.close()
    finally:
        app.setPalette(before)


def test_camera_sync_buttons_and_table_headers_speak_plainly(window):
    buttons = window.cameras.view.nudge_buttons
    assert [buttons[step].text() for step in ((-1, 0), (0, -1), (0, 1), (1, 0))] == ["◀◀", "◀", "▶", "▶▶"]
    assert "Ctrl+Alt+Left" in buttons[(-1, 0)].toolTip() and "clock offset" in buttons[(-1, 0)].toolTip()
    from handmocap.widgets.layout_plots import METRIC_ROWS, METRIC_TIPS

    assert not any("κ" in name for name, _ in METRIC_ROWS) and "κ(JᵀJ)" in METRIC_TIPS[1]


def test_the_batch_report_names_the_takes_on_its_axis(qtbot):
    pytest.importorskip("matplotlib")
    from handmocap.core.batch.report import COLUMNS, study_report_html

    rows = [{"take": f"t{index:04d}", "name": name, "status": "done", "labelled_share": 0.9, "longest_gap": 12,
             "mean_residual_mm": 0.5, "seconds": 1.0} for index, name in enumerate(["trial01", "trial02"])]
    assert "longest gap (frames)" in COLUMNS
    page = study_report_html("study", rows)
    assert "trial01" in page and "<th>longest gap (frames)</th>" in page
