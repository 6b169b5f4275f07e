"""Review widgets driven like an operator: marker lanes, review marker table, gap list, fill preview,
session browser (clicks, sorting, filtering, signals, no feedback loops)."""

import numpy as np
import pytest
from PySide6.QtCore import QMimeData, QPoint, QPointF, Qt, QUrl
from PySide6.QtGui import QDropEvent
from PySide6.QtWidgets import QFileDialog

from handmocap.core.gaps import check_gap, fill_codes, fill_gap, find_gaps
from handmocap.core.io import Take
from handmocap.core.review import (
    LANE_EDITED,
    LANE_FILLED,
    LANE_GAP,
    LANE_LOW_CONFIDENCE,
    LANE_NONE,
    LANE_OBSERVED,
    MarkerStats,
    ReviewTake,
)
from handmocap.widgets.fill_preview import FillPreview
from handmocap.widgets.gap_list import AUTO_DONOR, GapList, GapRow, gap_rows, with_state
from handmocap.widgets.gap_list import COLUMNS as GAP_COLUMNS
from handmocap.widgets.marker_lanes import (
    EDITED,
    GAP,
    LOW_CONFIDENCE,
    NO_DATA,
    OBSERVED,
    STATE_COLOURS,
    STATE_RANKS,
    MarkerLanes,
    lane_states,
    lanes_from_review,
    state_ranks,
)
from handmocap.widgets.review_table import COLUMNS as TABLE_COLUMNS
from handmocap.widgets.review_table import ReviewTable
from handmocap.widgets.session_browser import SessionBrowser, TakeRow

pytestmark = pytest.mark.gui


# ----------------------------------------------------------------------------------------------- data
def smooth_take(n_frames: int = 400, n_markers: int = 6, first_frame: int = 101) -> Take:
    """Markers on a slowly rotating rigid hand-sized cluster (so pattern and rigid fills apply), mm."""
    rng = np.random.default_rng(4)
    offsets = rng.normal(0.0, 30.0, (n_markers, 3))
    t = np.arange(n_frames) / 100.0
    angle = 0.8 * np.sin(1.3 * t)
    rotation = np.zeros((n_frames, 3, 3))
    rotation[:, 0, 0] = rotation[:, 1, 1] = np.cos(angle)
    rotation[:, 0, 1], rotation[:, 1, 0] = -np.sin(angle), np.sin(angle)
    rotation[:, 2, 2] = 1.0
    centre = np.stack([200 * np.sin(0.7 * t), 150 * np.cos(0.5 * t), 900 + 40 * t], axis=1)
    positions = centre[:, None] + np.einsum("fij,mj->fmi", rotation, offsets)
    return Take([f"m{i}" for i in range(n_markers)], positions, 100.0, first_frame=first_frame)


def view_to_widget(lanes: MarkerLanes, frame_number: float, lane: float) -> QPoint:
    """Viewport pixel of view point (file frame number, lane)."""
    scene = lanes.view_box.mapViewToScene(QPointF(frame_number, lane))
    return lanes.plot.mapFromScene(scene)


def shown(qtbot, widget, width: int, height: int):
    """``widget`` kept by ``qtbot``, resized to ``width`` × ``height`` px and shown."""
    qtbot.addWidget(widget)
    widget.resize(width, height)
    widget.show()
    return widget


def click_lane(qtbot, lanes: MarkerLanes, frame_number: float, lane: float) -> None:
    qtbot.mouseClick(lanes.plot.viewport(), Qt.MouseButton.LeftButton, pos=view_to_widget(lanes, frame_number, lane))


@pytest.fixture
def lanes(qtbot):
    widget = shown(qtbot, MarkerLanes(), 900, 360)
    qtbot.waitExposed(widget)
    return widget


def lane_fixture_states(n_frames: int = 1000, n_markers: int = 5) -> np.ndarray:
    states = np.zeros((n_frames, n_markers), dtype=np.int8)
    states[100:150, 1] = GAP
    states[300:320, 2] = fill_codes()["model"]
    states[500:505, 3] = LOW_CONFIDENCE
    states[700:760, 4] = EDITED
    states[:40, 0] = NO_DATA
    return states


# ------------------------------------------------------------------------------------- marker lanes
def test_lane_states_from_provenance_and_masks():
    provenance = np.array([[-1, 0], [0, 0], [-1, 5], [0, -1], [0, 0], [-1, 0]], dtype=np.int8)
    low = np.zeros((6, 2), dtype=bool)
    low[1, 0] = low[2, 1] = True                     # a filled sample cannot be low confidence
    edited = np.zeros((6, 2), dtype=bool)
    edited[4, 1] = edited[5, 0] = True                # a missing sample cannot be edited
    states = lane_states(provenance, low, edited)
    np.testing.assert_array_equal(states[:, 0], [NO_DATA, LOW_CONFIDENCE, GAP, OBSERVED, OBSERVED, NO_DATA])
    np.testing.assert_array_equal(states[:, 1], [OBSERVED, OBSERVED, 5, GAP, EDITED, OBSERVED])
    assert lane_states(provenance, no_data_outside=False)[0, 0] == GAP


def test_lanes_from_review_codes_keep_the_fill_method():
    lanes = np.array([[LANE_NONE, LANE_OBSERVED, LANE_GAP, LANE_FILLED, LANE_LOW_CONFIDENCE, LANE_EDITED]],
                     dtype=np.int8)
    provenance = np.array([[-1, 0, -1, fill_codes()["pattern"], 0, 0]], dtype=np.int8)
    states = lanes_from_review(lanes, provenance)
    np.testing.assert_array_equal(states[0], [NO_DATA, OBSERVED, GAP, fill_codes()["pattern"], LOW_CONFIDENCE,
                                              EDITED])


def test_zoomed_out_columns_show_the_most_important_state():
    assert STATE_RANKS[GAP] > STATE_RANKS[LOW_CONFIDENCE] > STATE_RANKS[EDITED] > STATE_RANKS[fill_codes()["model"]]
    assert STATE_RANKS[fill_codes()["linear"]] > STATE_RANKS[OBSERVED] > STATE_RANKS[NO_DATA]
    assert len(set(STATE_RANKS.values())) == len(STATE_RANKS)
    codes = np.array(list(STATE_RANKS), dtype=np.int8)[:, None]
    np.testing.assert_array_equal(state_ranks(codes)[:, 0], list(STATE_RANKS.values()))


def test_click_on_a_lane_emits_frame_marker_and_stretch(lanes, qtbot):
    states = lane_fixture_states()
    lanes.set_lanes([f"marker_{i}" for i in range(5)], states, first_frame=101, frame_rate=100.0)
    lanes.set_x_range(101, 500)           # ~0.5 frames per pixel: clicks hit exact frames
    qtbot.wait(20)
    received = []
    lanes.marker_clicked.connect(lambda marker: received.append(("marker", marker)))
    lanes.frame_clicked.connect(lambda frame: received.append(("frame", frame)))
    lanes.stretch_clicked.connect(lambda *stretch: received.append(("stretch", stretch)))
    click_lane(qtbot, lanes, 101 + 120, 1.5)        # inside the gap of marker 1 (frames 100..149)
    found = dict(received)
    assert len(received) == 3 and found["marker"] == 1
    assert abs(found["frame"] - 120) <= 1
    assert found["stretch"] == (1, 100, 149)
    assert lanes.selected_marker() == 1 and lanes.frame == found["frame"]
    with qtbot.waitSignal(lanes.stretch_clicked, timeout=2000) as stretch_signal:
        click_lane(qtbot, lanes, 101 + 310, 2.5)        # the model fill of marker 2
    assert stretch_signal.args == [2, 300, 319]
    assert "filled (model)" in lanes.describe(2, 310) and "frames 401–420" in lanes.describe(2, 310)


def test_hover_tooltip_names_marker_frame_and_stretch(lanes, qtbot):
    lanes.set_lanes([f"marker_{i}" for i in range(5)], lane_fixture_states(), first_frame=101, frame_rate=100.0)
    lanes.set_x_range(101, 500)
    qtbot.wait(20)
    qtbot.mouseMove(lanes.plot.viewport(), view_to_widget(lanes, 101 + 130, 1.5))
    qtbot.waitUntil(lambda: "marker_1" in lanes.plot.toolTip(), timeout=2000)
    tip = lanes.plot.toolTip()
    assert "gap: frames 201–250 (50 frames)" in tip and "(1.30 s)" in tip
    qtbot.wait(50)
    qtbot.mouseMove(lanes.plot.viewport(), view_to_widget(lanes, 101 + 310, 2.5))
    qtbot.waitUntil(lambda: "filled (model)" in lanes.plot.toolTip(), timeout=2000)


def test_a_one_frame_gap_survives_zooming_out_and_is_picked(lanes, qtbot):
    n_frames = 100_000
    states = np.zeros((n_frames, 20), dtype=np.int8)
    states[54_321, 7] = GAP
    lanes.set_lanes([f"m{i}" for i in range(20)], states, first_frame=1)
    qtbot.wait(20)
    image = lanes._image.image
    assert image.shape[0] <= lanes.view_box.width() + 1             # one column per pixel, not per frame
    gap_columns = np.flatnonzero((image[:, 7, :3] == STATE_COLOURS[GAP]).all(axis=1))
    assert len(gap_columns) == 1
    marker, frame, snapped = lanes.hit(1 + 54_321 + 0.4 * lanes._frames_per_column, 7.5)
    assert (marker, snapped) == (7, 54_321) and frame != snapped
    assert lanes.stretch_at(7, snapped) == (GAP, 54_321, 54_321)
    assert "gap: frame 54322 (1 frame)" in lanes.describe(7, frame, snapped)


def test_x_range_sync_and_cursor(lanes, qtbot):
    lanes.set_lanes(["a", "b"], np.zeros((500, 2), dtype=np.int8), first_frame=1)
    emitted = []
    lanes.x_range_changed.connect(lambda low, high: emitted.append((low, high)))
    lanes.set_x_range(50, 150)                 # from the timeline: no echo
    assert emitted == []
    low, high = lanes.x_range()
    assert abs(low - 50) < 1e-6 and abs(high - 150) < 1e-6
    lanes.view_box.setXRange(200, 300, padding=0)     # what a pan or a wheel zoom does
    assert emitted and abs(emitted[-1][0] - 200) < 1e-6
    lanes.set_frame(42)
    assert lanes.frame == 42 and lanes._cursor.value() == 43
    lanes.show_frames(300, 339)                  # e.g. on stretch_clicked: zoom to the stretch
    low, high = lanes.x_range()
    assert low < 301 and high > 340 and high - low < 100
    assert emitted[-1] == pytest.approx((low, high))


def test_lanes_follow_the_timeline_when_linked(lanes, qtbot):
    from handmocap.widgets.timeline import TimelineWidget

    timeline = TimelineWidget()
    qtbot.addWidget(timeline)
    timeline.resize(900, 150)
    timeline.show()
    timeline.set_take(800, 11, 100.0, np.full(800, 5))
    lanes.set_lanes(["a", "b"], np.zeros((800, 2), dtype=np.int8), first_frame=11)
    lanes.link_x(timeline.plot.getPlotItem().vb)
    timeline.plot.setXRange(211, 411, padding=0)
    assert lanes.x_range() == pytest.approx((211, 411))
    assert lanes._image_key[:2] == (200, 401)              # the image is redrawn for the new range
    lanes.view_box.setXRange(311, 361, padding=0)          # the operator zooms the lanes
    assert timeline.plot.getPlotItem().vb.viewRange()[0] == pytest.approx([311, 361])
    assert lanes.x_range() == pytest.approx((311, 361))


def test_many_lanes_scroll_and_the_selected_lane_is_brought_into_view(lanes, qtbot):
    names = [f"marker_{i:02d}" for i in range(60)]
    lanes.set_lanes(names, np.zeros((300, 60), dtype=np.int8))
    qtbot.wait(20)
    first, last = lanes.visible_lanes()
    assert first == 0 and last < 59 and lanes.scroll_bar.isVisible()
    lanes.set_selected_marker(55)
    first, last = lanes.visible_lanes()
    assert first <= 55 <= last
    lanes.scroll_lanes(-100)
    assert lanes.visible_lanes()[0] == 0
    with pytest.raises(ValueError, match="states must be"):
        lanes.set_states(np.zeros((300, 3), dtype=np.int8))
    with pytest.raises(ValueError, match="unknown lane state"):
        lanes.set_states(np.full((300, 60), 9, dtype=np.int8))


def test_lanes_show_a_review_take_end_to_end(lanes, qtbot):
    take = smooth_take()
    positions = take.marker_positions.copy()
    positions[50:80, 2] = np.nan
    take = Take(take.marker_names, positions, take.frame_rate, first_frame=take.first_frame)
    review = ReviewTake.from_labelled_take(take)
    states = lanes_from_review(review.lane_states(), review.provenance)
    lanes.set_lanes(review.label_names, states, take.first_frame, take.frame_rate)
    assert lanes.stretch_at(2, 60) == (GAP, 50, 79)
    assert "1 unfilled gaps" in lanes.summary_label.text()


# --------------------------------------------------------------------------------------- review table
def stats(names, observed, gaps, longest, residual, confidence) -> MarkerStats:
    count = len(names)
    return MarkerStats(list(names), np.asarray(observed, float), np.zeros(count), np.asarray(gaps),
                       np.asarray(longest), np.asarray(residual, float), np.asarray(confidence, float),
                       np.zeros(count, dtype=np.int64))


@pytest.fixture
def table(qtbot):
    widget = ReviewTable()
    qtbot.addWidget(widget)
    widget.show()
    names = ["thumb_tip", "index_tip", "middle_tip", "ring_tip"]
    widget.set_markers(stats(names, [9.5, 100.0, 80.0, 45.25], [3, 0, 12, 2], [40, 0, 7, 120],
                             [1.2, np.nan, 10.5, 2.0], [0.4, 6.0, np.nan, 2.5]))
    return widget


def test_table_sorts_numerically_with_unknown_values_last(table):
    observed = TABLE_COLUMNS.index("Seen %")
    table.sort_by(observed)
    assert table.visible_rows() == [0, 3, 2, 1]          # 9.5 < 45.25 < 80 < 100 (text order would differ)
    table.sort_by(TABLE_COLUMNS.index("Longest\ngap"), descending=True)
    assert table.visible_rows() == [3, 0, 2, 1]
    table.sort_by(TABLE_COLUMNS.index("Off model\n(mm)"))
    assert table.visible_rows() == [0, 3, 2, 1]          # NaN after every number
    assert table.model.index(1, TABLE_COLUMNS.index("Off model\n(mm)")).data() == "—"
    assert table.model.index(0, observed).data() == "9.5"


def test_table_selection_signals_without_feedback(table, qtbot):
    received = []
    table.marker_selected.connect(received.append)
    table.select_marker(2)                                 # from outside: no signal
    assert received == [] and table.selected_marker() == 2
    proxy_row = table.proxy.mapFromSource(table.model.index(3, 0)).row()
    rect = table.table.visualRect(table.proxy.index(proxy_row, 1))
    qtbot.mouseClick(table.table.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())
    assert received == [3]
    table.filter_edit.setText("MID")
    assert table.visible_rows() == [2] and "1 of 4" in table.count_label.text()
    table.filter_edit.clear()
    table.update_stats(stats(table.model._names, [10, 20, 30, 40], [0, 0, 0, 0], [0, 0, 0, 0],
                             [1, 1, 1, 1], [5, 5, 5, 5]))
    assert table.selected_marker() == 3 and received == [3]
    assert table.model.index(0, 1).data() == "10.0"


def test_table_shows_core_review_statistics(qtbot):
    take = smooth_take(200, 4)
    positions = take.marker_positions.copy()
    positions[20:30, 1] = np.nan
    positions[60:100, 1] = np.nan
    review = ReviewTake.from_labelled_take(Take(take.marker_names, positions, 100.0))
    widget = ReviewTable()
    qtbot.addWidget(widget)
    widget.set_markers(review.marker_stats(), colours=np.full((4, 3), 0.5))
    assert widget.model.index(1, TABLE_COLUMNS.index("Gaps")).data() == "2"
    assert widget.model.index(1, TABLE_COLUMNS.index("Longest\ngap")).data() == "40"
    assert widget.model.index(1, TABLE_COLUMNS.index("Seen %")).data() == "75.0"


# ------------------------------------------------------------------------------------------- gap list
@pytest.fixture(scope="module")
def gap_take():
    take = smooth_take()
    positions = take.marker_positions.copy()
    positions[150:170, 1] = np.nan            # a 20-frame gap inside the take
    positions[0:12, 3] = np.nan               # a gap at the start: observed on one side only
    return Take(take.marker_names, positions, take.frame_rate, first_frame=take.first_frame)


@pytest.fixture(scope="module")
def checked_rows(gap_take):
    rows = []
    for gap in find_gaps(gap_take):
        if gap.open:
            rows.append(GapRow.from_gap(gap))
        else:
            rows.append(GapRow.from_gap(gap, check_gap(gap_take, gap, context=None)))
    return rows


@pytest.fixture
def gaps(qtbot, gap_take, checked_rows):
    widget = shown(qtbot, GapList(), 700, 650)
    widget.set_gaps(checked_rows, gap_take.marker_names, gap_take.first_frame)
    return widget


def select_row(qtbot, widget: GapList, index: int) -> None:
    proxy_row = widget.proxy.mapFromSource(widget.model.index(index, 0)).row()
    rect = widget.table.visualRect(widget.proxy.index(proxy_row, 2))
    qtbot.mouseClick(widget.table.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())


def test_gap_rows_match_core(checked_rows):
    inner = next(row for row in checked_rows if row.marker == 1)
    assert (inner.start, inner.length, inner.at_take_edge) == (150, 20, False)
    assert set(inner.errors_mm) == {"linear", "spline", "pattern", "rigid", "pca"}
    assert "model" in inner.reasons and inner.recommended in ("pattern", "rigid", "pca")
    edge = next(row for row in checked_rows if row.marker == 3)
    assert edge.at_take_edge and not edge.checked


def test_selecting_a_gap_shows_each_methods_check_error(gaps, checked_rows, qtbot):
    index = next(i for i, row in enumerate(checked_rows) if row.marker == 1)
    row = checked_rows[index]
    with qtbot.waitSignal(gaps.gap_selected, timeout=1000) as selected:
        select_row(qtbot, gaps, index)
    assert selected.args == [index]
    assert "frames 251–270" in gaps.detail_title.text()          # file numbering (first frame 101)
    for method, error in row.errors_mm.items():
        assert f"{error:.2f} mm" in gaps.error_labels[method].text()
    assert gaps.error_labels[row.recommended].text().startswith("★")
    assert gaps.error_labels["model"].text() == "n/a" and not gaps.method_buttons["model"].isEnabled()
    assert "hand model" in gaps.error_labels["model"].toolTip()
    assert gaps.chosen_method() == row.recommended
    with qtbot.waitSignal(gaps.accept_requested, timeout=1000) as accepted:
        qtbot.mouseClick(gaps.accept_button, Qt.MouseButton.LeftButton)
    assert accepted.args == [index, row.recommended, -1]


def test_pattern_donor_choice_preview_and_reject(gaps, checked_rows, qtbot):
    index = next(i for i, row in enumerate(checked_rows) if row.marker == 1)
    select_row(qtbot, gaps, index)
    qtbot.mouseClick(gaps.method_buttons["pattern"], Qt.MouseButton.LeftButton)
    assert gaps.donor_box.isEnabled()
    names = [gaps.donor_box.itemText(i) for i in range(gaps.donor_box.count())]
    assert names[0].startswith("Auto") and "m1" not in names and "m4" in names
    gaps.set_donor(4)
    with qtbot.waitSignal(gaps.preview_requested, timeout=1000) as preview:
        qtbot.mouseClick(gaps.preview_button, Qt.MouseButton.LeftButton)
    assert preview.args == [index, "pattern", 4]
    qtbot.mouseClick(gaps.method_buttons["spline"], Qt.MouseButton.LeftButton)
    assert not gaps.donor_box.isEnabled()
    with qtbot.waitSignal(gaps.preview_requested, timeout=1000) as preview:
        gaps.preview_button.click()
    assert preview.args == [index, "spline", AUTO_DONOR]
    with qtbot.waitSignal(gaps.reject_requested, timeout=1000) as rejected:
        gaps.reject_button.click()
    assert rejected.args == [index]
    gaps.update_gap(index, with_state(checked_rows[index], "filled", "spline"))
    assert gaps.model.index(index, GAP_COLUMNS.index("State")).data() == "filled (spline)"
    assert gaps.chosen_method() == "spline"


def test_gap_at_the_take_edge_cannot_be_filled(gaps, checked_rows, qtbot):
    index = next(i for i, row in enumerate(checked_rows) if row.marker == 3)
    select_row(qtbot, gaps, index)
    assert not gaps.accept_button.isEnabled() and not gaps.preview_button.isEnabled()
    assert gaps.reject_button.isEnabled()
    assert "one side" in gaps.detail_note.text()
    assert gaps.model.index(index, GAP_COLUMNS.index("Best fill")).data() == "cannot fill"


def test_fill_all_counts_sorting_and_filters(qtbot):
    widget = GapList()
    qtbot.addWidget(widget)
    rows = [GapRow(0, "a", 10, 5), GapRow(1, "b", 40, 120), GapRow(2, "c", 80, 30, state="rejected"),
            GapRow(0, "a", 200, 9, state="filled", method="model"), GapRow(2, "c", 0, 3, at_take_edge=True)]
    widget.set_gaps(rows, ["a", "b", "c"], first_frame=1)
    widget.max_length_box.setValue(20)
    assert widget.fill_all_candidates(20) == 1 and widget.fill_all_count.text() == "(1 open)"
    widget.max_length_box.setValue(200)
    assert widget.fill_all_count.text() == "(2 open)"
    with qtbot.waitSignal(widget.fill_all_requested, timeout=1000) as fill_all:
        widget.fill_all_button.click()
    assert fill_all.args == [200]
    widget.sort_by(GAP_COLUMNS.index("Frames"))
    assert widget.visible_rows() == [4, 0, 3, 2, 1]                  # 3 < 5 < 9 < 30 < 120, not text order
    widget.state_box.setCurrentIndex(widget.state_box.findText("Open"))
    assert sorted(widget.visible_rows()) == [0, 1, 4]
    widget.filter_edit.setText("b")
    assert widget.visible_rows() == [1]
    received = []
    widget.gap_selected.connect(received.append)
    widget.select_gap(1)
    assert received == [] and widget.selected_gap() == 1
    assert widget.chosen_method() == "model"        # unchecked gap: the first method, all enabled
    widget.update_gap(1, with_state(rows[1], "filled", "linear"))      # leaves the "Open" filter
    assert widget.visible_rows() == [] and received == [] and widget.selected_gap() == 1
    assert "filled (linear)" in widget.detail_title.text()


def test_gap_rows_of_a_review_show_filled_open_and_rejected_gaps(gap_take):
    positions = gap_take.marker_positions.copy()
    positions[300:305, 0] = np.nan
    take = Take(gap_take.marker_names, positions, 100.0, first_frame=gap_take.first_frame)
    provenance = np.where(take.missing_mask, -1, 0).astype(np.int8)
    provenance[150:170, 1] = fill_codes()["model"]            # the 20-frame gap was filled
    review = ReviewTake.from_labelled_take(take)
    gaps = find_gaps(review.labelled_take(include_fills=False))
    index = {gap.marker: i for i, gap in enumerate(gaps)}
    rows = gap_rows(gaps, provenance, checks={index[0]: "needs 35 consecutive observed frames"},
                    rejected={index[3]})
    assert rows[index[1]].state_text() == "filled (model)"
    assert rows[index[3]].state == "rejected" and rows[index[3]].at_take_edge
    assert rows[index[0]].state == "open" and rows[index[0]].check_error.startswith("needs")
    assert rows[index[0]].applicable("spline")                # the check failed: the fill itself will tell


# ---------------------------------------------------------------------------------------- fill preview
def test_fill_preview_draws_each_candidate_through_the_gap(qtbot, gap_take):
    widget = shown(qtbot, FillPreview(), 600, 400)
    start, length = 150, 20
    candidates = {method: fill_gap(gap_take.marker_positions, 1, start, length, method)
                  for method in ("linear", "spline", "pattern", "rigid")}
    widget.show_gap(gap_take.marker_positions[:, 1], start, length, candidates, "spline",
                    {"linear": 3.2, "spline": 0.4}, gap_take.first_frame, "m1")
    assert widget.methods() == ["linear", "spline", "pattern", "rigid"]
    assert widget.selected() == "spline"
    frames, values = widget.curve_data("spline", 2)
    assert frames[0] == gap_take.first_frame + start - 1 and frames[-1] == gap_take.first_frame + start + length
    assert values[0] == pytest.approx(gap_take.marker_positions[start - 1, 1, 2])      # joins the samples
    np.testing.assert_allclose(values[1:-1], candidates["spline"][:, 2])
    assert widget._curves["spline"][0].opts["pen"].widthF() > widget._curves["linear"][0].opts["pen"].widthF()
    low, high = widget.frame_window()
    assert low < start and high > start + length
    assert "0.40&nbsp;mm" in widget.legend_label.text() and "frames 251–270" in widget.title_label.text()
    widget.set_selected("rigid")
    assert widget._curves["rigid"][1].opts["pen"].widthF() > widget._curves["spline"][1].opts["pen"].widthF()
    widget.clear()
    assert widget.methods() == [] and widget.selected() is None
    with pytest.raises(ValueError, match="outside"):
        widget.show_gap(gap_take.marker_positions[:, 1], 390, 20)


# -------------------------------------------------------------------------------------- session browser
@pytest.fixture
def browser(qtbot):
    widget = shown(qtbot, SessionBrowser(), 600, 300)
    widget.set_takes([
        TakeRow("t1", "grasp_01.c3d", "reviewed", "S01", "dense", 12000),
        TakeRow("t2", "grasp_02.c3d", "raw", "S01", "dense", 900),
        TakeRow("t3", "typing.tsv", "exported", "S02", "glove-13", 3000),
        TakeRow("t4", "wand.c3d", "labelled", None, None, 0),
    ])
    return widget


def test_session_browser_sorts_filters_and_groups(browser):
    browser.tree.sortByColumn(4, Qt.SortOrder.AscendingOrder)
    assert browser.visible_takes() == ["t4", "t2", "t3", "t1"]            # 0 < 900 < 3000 < 12000
    browser.tree.sortByColumn(1, Qt.SortOrder.AscendingOrder)
    assert browser.visible_takes() == ["t2", "t4", "t1", "t3"]            # raw → labelled → reviewed → exported
    browser.filter_edit.setText("s01")
    assert sorted(browser.visible_takes()) == ["t1", "t2"]
    browser.filter_edit.clear()
    browser.state_box.setCurrentIndex(browser.state_box.findData("exported"))
    assert browser.visible_takes() == ["t3"] and "1 of 4 takes" in browser.summary_label.text()
    browser.state_box.setCurrentIndex(0)
    browser.group_box.setChecked(True)
    assert browser.tree.topLevelItemCount() == 3                         # S01, S02, (no subject)
    assert sorted(browser.visible_takes()) == ["t1", "t2", "t3", "t4"]


def test_session_browser_open_add_and_state_requests(browser, qtbot, monkeypatch, tmp_path):
    browser.set_current("t2")
    item = browser._item("t2")
    assert item.font(0).bold()
    with qtbot.waitSignal(browser.open_requested, timeout=1000) as opened:
        rect = browser.tree.visualItemRect(item)
        qtbot.mouseClick(browser.tree.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())
        qtbot.mouseDClick(browser.tree.viewport(), Qt.MouseButton.LeftButton, pos=rect.center())
    assert opened.args == ["t2"]

    monkeypatch.setattr(QFileDialog, "getOpenFileNames", lambda *args, **kwargs: (["/x/a.c3d", "/x/b.tsv"], ""))
    with qtbot.waitSignal(browser.add_requested, timeout=1000) as added:
        browser.add_action.trigger()
    assert added.args == [["/x/a.c3d", "/x/b.tsv"]]

    mime = QMimeData()
    mime.setUrls([QUrl.fromLocalFile(str(tmp_path / "new.trc")), QUrl.fromLocalFile(str(tmp_path / "notes.txt"))])
    drop = QDropEvent(QPointF(10, 10), Qt.DropAction.CopyAction, mime, Qt.MouseButton.LeftButton,
                      Qt.KeyboardModifier.NoModifier)
    with qtbot.waitSignal(browser.add_requested, timeout=1000) as dropped:
        browser.dropEvent(drop)
    assert dropped.args == [[str(tmp_path / "new.trc")]]

    menu = browser.state_menu("t2")
    state_menu = next(a.menu() for a in menu.actions() if a.menu() is not None)
    actions = {a.text(): a for a in state_menu.actions()}
    assert actions["Raw"].isChecked() and not actions["Reviewed"].isChecked()
    with qtbot.waitSignal(browser.state_change_requested, timeout=1000) as changed:
        actions["Reviewed"].trigger()
    assert changed.args == ["t2", "reviewed"]

    received = []
    browser.take_selected.connect(received.append)
    browser.select_take("t3")
    assert received == [] and browser.selected_take() == "t3"
    browser.tree.setFocus()
    with qtbot.waitSignal(browser.remove_requested, timeout=1000) as removed:
        qtbot.keyClick(browser.tree, Qt.Key.Key_Delete)
    assert removed.args == ["t3"]
    browser.update_take(TakeRow("t3", "typing.tsv", "reviewed", "S02", "glove-13", 3000))
    assert browser.selected_take() == "t3" and browser._item("t3").text(1) == "reviewed"
    browser.set_takes([])
    assert browser.stack.currentWidget() is browser.empty_label
    with pytest.raises(ValueError, match="unknown state"):
        browser.set_takes([TakeRow("x", "x.c3d", "done")])
