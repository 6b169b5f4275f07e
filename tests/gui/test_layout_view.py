"""The layout view driven like an operator: optimise a tiny problem with a live energy plot, cancel,
compare two layouts in synchronised views with their metrics, export placement sheets, bad input."""

import numpy as np
import pytest
from conftest import release
from PySide6.QtWidgets import QMessageBox

import handmocap.app.gui.layout_view as layout_view_module
from handmocap.app.gui.layout_view import open_layout_view
from handmocap.core.model import load_layout


@pytest.fixture
def view(qtbot, monkeypatch):
    messages: list[str] = []
    monkeypatch.setattr(QMessageBox, "warning", lambda parent, title, text: messages.append(text))
    monkeypatch.setattr(layout_view_module, "METRIC_RECONSTRUCTION_FRAMES", 60)
    saved = []
    window = open_layout_view(save_to_session=saved.append)
    window.messages, window.saved = messages, saved
    qtbot.addWidget(window)
    yield window
    window.close()
    release(window)


def tiny(window, markers=5):
    window.markers_spin.setValue(markers)
    window.particles_spin.setValue(40)
    window.iterations_spin.setValue(6)
    window.keyframes_spin.setValue(3)


def test_optimise_a_tiny_layout_with_live_energy(qtbot, view):
    before = len(view.entries)
    tiny(view)
    view.optimise_button.click()
    assert view.cancel_button.isEnabled()
    qtbot.waitUntil(lambda: not view.is_busy() and len(view.entries) == before + 1, timeout=60_000)
    entry = view.entries[-1]
    assert entry.origin == "optimised" and len(entry.layout.markers) == 5 and entry.energy is not None
    energies = view.energy_plot.current_values()
    assert len(energies) == 6 and energies[-1] == pytest.approx(entry.energy)
    assert all(later <= earlier for earlier, later in zip(energies, energies[1:], strict=False))
    assert view.layout_list.currentRow() == len(view.entries) - 1
    view.save_session_button.click()                              # the session callback gets the layout
    assert view.saved == [entry.layout]


def test_cancel_keeps_everything(qtbot, view):
    before = [entry.layout.name for entry in view.entries]
    view.particles_spin.setValue(5000)
    view.iterations_spin.setValue(2000)
    view.optimise_button.click()
    qtbot.waitUntil(lambda: len(view.energy_plot.current_values()) >= 1, timeout=60_000)
    view.cancel_button.click()
    qtbot.waitUntil(lambda: not view.is_busy(), timeout=30_000)
    assert "cancelled" in view.status.text()
    assert [entry.layout.name for entry in view.entries] == before and not view.messages


def test_compare_two_layouts_side_by_side(qtbot, view):
    view.set_checked(["grasp-4", "glove-13"])
    assert view.compare.view_count() == 2
    view.compare.set_frame(120)
    first, second = view.compare.views()
    np.testing.assert_allclose(first.vertex_points(), second.vertex_points())   # same posture in both
    assert len(first.marker_points()) == 13 and len(second.marker_points()) == 4
    moved_before = second.marker_points()
    view.compare.slider.setValue(400)                             # one slider drives every view
    assert view.compare.frame() == 400
    assert not np.allclose(moved_before, second.marker_points())
    assert first.plotter.renderer.GetActiveCamera() is second.plotter.renderer.GetActiveCamera()

    view.metrics_button.click()
    qtbot.waitUntil(lambda: not view.is_busy() and view.metrics_table.columnCount() == 2, timeout=120_000)
    table = view.metrics_table
    assert [table.horizontalHeaderItem(c).text() for c in range(2)] == ["glove-13", "grasp-4"]
    assert table.text_at(0, 0) == "13" and table.text_at(0, 1) == "4"
    assert float(table.text_at(6, 0)) > 0 and "–" in table.text_at(4, 1)


def test_placement_sheets_and_saving_to_a_file(tmp_path, view, monkeypatch):
    layout = load_layout("grasp-4")
    assert view.export_sheet(layout, tmp_path / "sheet.png") and view.export_sheet(layout, tmp_path / "sheet.pdf")
    assert (tmp_path / "sheet.png").stat().st_size > 30_000
    assert (tmp_path / "sheet.pdf").read_bytes()[:5] == b"%PDF-"
    assert not view.export_sheet(layout, tmp_path / "sheet.bmp") and ".png or .pdf" in view.messages[-1]
    view.save_to_session = None
    assert view.save_layout_file(layout, tmp_path / "copy.json")
    assert load_layout(tmp_path / "copy.json").names == layout.names


def test_bad_requests_are_explained_and_lose_nothing(qtbot, view):
    names = [entry.layout.name for entry in view.entries]
    tiny(view, markers=3000)
    view.optimise_button.click()
    qtbot.waitUntil(lambda: not view.is_busy() and len(view.messages) == 1, timeout=60_000)
    assert "cannot place 3000 markers" in view.messages[-1]
    tiny(view, markers=2)
    view.dims_spin.setValue(6)
    view.optimise_button.click()
    qtbot.waitUntil(lambda: not view.is_busy() and len(view.messages) == 2, timeout=60_000)
    assert "cannot constrain" in view.messages[-1]
    view.motion_combo.setCurrentIndex(3)                          # solved takes, none chosen
    view.optimise_button.click()
    assert "empty" in view.messages[-1] and not view.is_busy()
    view.set_result_files(["/nonexistent/take.npz"])
    assert "take.npz" in view.messages[-1]
    assert [entry.layout.name for entry in view.entries] == names


def test_error_against_markers_plot(qtbot, view):
    tiny(view)
    view.particles_spin.setValue(20)
    view.iterations_spin.setValue(2)
    view.table_min_spin.setValue(4)
    view.table_max_spin.setValue(5)
    view.error_button.click()
    qtbot.waitUntil(lambda: not view.is_busy() and len(view.error_plot.rows) == 2, timeout=120_000)
    assert [row.markers for row in view.error_plot.rows] == [4, 5]
    assert "specific layouts better" in view.status.text()
