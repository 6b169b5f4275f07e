"""The GUI's lists come from the registries (issue 26 item 3): a fill method registered for a while is in the
batch panel's fill combo and the gap list's methods, an export format in the Export dialog and the batch
panel's exports; both are gone from widgets built after they are unregistered."""

from __future__ import annotations

import pytest
from registry_extras import registered_extras
from simulated_files import solved_review

from handmocap.app.gui.application import Application
from handmocap.app.gui.batch_panel import BatchPanel
from handmocap.app.gui.export_dialog import ExportDialog
from handmocap.core.gaps import fill_choices, menu_fill_methods
from handmocap.core.model import load_template
from handmocap.core.review.export_formats import export_format_names
from handmocap.widgets.gap_list import GapList

pytestmark = pytest.mark.gui


def _lists(qtbot) -> dict[str, tuple[str, ...]]:
    """What the batch panel, the gap list and the Export dialog offer."""
    panel = BatchPanel(Application())
    gaps = GapList()
    dialog = ExportDialog(None, solved_review(20, seed=3)[0], load_template, None, "take")
    for widget in (panel, gaps, dialog):
        qtbot.addWidget(widget)
    return {"fill combo": tuple(panel.fill_box.itemText(row) for row in range(panel.fill_box.count())),
            "gap list": tuple(gaps.method_buttons),
            "batch exports": tuple(panel.exports),
            "export dialog": tuple(dialog.format_box.itemData(row) for row in range(dialog.format_box.count()))}


def test_the_gui_lists_are_the_registries(qtbot):
    lists = _lists(qtbot)
    assert lists["fill combo"] == fill_choices()
    assert lists["gap list"] == tuple(method.name for method in menu_fill_methods()) == (
        "model", "pca", "linear", "spline", "pattern", "rigid")
    assert lists["batch exports"] == lists["export dialog"] == export_format_names()


def test_registered_ones_are_offered_then_gone(qtbot):
    with registered_extras():
        lists = _lists(qtbot)
        assert lists["fill combo"][-1] == "hold" and lists["gap list"][-1] == "hold"
        assert lists["batch exports"][-1] == "names" and lists["export dialog"][-1] == "names"
    lists = _lists(qtbot)
    assert "hold" not in lists["fill combo"] + lists["gap list"]
    assert "names" not in lists["batch exports"] + lists["export dialog"]
