"""Legibility at 1366×768: every toolbar command reachable, the fill preview beside the gap list, units in the
column headers with tooltips, take names elided in the middle with the full name as tooltip, and the
warnings of reading and labelling in the message panel instead of on the terminal."""

import logging
import threading
import warnings

import pytest
from PySide6.QtCore import QPoint

from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.launch import window_size
from handmocap.core.errors import InputError
from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.simulate import simulate_take
from handmocap.widgets.gap_list import COLUMNS as GAP_COLUMNS
from handmocap.widgets.review_table import COLUMNS as TABLE_COLUMNS

pytestmark = pytest.mark.gui

LONG_NAME = "session_2024-05-01_subject_07_right_hand_grasp_and_release_take_012.c3d"


@pytest.fixture
def small(window, qtbot):
    """The window at 1366×768 showing a labelled simulated take with a long name."""
    window.resize(1366, 768)
    take = simulate_take(layout="dense", n_frames=150, seed=2, occlusion=True).take
    window.add_document(TakeDocument(take, LONG_NAME))
    qtbot.wait(300)
    return window


def test_every_toolbar_command_is_on_screen_at_1366(small):
    for toolbar in (small.findChild(type(small.review.toolbar), "main-toolbar"), small.review.toolbar):
        for action in toolbar.actions():
            if action.isSeparator():
                continue
            widget = toolbar.widgetForAction(action)
            assert widget is not None and widget.isVisible(), action.text() or action
            right = widget.mapTo(small, QPoint(widget.width(), 0)).x()
            assert right <= small.width(), f"{action.text()} ends at {right} px"


def test_fill_preview_is_shown_beside_the_gap_list(small, qtbot):
    small.gaps_dock.raise_()
    qtbot.wait(100)
    gap_list, preview = small.review.gap_list, small.review.preview
    assert gap_list.isVisible() and preview.isVisible()
    assert preview.height() >= 150 and preview.width() >= 200
    top_left = preview.mapTo(small, QPoint(0, 0))
    assert top_left.y() + preview.height() <= small.height() and top_left.x() + preview.width() <= small.width()


def test_column_headers_carry_units_and_tooltips(small):
    assert "Sure by\n(mm)" in TABLE_COLUMNS and "Off model\n(mm)" in TABLE_COLUMNS and "Error (mm)" in GAP_COLUMNS
    from PySide6.QtCore import Qt

    for model in (small.review.table.model, small.review.gap_list.model):
        for column in range(model.columnCount()):
            tip = model.headerData(column, Qt.Orientation.Horizontal, Qt.ItemDataRole.ToolTipRole)
            assert tip, model.headerData(column, Qt.Orientation.Horizontal, Qt.ItemDataRole.DisplayRole)
    confidence = small.review.table.model.headerData(TABLE_COLUMNS.index("Sure by\n(mm)"), Qt.Orientation.Horizontal,
                                                     Qt.ItemDataRole.ToolTipRole)
    assert "mm" in confidence and "swap" in confidence and "labelling confidence" in confidence   # the precise term
    residual = small.review.table.model.headerData(TABLE_COLUMNS.index("Off model\n(mm)"), Qt.Orientation.Horizontal,
                                                   Qt.ItemDataRole.ToolTipRole)
    assert "IK residual" in residual


def test_take_names_are_elided_in_the_middle_with_the_full_name_as_tooltip(small):
    box = small.take_box
    assert box.currentText() == LONG_NAME
    assert box.width() < box.fontMetrics().horizontalAdvance(LONG_NAME)     # it does not fit: elided
    assert LONG_NAME in box.full_tooltip()
    image = box.grab()                                                     # paints without error
    assert not image.isNull()


def test_warnings_land_in_the_message_panel(small, qtbot, capsys):
    panel = small.message_panel
    logging.getLogger("handmocap.core.io.c3d_file").warning("take.c3d: POINT:UNITS is missing")
    worker = threading.Thread(target=lambda: logging.getLogger("handmocap.core.io.trc").warning("from a worker"))
    worker.start()
    worker.join()
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.warn("a Python warning", UserWarning, stacklevel=1)
    qtbot.waitUntil(lambda: len(panel.messages()) == 3, timeout=3_000)
    assert panel.messages()[0] == "take.c3d: POINT:UNITS is missing"
    assert panel.messages()[1] == "from a worker"
    assert "a Python warning" in panel.messages()[2]
    assert small.messages_button.isVisible() and "3" in small.messages_button.text()
    assert small.messages_dock.windowTitle() == "Messages (3)"
    assert "POINT:UNITS" not in capsys.readouterr().err
    panel.clear()
    assert not small.messages_button.isVisible()


def test_closing_the_window_stops_routing_warnings(window):
    handler = window.log_handler
    assert handler in logging.getLogger().handlers
    window.close()
    assert handler not in logging.getLogger().handlers


def test_window_size_option():
    assert window_size("1366x768") == (1366, 768)
    assert window_size("1920X1080") == (1920, 1080)
    for text in ("big", "1366", "10x10", "1366x-768"):
        with pytest.raises(InputError):
            window_size(text)




@pytest.mark.skipif(not REAL_RECORDING.exists(), reason="the real recording is not in ../shared")
def test_a_file_reading_warning_lands_in_the_message_panel(window, qtbot, tmp_path, capsys):
    lines = REAL_RECORDING.read_text().splitlines(keepends=True)
    header = next(number for number, line in enumerate(lines) if line.startswith("Frame\t")) + 1
    short = tmp_path / "short.tsv"
    short.write_text("".join(lines[:header + 40]))          # NO_OF_FRAMES still says 3000
    with qtbot.waitSignal(window.loader.succeeded, timeout=30_000):
        window.open_files([short])
    qtbot.waitUntil(lambda: bool(window.message_panel.messages()), timeout=5_000)
    assert window.message_panel.messages() == ["short.tsv: NO_OF_FRAMES says 3000, the file has 40 frames"]
    assert "NO_OF_FRAMES" not in capsys.readouterr().err
