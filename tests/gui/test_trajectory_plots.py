"""Trajectory plots driven like an operator: View ▸ Plots, select and pin labels, click a frame, drag a range;
the plots follow edits, show gaps and fills in their provenance colours and mark spikes and swap suspects."""

import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, Qt

from handmocap.app.gui.document import TakeDocument
from handmocap.core.gaps import fill_method
from handmocap.core.io import Take
from handmocap.core.review import AcceptFills, GapFill, Unlabel
from handmocap.core.simulate import simulate_take
from handmocap.widgets.marker_lanes import GAP_COLOUR
from handmocap.widgets.trajectory_plots import acceleration_spikes, kinematics

pytestmark = pytest.mark.gui

FRAMES = 300
SPIKE_FRAME, SPIKE_LABEL = 140, 2
SWAP = (200, 215)            # frames where labels 6 and 7 swap points


@pytest.fixture
def document():
    """A labelled take with a 6 mm one-frame spike on label 2 and labels 6 and 7 swapped for 15 frames."""
    take = simulate_take(layout="dense", n_frames=FRAMES, seed=3, noise_mm=0.2).take
    positions = take.marker_positions.copy()
    positions[SPIKE_FRAME, SPIKE_LABEL, 2] += 6.0
    positions[SWAP[0]:SWAP[1], [6, 7]] = positions[SWAP[0]:SWAP[1], [7, 6]]
    return TakeDocument(Take(take.marker_names, positions, take.frame_rate, first_frame=take.first_frame), "plots")


@pytest.fixture
def shown(window, qtbot, document):
    window.add_document(document)
    window.plots_dock.toggleViewAction().trigger()              # View ▸ Plots
    qtbot.waitUntil(window.plots.plots.isVisible, timeout=2_000)
    window.resizeDocks([window.plots_dock], [420], Qt.Orientation.Vertical)
    return window


def canvas_point(plots, key, frame_number, value=None):
    """Canvas pixel of (file frame number, value) in the plot of ``key`` (value: the middle of the view)."""
    box = plots.plots[key].getViewBox()
    if value is None:
        value = float(np.mean(box.viewRange()[1]))
    scene = box.mapViewToScene(QPointF(frame_number, value))
    point = plots.canvas.mapFromScene(scene)
    return QPoint(point.x(), point.y())


def test_kinematics_in_mm_per_second_and_spikes_from_the_labels_own_data():
    rate = 200.0
    time = np.arange(400) / rate
    positions = np.stack([30.0 * time, 5.0 * time**2, np.zeros_like(time)], axis=1)   # mm: 30 mm/s; 10 mm/s²
    speed, acceleration = kinematics(positions, rate)
    assert np.isnan(speed[0]) and np.isnan(acceleration[-1])
    np.testing.assert_allclose(speed[1:-1], np.hypot(30.0, 10.0 * time[1:-1]), rtol=1e-6)
    np.testing.assert_allclose(acceleration[1:-1], 10.0, rtol=1e-6)
    noisy = positions + np.random.default_rng(1).normal(scale=0.2, size=positions.shape)
    assert len(acceleration_spikes(kinematics(noisy, rate)[1])[0]) == 0           # noise alone: no spike
    noisy[250, 0] += 4.0
    spikes, threshold = acceleration_spikes(kinematics(noisy, rate)[1])
    assert spikes.tolist() == [250] and threshold > 0                              # one mark, at its peak


def test_selected_and_pinned_labels_overlay_with_their_colours(shown):
    window = shown
    plots, review = window.plots.plots, window.document.review
    assert plots.traces == []
    window.review.select_label(SPIKE_LABEL)
    assert [trace.name for trace in plots.traces] == [review.label_names[SPIKE_LABEL]]
    trace = plots.traces[0]
    np.testing.assert_allclose(trace.positions, review.labelled_positions()[:, SPIKE_LABEL])
    assert SPIKE_FRAME in trace.spikes.tolist()                    # the injected spike is marked
    assert all(abs(int(spike) - SPIKE_FRAME) > 1 or spike == SPIKE_FRAME for spike in trace.spikes)
    for key, unit in (("x", "mm"), ("speed", "mm/s"), ("acceleration", "mm/s²")):
        assert unit in plots.plots[key].getAxis("left").labelString()
    plots.pin_button.click()
    window.review.select_label(6)
    assert [trace.name for trace in plots.traces] == [review.label_names[SPIKE_LABEL], review.label_names[6]]
    assert plots.traces[0].colour != plots.traces[1].colour
    assert any(start <= SWAP[0] + 1 and stop >= SWAP[0] for start, stop in plots.traces[1].swaps)  # swap suspect
    window.app.clear_selection()
    assert [trace.name for trace in plots.traces] == [review.label_names[SPIKE_LABEL]]   # the pin stays
    plots.clear_button.click()
    assert plots.traces == []


def test_click_jumps_to_the_frame_and_the_cursor_follows_the_timeline(shown, qtbot):
    window = shown
    plots, first = window.plots.plots, window.document.take.first_frame
    window.review.select_label(3)
    qtbot.mouseClick(plots.canvas.viewport(), Qt.MouseButton.LeftButton, pos=canvas_point(plots, "y", first + 120))
    assert abs(window.app.frame - 120) <= 1
    assert window.timeline.frame == window.app.frame
    window.timeline.set_frame(42)
    assert all(cursor.value() == first + 42 for cursor in plots.cursors.values())


def test_dragging_a_range_sets_the_io_range(shown, qtbot):
    window = shown
    plots, first = window.plots.plots, window.document.take.first_frame
    window.review.select_label(3)
    viewport = plots.canvas.viewport()
    start, end = canvas_point(plots, "z", first + 60), canvas_point(plots, "z", first + 180)
    qtbot.mousePress(viewport, Qt.MouseButton.LeftButton, pos=start)
    for step in range(1, 11):
        qtbot.mouseMove(viewport, start + (end - start) * step / 10)
    qtbot.mouseRelease(viewport, Qt.MouseButton.LeftButton, pos=end)
    selection = window.app.selection
    assert abs(selection.range_in - 60) <= 1 and abs(selection.range_out - 180) <= 1
    shown_range = f"range {first + selection.range_in}–{first + selection.range_out}"
    assert window.review.range_label.text().strip() == shown_range
    low, high = plots.regions["x"].getRegion()
    assert low == pytest.approx(first + selection.range_in - 0.5) and plots.regions["x"].isVisible()
    window.review.clear_range()                                   # the I/O range cleared elsewhere: region hides
    assert not plots.regions["x"].isVisible()


def test_plots_follow_edits_gaps_and_fills_in_provenance_colours(shown):
    window = shown
    document, plots = window.document, window.plots.plots
    name = document.review.label_names[4]
    window.review.select_label(4)
    document.push(Unlabel(label=name, scope="range", start=100, stop=130))
    trace = plots.traces[0]
    assert np.isnan(trace.positions[100:130]).all() and trace.gaps == [(100, 130)]
    bands = [item for _, item in plots._items if type(item).__name__ == "BarGraphItem"]
    assert any(item.opts["brush"].color().getRgb()[:3] == GAP_COLOUR for item in bands)
    column = int(document.review.assignment[99, 4])
    values = np.linspace(document.take.marker_positions[99, column], document.take.marker_positions[130, column], 32)
    document.push(AcceptFills([GapFill(name, 100, "linear", values[1:-1])]))
    trace = plots.traces[0]
    assert trace.gaps == [] and trace.fills == {"linear": [(100, 130)]}
    assert np.isfinite(trace.positions[100:130]).all()
    pens = [item.opts["pen"].color().getRgb()[:3] for _, item in plots._items if hasattr(item, "opts")
            and "pen" in item.opts and not isinstance(item.opts["pen"], str)]
    assert fill_method("linear").colour in pens
    document.undo()
    assert plots.traces[0].gaps == [(100, 130)]


def test_hidden_plots_compute_nothing_until_shown(shown, qtbot):
    window = shown
    window.review.select_label(1)
    window.plots_dock.toggleViewAction().trigger()               # hide
    qtbot.waitUntil(lambda: not window.plots.plots.isVisible(), timeout=2_000)
    window.review.select_label(5)
    assert [trace.name for trace in window.plots.plots.traces] == [window.document.review.label_names[1]]
    window.plots_dock.toggleViewAction().trigger()
    qtbot.waitUntil(window.plots.plots.isVisible, timeout=2_000)
    assert [trace.name for trace in window.plots.plots.traces] == [window.document.review.label_names[5]]
