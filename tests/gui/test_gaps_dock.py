"""The PCA fill in the gap dock: the gap list lists and recommends it, the fill preview draws it, the
marker lanes colour and name its filled samples."""

import numpy as np
import pytest

from handmocap.core.gaps import check_gap, fill_codes, fill_gap, fill_method, find_gaps
from handmocap.core.io import Take
from handmocap.core.simulate import simulate_take
from handmocap.widgets.fill_preview import FillPreview
from handmocap.widgets.gap_list import GapList, gap_rows
from handmocap.widgets.marker_lanes import STATE_COLOURS, STATE_NAMES, STATE_RANKS, lane_states

pytestmark = pytest.mark.gui


@pytest.fixture(scope="module")
def hand_take():
    """A simulated glove-13 take with a 40-frame gap of the middle fingertip."""
    take = simulate_take(layout="glove-13", n_frames=400, seed=7, noise_mm=0.2).take
    positions = take.marker_positions.copy()
    tip = take.marker_names.index("middle_tip")
    positions[180:220, tip] = np.nan
    return Take(list(take.marker_names), positions, take.frame_rate, first_frame=1), tip


def test_gap_list_lists_and_checks_pca(qtbot, hand_take):
    take, tip = hand_take
    gap = next(gap for gap in find_gaps(take) if gap.marker == tip)
    rows = gap_rows([gap], checks={0: check_gap(take, gap)})
    assert "pca" in rows[0].errors_mm and rows[0].recommended == "pca"      # a 0.4 s gap: PCA first
    widget = GapList()
    qtbot.addWidget(widget)
    widget.resize(700, 650)
    widget.show()
    widget.set_gaps(rows, take.marker_names, take.first_frame)
    widget.select_gap(0)
    button = widget.method_buttons["pca"]
    assert button.text() == fill_method("pca").label == "PCA" and button.isEnabled()
    assert widget.error_labels["pca"].text() == f"★ {rows[0].errors_mm['pca']:.2f} mm"
    assert widget.chosen_method() == "pca"
    assert widget.model.data(widget.model.index(0, 3)) == "PCA"
    with qtbot.waitSignal(widget.accept_requested, timeout=1000) as accepted:
        widget.accept_button.click()
    assert accepted.args == [0, "pca", -1]


def test_fill_preview_draws_the_pca_fill(qtbot, hand_take):
    take, tip = hand_take
    widget = FillPreview()
    qtbot.addWidget(widget)
    widget.resize(600, 400)
    widget.show()
    candidates = {method: fill_gap(take.marker_positions, tip, 180, 40, method) for method in ("spline", "pca")}
    widget.show_gap(take.marker_positions[:, tip], 180, 40, candidates, "pca", {"pca": 0.8}, take.first_frame,
                    "middle_tip")
    assert widget.methods() == ["pca", "spline"] and widget.selected() == "pca"
    _, values = widget.curve_data("pca", 0)
    np.testing.assert_allclose(values[1:-1], candidates["pca"][:, 0])
    assert widget._curves["pca"][0].opts["pen"].color().getRgb()[:3] == fill_method("pca").colour
    assert "PCA&nbsp;0.80&nbsp;mm" in widget.legend_label.text()


def test_marker_lanes_show_pca_fills():
    provenance = np.array([[0, fill_codes()["pca"], -1, fill_codes()["model"]]], dtype=np.int8)
    states = lane_states(provenance, low_confidence=np.array([[True, False, False, False]]), no_data_outside=False)
    assert states[0, 1] == fill_codes()["pca"] == 6
    assert STATE_COLOURS[6] == fill_method("pca").colour and STATE_NAMES[6] == "filled (PCA)"
    assert STATE_RANKS[states[0, 0]] > STATE_RANKS[6] > STATE_RANKS[0]      # low confidence > fill > observed
    assert len(set(STATE_RANKS.values())) == len(STATE_RANKS)
