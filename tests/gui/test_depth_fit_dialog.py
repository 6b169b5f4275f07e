"""Tools ▸ Fit a hand to a depth frame… (issue 27 item 1): the dialog fits a real SR305 frame on a worker, draws
the fitted hand on the depth, says whether it is trusted and where the palm is, saves the same JSON and overlay
as ``handmocap depth fit``, and says what is wrong with a bad frame in one line.

Run as a script it saves the README's screenshot:
``xvfb-run -a python tests/gui/test_depth_fit_dialog.py OUT.png``."""

from __future__ import annotations

import json
import sys

import pytest

from handmocap.core.evaluation.data import RGBD_FRAMES

FRAME = RGBD_FRAMES / "sr305_open_right_hand" / "130.png"
pytestmark = [pytest.mark.gui,
              pytest.mark.skipif(not FRAME.is_file(), reason="the real depth frames are not in ../shared/data")]


def _fitted_dialog(qtbot, frame=FRAME):
    from handmocap.app.gui.depth_fit_dialog import DepthFitDialog

    dialog = DepthFitDialog(None, str(frame))
    qtbot.addWidget(dialog)
    dialog.resize(760, 720)
    dialog.show()
    dialog.start()
    qtbot.waitUntil(lambda: not dialog.runner.is_busy(), timeout=120_000)
    return dialog


def test_depth_fit_dialog_from_the_tools_menu_fits_shows_and_saves(window, qtbot, tmp_path):
    titles = [action.text() for action in window.tools_menu.actions()]
    assert "Fit a hand to a &depth frame…" in titles
    dialog = _fitted_dialog(qtbot)
    assert dialog.fit_result is not None and dialog.fit_result.fit.trusted
    assert dialog.status_label.text().startswith("Trusted.") and "Palm centre at" in dialog.status_label.text()
    assert not dialog.image_label.pixmap().isNull() and dialog.save_button.isEnabled()
    saved = dialog.save(tmp_path / "fit.json")
    result = json.loads(saved.read_text())
    assert result["trusted"] is True and len(result["palm_uv"]) == 2 and (tmp_path / "fit.png").is_file()
    dialog.close()


def test_depth_fit_dialog_bad_frame_is_one_line(qtbot, tmp_path):
    dialog = _fitted_dialog(qtbot, tmp_path / "missing.png")
    assert dialog.fit_result is None and "does not exist" in dialog.status_label.text()
    assert "\n" not in dialog.status_label.text() and not dialog.save_button.isEnabled()
    dialog.close()


if __name__ == "__main__":  # pragma: no cover - the README's screenshot
    from PySide6.QtWidgets import QApplication

    from handmocap.app.gui.depth_fit_dialog import DepthFitDialog

    application = QApplication.instance() or QApplication(sys.argv)
    shown = DepthFitDialog(None, str(FRAME))
    shown.resize(760, 720)
    shown.show()
    shown.start()
    while shown.runner.is_busy():
        application.processEvents()
    application.processEvents()
    shown.grab().save(sys.argv[1] if len(sys.argv) > 1 else "depth_fit.png")
