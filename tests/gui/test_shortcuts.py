"""One table of shortcuts (issue 23 item 5): it gives every action its keys, the menus' hints, the tooltips and
Help ▸ Keyboard shortcuts; the label menus (L, W) are typed into; Ctrl+Z works in the calibration wizard."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import release
from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QApplication

from handmocap.app.gui.document import TakeDocument
from handmocap.core.simulate import simulate_take
from handmocap.widgets.label_picker import LabelPicker
from handmocap.widgets.shortcuts import SECTIONS, SHORTCUTS, key_text, rows
from handmocap.widgets.shortcuts_dialog import ShortcutsDialog

pytestmark = pytest.mark.gui


def test_the_table_has_no_key_twice_in_one_window():
    seen: dict[str, str] = {}
    for name, entry in SHORTCUTS.items():
        assert entry.section in SECTIONS and entry.what and entry.keys, name
        window = "wizard" if entry.section == "Calibration wizard" else "main"
        for key in entry.keys:
            portable = QKeySequence(key).toString()
            assert portable, f"{name}: {key!r} is no key"
            assert (window, portable) not in seen, f"{key} is both {seen[(window, portable)]} and {name}"
            seen[(window, portable)] = name


def test_every_key_of_the_window_comes_from_the_table_and_is_named_in_its_tooltip_and_menu(window):
    bound = set()
    for action in window.findChildren(QAction):
        if not action.shortcuts():
            continue
        name = action.property("shortcut_name")
        assert name in SHORTCUTS, f"'{action.text()}' has keys {action.shortcut().toString()} outside the table"
        assert [sequence.toString() for sequence in action.shortcuts()] == \
            [QKeySequence(key).toString() for key in SHORTCUTS[name].keys]
        assert key_text(name) in action.toolTip(), (action.text(), action.toolTip())
        bound.add(name)
    missing = {name for name, entry in SHORTCUTS.items() if entry.section != "Calibration wizard"} - bound
    assert not missing, f"table entries no action of the window uses: {sorted(missing)}"
    assert window.review.redo_action.shortcuts()[1].toString() == "Ctrl+Y"
    help_menu = window.help_menu
    assert [action.text() for action in help_menu.actions()] == ["&Keyboard shortcuts"]
    assert help_menu.actions()[0].shortcut().toString() == "F1"


def test_help_lists_every_shortcut_and_finds_one(qtbot):
    dialog = ShortcutsDialog()
    qtbot.addWidget(dialog)
    assert dialog.visible_rows() == rows()
    qtbot.keyClicks(dialog.filter_edit, "redo")
    assert [row[1] for row in dialog.visible_rows()] == ["Ctrl+Shift+Z or Ctrl+Y"]
    dialog.filter_edit.setText("swap")
    assert any(row[1] == "W" for row in dialog.visible_rows())


def test_the_label_picker_is_typed_into(qtbot):
    picker = LabelPicker(None, "Swap with", [("right", ["R_index_tip", "R_ring_tip", "R_ring_middle"]),
                                              ("left", ["L_index_tip", "L_ring_tip"])])
    qtbot.addWidget(picker)
    picker.show()
    qtbot.keyClicks(picker.search, "ring")
    assert picker.names() == ["R_ring_tip", "R_ring_middle", "L_ring_tip"]
    qtbot.keyClicks(picker.search, "_m")
    assert picker.names() == ["R_ring_middle"]
    qtbot.keyClick(picker.search, Qt.Key.Key_Return)
    assert picker.chosen == "R_ring_middle" and not picker.isVisible()


def test_w_then_typing_swaps_with_the_label_found(window, qtbot):
    take = simulate_take(layout="dense", n_frames=60, seed=4, noise_mm=0.3).take
    window.add_document(TakeDocument(take, "typed"))
    review, controller = window.document.review, window.review
    controller.select_label(0)
    before = review.assignment.copy()
    target = "ring_distal"

    def type_into_picker() -> None:
        picker = QApplication.activePopupWidget()
        assert isinstance(picker, LabelPicker)
        qtbot.keyClicks(picker.search, "ring")
        qtbot.keyClicks(picker.search, "_dist")
        qtbot.keyClick(picker.search, Qt.Key.Key_Enter)

    QTimer.singleShot(200, type_into_picker)
    controller.choose_label_to_swap()
    other = review.label_index(target)
    np.testing.assert_array_equal(review.assignment[:, 0], before[:, other])
    assert controller.undo_action.text().startswith(f"&Undo swap '{review.label_names[0]}' and '{target}'")


def test_ctrl_z_in_the_calibration_wizard_undoes_the_last_landmark(qtbot):
    from handmocap.app.gui.calibration_wizard import open_calibration_wizard

    wizard = open_calibration_wizard(None)
    qtbot.addWidget(wizard)
    landmarks = wizard.pages["landmarks"]
    landmarks.assign(landmarks.current_name(), np.zeros(3))
    assert wizard.state.picked_count() == 1
    assert "Ctrl+Z" in landmarks.undo_button.toolTip()
    wizard.activateWindow()
    qtbot.waitUntil(wizard.isActiveWindow, timeout=2_000)
    qtbot.keyClick(wizard, Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier)
    # Qt keeps Ctrl in the application's modifier state until a Ctrl release arrives: without it the next
    # tests' clicks in the 3D view would be Ctrl+clicks (rigid-body picks)
    qtbot.keyRelease(wizard, Qt.Key.Key_Control)
    assert wizard.state.picked_count() == 0
    wizard.close()
    release(wizard)
