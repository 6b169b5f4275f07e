"""File ▸ Export…: the dialog offers each format with the options it takes, writes the file as
``handmocap export`` does, asks before replacing a file and shows errors without closing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PySide6.QtWidgets import QMessageBox
from simulated_files import solved_review

from handmocap.app.gui.export_dialog import ExportDialog
from handmocap.core.io import load_take
from handmocap.core.io.axes import Y_UP
from handmocap.core.io.labelled_c3d import read_labelled_c3d
from handmocap.core.model import load_template
from handmocap.core.model.bvh import read_bvh
from handmocap.core.model.gltf import load_gltf_hand
from handmocap.core.review import ReviewTake

FRAMES = 40


@pytest.fixture
def review() -> ReviewTake:
    return solved_review(FRAMES, seed=3)[0]


@pytest.fixture
def messages(monkeypatch) -> list[str]:
    shown: list[str] = []
    monkeypatch.setattr(QMessageBox, "warning", lambda parent, title, text: shown.append(text))
    return shown


def _dialog(qtbot, review: ReviewTake, tmp_path: Path) -> ExportDialog:
    review.take.source_path = str(tmp_path / "take.c3d")      # the raw take the review was made from
    dialog = ExportDialog(None, review, load_template, None, "take")
    qtbot.addWidget(dialog)
    return dialog


def _choose(dialog: ExportDialog, name: str) -> None:
    dialog.format_box.setCurrentIndex(dialog.format_box.findData(name))


def test_each_format_with_its_options(qtbot, review, tmp_path, messages) -> None:
    dialog = _dialog(qtbot, review, tmp_path)
    # proposed next to the raw take, named after it and never the raw file itself
    assert dialog.format_name == "c3d" and dialog.path_edit.text() == str(tmp_path / "take_labelled.c3d")
    assert not dialog.units_box.isEnabled() and not dialog.up_box.isEnabled() and dialog.fills_box.isEnabled()
    assert dialog.export() and (tmp_path / "take_labelled.c3d").exists()
    assert read_labelled_c3d(tmp_path / "take_labelled.c3d").label_names == review.label_names

    dialog = _dialog(qtbot, review, tmp_path)
    _choose(dialog, "trc")
    assert dialog.units_box.isEnabled() and dialog.up_box.isEnabled()
    assert dialog.path_edit.text() == str(tmp_path / "take_markers.trc")
    dialog.units_box.setCurrentText("m")
    dialog.up_box.setCurrentIndex(dialog.up_box.findData("y"))
    written: list[tuple[str, str]] = []
    dialog.exported.connect(lambda name, path: written.append((name, path)))
    assert dialog.export()
    assert written == [("trc", str(tmp_path / "take_markers.trc"))]
    back = load_take(tmp_path / "take_markers.trc")
    np.testing.assert_allclose(back.marker_positions @ Y_UP, review.labelled_positions(), atol=2e-3, equal_nan=True)

    dialog = _dialog(qtbot, review, tmp_path)
    _choose(dialog, "gltf")
    assert not dialog.units_box.isEnabled() and dialog.units_box.currentText() == "m"
    assert dialog.up_box.currentData() == "y" and not dialog.fills_box.isEnabled()
    assert dialog.path_edit.text() == str(tmp_path / "take_hand.glb")
    assert dialog.export() and load_gltf_hand(tmp_path / "take_hand.glb").side == review.hands[0].side

    dialog = _dialog(qtbot, review, tmp_path)
    _choose(dialog, "bvh")
    dialog.units_box.setCurrentText("cm")
    assert dialog.export() and read_bvh(tmp_path / "take_angles.bvh").n_frames == FRAMES
    dialog = _dialog(qtbot, review, tmp_path)
    dialog.path_edit.setText(str(tmp_path / "mine.c3d"))      # the operator's own name keeps, with the suffix
    _choose(dialog, "csv")
    assert dialog.path_edit.text() == str(tmp_path / "mine.csv")
    assert not messages, messages


def test_joint_angle_formats_need_a_solved_hand(qtbot, review, tmp_path) -> None:
    review.hands[0].joint_angles[:] = np.nan
    dialog = _dialog(qtbot, review, tmp_path)
    model = dialog.format_box.model()
    enabled = {dialog.format_box.itemData(row): model.item(row).isEnabled() for row in range(dialog.format_box.count())}
    assert enabled == {"c3d": True, "trc": True, "csv": True, "angles-csv": False, "bvh": False, "gltf": False}


def test_replacing_asks_and_errors_keep_the_dialog_open(qtbot, review, tmp_path, messages, monkeypatch) -> None:
    target = tmp_path / "take_labelled.c3d"
    target.write_bytes(b"old")
    dialog = _dialog(qtbot, review, tmp_path)
    monkeypatch.setattr(QMessageBox, "question", lambda *args: QMessageBox.StandardButton.No)
    assert not dialog.export() and target.read_bytes() == b"old"
    monkeypatch.setattr(QMessageBox, "question", lambda *args: QMessageBox.StandardButton.Yes)
    assert dialog.export() and target.read_bytes()[:2] == bytes([2, 0x50])
    dialog = _dialog(qtbot, review, tmp_path)
    dialog.path_edit.setText(str(tmp_path / "missing" / "take.c3d"))
    assert not dialog.export()
    assert len(messages) == 1 and "does not exist" in messages[0]
    assert not dialog.result()


def test_file_menu_offers_export(window) -> None:
    texts = [action.text() for action in window.file_menu.actions()]
    assert "&Export…" in texts
    window.export_dialog_action.trigger()          # no take shown: nothing happens
    assert not window.messages
