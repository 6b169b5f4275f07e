"""The GUI's lists come from the registries (issue 26 item 3): a fill method registered in a fixture is in the
batch panel's fill combo and the gap list's methods, an export format in the Export dialog and the batch
panel's exports; both are gone from widgets built after they are unregistered."""

from __future__ import annotations

import numpy as np
import pytest

from handmocap.app.gui.application import Application
from handmocap.app.gui.batch_panel import BatchPanel
from handmocap.app.gui.export_dialog import ExportDialog
from handmocap.core.gaps import (
    FillMethod,
    fill_choices,
    menu_fill_methods,
    register_fill_method,
    unregister_fill_method,
)
from handmocap.core.model import load_template
from handmocap.core.review import ReviewTake
from handmocap.core.review.export_formats import (
    ExportFormat,
    export_format_names,
    register_export_format,
    unregister_export_format,
)
from handmocap.core.review.synthetic import synthetic_labelling
from handmocap.core.simulate.motion import simulate_joint_angles
from handmocap.widgets.gap_list import GapList

pytestmark = pytest.mark.gui


@pytest.fixture
def extras():
    """A fill method "hold" and an export format "names", registered for one test."""
    register_fill_method(FillMethod(name="hold", label="Hold", description="The sample before the gap held",
                                    needs="", code=42, colour=(10, 20, 30), reach=1, menu_rank=9,
                                    fill=lambda positions, marker, start, length, _c, _a: np.repeat(
                                        positions[start - 1:start, marker], length, axis=0)))
    register_export_format(ExportFormat(name="names", label="Label names", suffixes=(".txt",), name_tag="_names",
                                        batch_ending=".names.txt", writer=lambda review, path, options: [path]))
    yield
    unregister_fill_method("hold")
    unregister_export_format("names")


def _review() -> ReviewTake:
    take, result, _ = synthetic_labelling(frames=20, labels=5, ghosts=1, seed=3)
    result.joint_angles = simulate_joint_angles(20, 0, "mixed", 100.0)
    return ReviewTake.from_labelling(take, result, layout="test")


def _lists(qtbot) -> dict[str, tuple[str, ...]]:
    """What the batch panel, the gap list and the Export dialog offer."""
    panel = BatchPanel(Application())
    gaps = GapList()
    dialog = ExportDialog(None, _review(), load_template, None, "take")
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


def test_registered_ones_are_offered_then_gone(qtbot, extras):
    lists = _lists(qtbot)
    assert lists["fill combo"][-1] == "hold" and lists["gap list"][-1] == "hold"
    assert lists["batch exports"][-1] == "names" and lists["export dialog"][-1] == "names"
    unregister_fill_method("hold")
    unregister_export_format("names")
    try:
        lists = _lists(qtbot)
        assert "hold" not in lists["fill combo"] + lists["gap list"]
        assert "names" not in lists["batch exports"] + lists["export dialog"]
    finally:
        register_fill_method(FillMethod(name="hold", label="", description="", needs="", code=42, colour=(0, 0, 0),
                                        reach=1, menu_rank=9, fill=lambda *_: np.zeros((0, 3))))
        register_export_format(ExportFormat(name="names", label="", suffixes=(".txt",), name_tag="",
                                            batch_ending=".names.txt", writer=lambda review, path, options: [path]))
