"""Tools ▸ Learn a labelling template…: the dialog learns a lab's template from labelled takes on a worker
(progress, Cancel), shows where each marker sits per hand, saves it into the session's layouts (then
Auto-label lists it) or to a file, asks the rate of a file that states none, and says what is wrong with
bad input in one line."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QMessageBox

from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.learn_template import LearnTemplateDialog, TakeSource, where_it_sits
from handmocap.app.gui.review.dialogs import AutoLabelDialog, AutoLabelSettings
from handmocap.core.evaluation.data import SHARED_DATA
from handmocap.core.io import Take
from handmocap.core.model import MarkerLayout, layout_names, load_layout
from handmocap.core.model.lab_template import load_lab_template
from handmocap.core.simulate import simulate_scene
from handmocap.widgets.frame_rate_dialog import FrameRatePrompt

FRAMES = 300            # shorter simulated takes sometimes get the digit order wrong (core)
GUITAR = SHARED_DATA / "guitar" / "nokov_guitarist_arpeggio.csv"
WAIT_MS = 120_000


def _lab_layout() -> MarkerLayout:
    """The dense layout's finger and back-of-hand markers under a lab's names: digits A (thumb) to E (little),
    1 distal to 3 proximal, ``Wan-<n>`` on the back of the hand (the guitar lab's convention)."""
    names = {"back_radial": "Wan-1", "back_centre": "Wan-2", "back_ulnar": "Wan-3"}
    for letter, digit in zip("ABCDE", ("thumb", "index", "middle", "ring", "little"), strict=True):
        segments = ("metacarpal", "proximal", "distal") if digit == "thumb" else ("proximal", "middle", "distal")
        names.update({f"{digit}_{segment}": f"{letter}{number}" for number, segment in zip((3, 2, 1), segments,
                                                                                            strict=True)})
    dense = load_layout("dense")
    return MarkerLayout("lab", tuple(replace(spec, name=names[spec.name]) for spec in dense.markers
                                     if spec.name in names))


@pytest.fixture(scope="module")
def lab_take() -> Take:
    """A labelled two-hand take of a lab (``R-B1``, ``L-Wan-2`` …) with a rigid box (``box1``-``box4``)."""
    scene = simulate_scene(_lab_layout(), n_frames=FRAMES, seed=3, hands="both", n_objects=1, noise_mm=0.2,
                           ghost_rate=0.0, occlusion=False)
    positions = scene.truth["marker_positions"] + np.random.default_rng(0).normal(0.0, 0.2, (FRAMES, 40, 3))
    names = [str(name).replace("R_", "R-", 1).replace("L_", "L-", 1) for name in scene.truth["marker_names"]]
    return Take(names, positions, 100.0, vendor="simulated")


@pytest.fixture
def messages(monkeypatch) -> list[str]:
    shown: list[str] = []
    monkeypatch.setattr(QMessageBox, "warning", lambda parent, title, text: shown.append(text))
    return shown


def _dialog(qtbot, sources: list[TakeSource], **options) -> LearnTemplateDialog:
    dialog = LearnTemplateDialog(None, [(source, True) for source in sources], **options)
    qtbot.addWidget(dialog)
    dialog.show()
    return dialog


def _learn(qtbot, dialog: LearnTemplateDialog, name: str) -> None:
    dialog.name_edit.setText(name)
    qtbot.mouseClick(dialog.learn_button, Qt.MouseButton.LeftButton)
    assert dialog.runner.is_busy() and dialog.cancel_button.isEnabled() and not dialog.learn_button.isEnabled()
    qtbot.waitUntil(lambda: not dialog.runner.is_busy(), timeout=WAIT_MS)


def _check_lab_hands(dialog: LearnTemplateDialog) -> None:
    assert set(dialog.hand_tables) == {"right", "left"}
    for side, prefix in (("right", "R-"), ("left", "L-")):
        sits_on = dialog.sits_on(side)
        assert sits_on[prefix + "B1"] == "index, segment 3 (distal)"
        assert sits_on[prefix + "A3"] == "thumb, segment 1 (metacarpal)"
        assert sits_on[prefix + "E2"] == "little, segment 2 (middle)"
        assert sits_on[prefix + "Wan-2"].startswith("palm")
        assert "residual" in dialog.hand_boxes[side].title() and " mm" in dialog.hand_boxes[side].title()


def test_learn_from_the_shown_take_into_the_session(qtbot, window, lab_take, tmp_path) -> None:
    assert window.sessions.create_session(tmp_path / "guitar lab")
    try:
        window.add_document(TakeDocument(lab_take, "lab take.c3d"))
        assert any(action.text() == "Learn a labelling &template…" for action in window.tools_menu.actions())
        window.open_learn_template()
        dialog = window._learn_template_dialog
        assert [source.title for source in dialog.chosen_sources()] == ["lab take.c3d (shown take)"]
        assert dialog.template_name() == "guitar-lab-template"
        _learn(qtbot, dialog, "sim-lab")
        assert window.messages == [] and dialog.learned is not None
        _check_lab_hands(dialog)
        assert "box" in dialog.objects_label.text() and "box4" in dialog.objects_label.text()
        assert dialog.save_button.isEnabled()
        qtbot.mouseClick(dialog.save_button, Qt.MouseButton.LeftButton)
        saved = tmp_path / "guitar lab" / "layouts" / "sim-lab.json"
        assert saved.is_file() and "Auto-label" in dialog.status_label.text()
        assert window.sessions.session.layout_path("sim-lab") == saved
        template = load_lab_template("sim-lab")
        assert template is not None and template.sides == ["right", "left"] and len(template.objects) == 1
        assert template.hands["left"].digits[template.hands["left"].names.index("L-C1")] == "middle"
        auto_label = AutoLabelDialog(window, AutoLabelSettings())
        assert "sim-lab" in [auto_label.layout_box.itemText(i) for i in range(auto_label.layout_box.count())]
        auto_label.close()
        assert window.layout_box.findText("sim-lab") >= 0
        dialog.close()
    finally:
        window.sessions.close_session()
    assert "sim-lab" not in layout_names()


def _write_nokov(take: Take, path: Path) -> None:
    """``take`` as a NOKOV CSV export: ``<name>-X,<name>-Y,<name>-Z`` columns, no frame rate."""
    header = ",".join(f"{name}-{axis}" for name in take.marker_names for axis in "XYZ")
    np.savetxt(path, take.marker_positions.reshape(take.n_frames, -1), fmt="%.4f", delimiter=",", header=header,
               comments="")


def test_file_without_rate_asks_it_and_saves_to_a_file(qtbot, lab_take, tmp_path, messages, monkeypatch) -> None:
    csv = tmp_path / "lab_take.csv"
    _write_nokov(lab_take, csv)
    asked: list[str] = []

    def ask(prompt, path):
        asked.append(f"{Path(path).name} states no frame rate")
        return 100.0

    monkeypatch.setattr(FrameRatePrompt, "ask", ask)
    dialog = _dialog(qtbot, [])
    dialog.add_files([csv])
    assert "a file you choose" in dialog.where_label.text()
    _learn(qtbot, dialog, "from-file")
    qtbot.waitUntil(lambda: dialog.learned is not None, timeout=WAIT_MS)   # learned again with the rate
    assert len(asked) == 1 and "lab_take.csv states no frame rate" in asked[0] and messages == []
    _check_lab_hands(dialog)
    path = dialog.save(tmp_path / "lab.json")
    assert path == tmp_path / "lab.json" and load_lab_template(path).name == "from-file"


def test_session_takes_are_offered_when_the_shown_take_has_no_labels(qtbot, window, lab_take, tmp_path,
                                                                     monkeypatch) -> None:
    csv = tmp_path / "lab_take.csv"
    _write_nokov(lab_take, csv)
    monkeypatch.setattr(FrameRatePrompt, "ask", lambda *args: pytest.fail("the session knows the rate"))
    assert window.sessions.create_session(tmp_path / "session")
    try:
        entry = window.sessions.session.add_take(csv, frame_rate=100.0)
        assert entry.labelled_source
        window.open_learn_template()
        dialog = window._learn_template_dialog
        assert [source.title for source in dialog.chosen_sources()] == ["lab_take (session)"]
        _learn(qtbot, dialog, "from-session")
        assert window.messages == [] and dialog.learned is not None
        _check_lab_hands(dialog)
        dialog.close()
    finally:
        window.sessions.close_session()


def test_bad_input_is_one_line(qtbot, lab_take, messages) -> None:
    dialog = _dialog(qtbot, [])
    assert not dialog.learn() and messages == ["Tick at least one labelled take to learn from"]
    raw = Take([f"point_{i:03d}" for i in range(lab_take.n_markers)], lab_take.marker_positions, 100.0,
               source_path="raw.c3d")
    dialog = _dialog(qtbot, [TakeSource("raw", take=raw)])
    dialog.name_edit.setText("bad name!")
    assert not dialog.learn() and "letters, digits" in messages[-1]
    _learn(qtbot, dialog, "raw")
    assert "no labelled markers" in messages[-1] and "\n" not in messages[-1] and dialog.learned is None
    assert not dialog.save_button.isEnabled() and dialog.hand_tables == {}
    few = Take(lab_take.marker_names[:4], lab_take.marker_positions[:, :4], 100.0)
    dialog = _dialog(qtbot, [TakeSource("few", take=few)])
    _learn(qtbot, dialog, "few")
    assert "at least 5 are needed" in messages[-1] and "\n" not in messages[-1]
    assert len(messages) == 4 and all("Traceback" not in message for message in messages)


def test_cancel_learns_nothing(qtbot, lab_take, messages) -> None:
    dialog = _dialog(qtbot, [TakeSource("lab", take=lab_take)])
    dialog.name_edit.setText("cancelled")
    qtbot.mouseClick(dialog.learn_button, Qt.MouseButton.LeftButton)
    qtbot.mouseClick(dialog.cancel_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: not dialog.runner.is_busy(), timeout=WAIT_MS)
    assert dialog.learned is None and "Cancelled" in dialog.status_label.text() and messages == []
    assert dialog.learn_button.isEnabled() and not dialog.save_button.isEnabled()


def test_where_it_sits_in_words() -> None:
    assert where_it_sits("index", 3) == "index, segment 3 (distal)"
    assert where_it_sits("thumb", 1) == "thumb, segment 1 (metacarpal)"
    assert where_it_sits("palm", 0) == "palm (back of the hand)"


def guitar_take(frames: int = 300) -> Take:
    """The first ``frames`` of the guitar lab's NOKOV take (120 Hz), read with numpy."""
    with GUITAR.open(encoding="utf-8") as stream:
        header = stream.readline().strip().split(",")
    names = [cell[:-2] for cell in header[::3]]
    values = np.genfromtxt(GUITAR, delimiter=",", skip_header=1, max_rows=frames)
    return Take(names, values.reshape(len(values), len(names), 3), 120.0, vendor="NOKOV", source_path=str(GUITAR))


@pytest.mark.skipif(not GUITAR.is_file(), reason=f"{GUITAR} is absent")
def test_guitar_lab(qtbot, tmp_path, messages) -> None:
    dialog = _dialog(qtbot, [TakeSource(f"{GUITAR.name} (first 300 frames)", take=guitar_take())])
    _learn(qtbot, dialog, "guitar-lab")
    assert messages == [] and set(dialog.hand_tables) == {"right", "left"}
    for side, prefix in (("right", "R-"), ("left", "L-")):
        sits_on = dialog.sits_on(side)
        assert len(sits_on) == 19
        assert sits_on[prefix + "A1"] == "thumb, segment 3 (distal)"
        assert sits_on[prefix + "B1"] == "index, segment 3 (distal)"
        assert sits_on[prefix + "E3"] == "little, segment 1 (proximal)"
        assert sits_on[prefix + "Wan-nei"].startswith("palm")
    assert "Marker1, Marker2, Marker3, Marker4" in dialog.objects_label.text()
    template = load_lab_template(dialog.save(tmp_path / "guitar-lab.json"))
    assert template.sides == ["right", "left"] and template.learned_from == (GUITAR.name,)
