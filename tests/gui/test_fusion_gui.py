"""Solve ▸ Fuse with RGB-D in the review (issue 15 item 5): on a small synthetic take with a registered RGB-D
camera the fusion runs on a worker and becomes one undoable, journalled step (undo restores the IK solve, redo
the fusion), Cancel stops it without changing anything, the energy strip under the video shows the terms of
the RGB-D frames, and the silhouette of the solved hand is outlined over the video where the hand is."""

import json

import numpy as np
import pytest

from handmocap.core.camera.files import save_camera
from handmocap.core.camera.writers import write_depth_frames, write_video
from handmocap.core.fusion import FusionSettings
from handmocap.core.fusion.icp import ICPSettings
from handmocap.core.io import save_take
from handmocap.core.review import command_from_json
from handmocap.core.session import Session
from handmocap.core.session.cameras import add_camera
from handmocap.core.simulate.camera import random_camera, simulate_camera_take

pytestmark = pytest.mark.gui

#: the fast optimiser with few ICP iterations and a small crop (as tests/fusion/test_fusion_track.py)
FAST = FusionSettings(icp=ICPSettings(iterations=4, depth_points=200), max_side=64)
OFFSET_S = 0.1


@pytest.fixture(scope="module")
def filmed(tmp_path_factory):
    """A labelled simulated take (60 frames at 100 Hz), its RGB-D camera's 30 Hz video and depth frames
    (about 16) and the registered camera."""
    folder = tmp_path_factory.mktemp("rgbd")
    simulated = simulate_camera_take(seed=11, n_frames=60, mocap_rate=100.0, offset_s=OFFSET_S,
                                     camera=random_camera(11, distance=450.0))
    save_take(simulated.simulated.take, folder / "take.c3d")
    rendered = [simulated.render(k) for k in range(len(simulated.camera_times))]
    write_video(folder / "video.avi", (colour for colour, _ in rendered), simulated.frame_rate, simulated.camera.size)
    (folder / "depth").mkdir()
    write_depth_frames(folder / "depth", (depth for _, depth in rendered), 1.0)
    save_camera(simulated.camera, folder / "camera.json")
    return folder, simulated


def session_with_camera(filmed, folder, depth=True):
    files, simulated = filmed
    session = Session.create(folder)
    entry = session.add_take(files / "take.c3d", layout="dense")
    add_camera(session, entry.id, simulated.camera, files / "video.avi", files / "depth" if depth else None,
               1.0 if depth else None)
    session.close()
    return folder


def open_solved(window, qtbot, folder):
    """Open the session's take and solve it with IK (the solve the fusion replaces)."""
    assert window.sessions.open_session(folder)
    window.sessions.open_take(window.sessions.session.takes[0].id)
    qtbot.waitUntil(lambda: not window.loader.is_busy() and window.document is not None, timeout=30_000)
    window.fusion.settings = FAST
    window.solver.solve()
    qtbot.waitUntil(lambda: not window.is_busy() and window.document.has_solved_hands(), timeout=60_000)
    return window.document


def test_fusion_is_an_undoable_step_with_energy_strip_and_silhouette(window, qtbot, filmed, tmp_path):
    files, simulated = filmed
    document = open_solved(window, qtbot, session_with_camera(filmed, tmp_path / "session"))
    fusion, cameras = window.fusion, window.cameras
    assert fusion.fuse_action in window.solve_menu.actions() and fusion.fuse_action.isEnabled()
    assert not cameras.view.energy_strip.isVisible()
    solved = document.review.hands[0].joint_angles.copy()
    steps = document.stack.index

    fusion.fuse_action.trigger()
    assert window.app.is_busy() and not fusion.fuse_action.isEnabled()
    qtbot.waitUntil(lambda: not window.is_busy(), timeout=120_000)
    assert not window.messages
    fused = document.review.hands[0].joint_angles.copy()
    assert document.stack.index == steps + 1 and "RGB-D fusion" in document.stack.undo_text()
    assert np.isfinite(fused).all() and np.abs(fused - solved).max() > 1e-3
    # journalled like the others: the step is plain JSON and reads back with the fused angles
    command = document.stack.commands[-1]
    again = command_from_json(json.loads(json.dumps(command.to_json())))
    np.testing.assert_allclose(again.children[-1].joint_angles, fused)

    # the energy strip: one value per term at each fused RGB-D frame, shown under the video
    strip = cameras.view.energy_strip
    result = fusion.fused_result(document)
    assert strip.isVisible() and len(strip.frames) == len(result.rgbd_frames) >= 10
    assert np.isfinite(strip.values).all() and (strip.values[:, strip.shown_terms()] > 0).any(axis=0).all()
    frame = int(round(result.rgbd_mocap_frames[3]))
    window.timeline.set_frame(frame)
    qtbot.waitUntil(lambda: cameras._shown_key is not None and cameras._shown_key[3] == frame, timeout=5000)
    assert strip.frame == frame and strip.values_at(frame)["depth"] == pytest.approx(result.energy_terms[3, 2])

    # the silhouette outline surrounds the hand's markers as the camera sees them
    assert cameras.view.silhouette_box.isChecked()
    outlines = cameras.view.canvas.outlines
    assert outlines and sum(len(outline) for outline in outlines) > 20
    points = np.concatenate(outlines)
    low, high = points.min(axis=0), points.max(axis=0)
    markers = cameras.view.canvas._pixels
    markers = markers[np.isfinite(markers).all(axis=1)]
    inside = ((markers >= low - 10) & (markers <= high + 10)).all(axis=1)
    assert inside.mean() > 0.9
    cameras.view.silhouette_box.setChecked(False)
    qtbot.waitUntil(lambda: cameras._shown_key is not None and not cameras._shown_key[-1], timeout=5000)
    assert cameras.view.canvas.outlines == []

    # undo restores the IK solve and hides the strip; redo brings the fusion back
    window.review.undo()
    np.testing.assert_array_equal(document.review.hands[0].joint_angles, solved)
    assert not strip.isVisible()
    window.review.redo()
    np.testing.assert_array_equal(document.review.hands[0].joint_angles, fused)
    assert strip.isVisible()


def test_cancel_stops_the_fusion_and_changes_nothing(window, qtbot, filmed, tmp_path):
    document = open_solved(window, qtbot, session_with_camera(filmed, tmp_path / "session"))
    solved = document.review.hands[0].joint_angles.copy()
    steps, version = document.stack.index, document.review.version
    window.fusion.fuse_action.trigger()
    window.cancel_work()
    qtbot.waitUntil(lambda: not window.is_busy(), timeout=60_000)
    assert "cancelled" in window.statusBar().currentMessage() and not window.messages
    np.testing.assert_array_equal(document.review.hands[0].joint_angles, solved)
    assert document.stack.index == steps and document.review.version == version
    assert not window.cameras.view.energy_strip.isVisible() and window.fusion.fuse_action.isEnabled()


def test_fusion_needs_depth_frames(window, qtbot, filmed, tmp_path):
    open_solved(window, qtbot, session_with_camera(filmed, tmp_path / "session", depth=False))
    assert not window.fusion.fuse_action.isEnabled()
    assert "RGB-D camera" in window.fusion.unavailable()
    window.fusion.fuse()
    assert window.messages and "RGB-D camera" in window.messages[-1] and not window.is_busy()


def test_demo_camera_is_an_rgbd_camera(tmp_path):
    from handmocap.app.gui.demo import _add_camera_take
    from handmocap.core.camera.frames import open_frames
    from handmocap.core.session.cameras import take_cameras

    session = Session.create(tmp_path / "demo")
    (tmp_path / "demo" / "files").mkdir()
    _add_camera_take(session, tmp_path / "demo" / "files")
    [camera] = take_cameras(session, session.takes[0].id)
    session.close()
    assert camera.camera.registered and camera.depth_unit_mm == 1.0 and session.folder in camera.depth.parents
    with open_frames(camera.media) as video, open_frames(camera.depth, depth_unit_mm=1.0) as depth:
        assert len(depth) == len(video) and depth.size == video.size
        hand = depth.frame(len(depth) // 2)
        assert 200.0 < np.median(hand[hand > 0]) < 2000.0     # mm: the scene ~0.45 m from the camera
