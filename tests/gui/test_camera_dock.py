"""The camera in the review (issue 14 item 5): the dock shows the camera frame at the timeline's time with the
markers over it, a click on a marker selects it, the sync nudges move the shown frame and are saved with
the camera, File ▸ Add camera… keeps the camera in the session, and the calibration wizard calibrates on
a worker and can be cancelled."""

import cv2
import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from handmocap.core.camera.files import save_camera
from handmocap.core.camera.frames import VideoFrames
from handmocap.core.camera.intrinsics import BoardSpec
from handmocap.core.camera.writers import write_video
from handmocap.core.io import save_take
from handmocap.core.session import Session
from handmocap.core.session.cameras import add_camera, take_cameras
from handmocap.core.simulate.camera import board_views, random_camera, simulate_camera_take

pytestmark = pytest.mark.gui

OFFSET_S = 0.1


@pytest.fixture(scope="module")
def filmed(tmp_path_factory):
    """A labelled simulated take (150 frames at 100 Hz), its camera's 30 Hz video and camera file."""
    folder = tmp_path_factory.mktemp("filmed")
    simulated = simulate_camera_take(seed=11, n_frames=150, mocap_rate=100.0, offset_s=OFFSET_S,
                                     camera=random_camera(11, distance=450.0))
    save_take(simulated.simulated.take, folder / "take.c3d")
    write_video(folder / "video.avi", (simulated.render(k, with_depth=False)[0]
                                       for k in range(len(simulated.camera_times))),
                simulated.frame_rate, simulated.camera.size)
    save_camera(simulated.camera, folder / "camera.json")
    return folder, simulated


def open_session_take(window, qtbot, folder):
    assert window.sessions.open_session(folder)
    window.sessions.open_take(window.sessions.session.takes[0].id)
    qtbot.waitUntil(lambda: not window.loader.is_busy() and window.document is not None, timeout=30_000)


def run_step(wizard, qtbot, start):
    """Start a step of the camera wizard (``start``) and wait until its worker is done."""
    start()
    qtbot.waitUntil(lambda: not wizard.runner.is_busy(), timeout=120_000)


def registered_camera(wizard, qtbot):
    """The camera the wizard's registration step gives (it must be registered)."""
    run_step(wizard, qtbot, wizard.start_registration)
    assert wizard.camera.registered, wizard.status_label.text()
    return wizard.camera


def session_with_camera(filmed, folder, with_camera=True):
    files, simulated = filmed
    session = Session.create(folder)
    entry = session.add_take(files / "take.c3d", layout="dense")
    if with_camera:
        add_camera(session, entry.id, simulated.camera, files / "video.avi")
    session.close()
    return folder


def test_dock_shows_the_camera_frame_at_the_timeline_time(window, qtbot, filmed, tmp_path):
    files, simulated = filmed
    open_session_take(window, qtbot, session_with_camera(filmed, tmp_path / "session"))
    controller = window.cameras
    assert window.camera_dock.isVisible() and [c.name for c in controller.cameras] == [simulated.camera.name]
    window.timeline.set_frame(90)
    qtbot.waitUntil(lambda: controller._shown_key is not None and controller._shown_key[3] == 90, timeout=5000)
    expected = int(round((90 / 100.0 - OFFSET_S) * 30.0))
    assert controller._shown_key[2] == expected
    with VideoFrames(files / "video.avi") as video:
        np.testing.assert_array_equal(controller.view.canvas._image.array, video.frame(expected))
    # the markers drawn are the take's at that camera frame's time, where the video shows them
    pixels = controller.view.canvas._pixels
    mocap = simulated.camera.clock.mocap_frame(expected / 30.0, 100.0)
    truth = simulated.camera.project(simulated.pose_at(mocap / 100.0)[1])
    assert np.nanmedian(np.linalg.norm(pixels - truth, axis=1)) < 2.0
    assert controller.view.canvas.paint_count > 0
    # the camera is drawn as a frustum in the 3D view
    view = window.viewport.view()
    assert view._frustum_actor.visibility and view._frustum_lines.GetNumberOfCells() == 8


def test_clicking_a_marker_in_the_video_selects_it(window, qtbot, filmed, tmp_path):
    open_session_take(window, qtbot, session_with_camera(filmed, tmp_path / "session"))
    controller, canvas = window.cameras, window.cameras.view.canvas
    window.camera_dock.resize(700, 560)
    window.timeline.set_frame(60)
    qtbot.waitUntil(lambda: controller._shown_key is not None and controller._shown_key[3] == 60, timeout=5000)
    pixels = canvas._pixels
    visible = np.flatnonzero(np.isfinite(pixels).all(axis=1))
    # the point furthest from every other one: a click on it is unambiguous
    distances = np.linalg.norm(pixels[visible, None] - pixels[None, visible], axis=2) + np.eye(len(visible)) * 1e9
    column = int(visible[np.argmax(distances.min(axis=1))])
    where = canvas.widget_point(pixels[column])
    qtbot.mouseClick(canvas, Qt.MouseButton.LeftButton, pos=QPoint(round(where.x()), round(where.y())))
    assert window.app.selection.column == column
    assert window.app.selection.label == window.document.review.label_of_point(60, column) >= 0
    qtbot.waitUntil(lambda: controller._shown_key[4] == column, timeout=5000)
    assert canvas._selected == column
    qtbot.mouseClick(canvas, Qt.MouseButton.LeftButton, pos=QPoint(2, 2))     # far from every marker
    assert window.app.selection.column == -1


def test_nudging_the_offset_moves_the_shown_frame_and_is_saved(window, qtbot, filmed, tmp_path):
    folder = session_with_camera(filmed, tmp_path / "session")
    open_session_take(window, qtbot, folder)
    controller = window.cameras
    window.timeline.set_frame(100)
    qtbot.waitUntil(lambda: controller._shown_key is not None and controller._shown_key[3] == 100, timeout=5000)
    before = controller._shown_key[2]
    qtbot.mouseClick(controller.view.nudge_buttons[(1, 0)], Qt.MouseButton.LeftButton)    # + one camera frame
    assert controller._shown_key[2] == before - 1
    for _ in range(3):
        qtbot.mouseClick(controller.view.nudge_buttons[(0, -1)], Qt.MouseButton.LeftButton)  # − three mocap frames
    assert controller._shown_key[2] == before - 1 + 1     # 1/30 − 3/100 s: back to the first frame
    offset = controller.camera.camera.clock.offset_s
    assert offset == pytest.approx(OFFSET_S + 1 / 30 - 3 / 100)
    assert take_cameras(Session.open(folder, read_only=True), "t0001")[0].camera.clock.offset_s == pytest.approx(offset)


def test_add_camera_stores_it_in_the_session_and_reopening_restores_it(window, qtbot, filmed, tmp_path):
    files, simulated = filmed
    folder = session_with_camera(filmed, tmp_path / "session", with_camera=False)
    open_session_take(window, qtbot, folder)
    controller = window.cameras
    assert controller.cameras == [] and not window.camera_dock.isVisible()
    assert not controller.add(str(files / "video.avi"), None, None, str(tmp_path / "missing.json"))
    assert window.messages and "missing.json" in window.messages[-1]
    assert controller.add(str(files / "video.avi"), None, None, str(files / "camera.json"))
    assert window.camera_dock.isVisible() and controller.camera is not None
    stored = take_cameras(Session.open(folder, read_only=True), "t0001")
    assert [c.name for c in stored] == [simulated.camera.name] and stored[0].media == files / "video.avi"
    # reopening the session shows it again
    window.sessions.close_session()
    open_session_take(window, qtbot, folder)
    assert [c.name for c in window.cameras.cameras] == [simulated.camera.name]
    np.testing.assert_allclose(window.cameras.camera.camera.matrix, simulated.camera.matrix)


@pytest.fixture(scope="module")
def board_images(tmp_path_factory):
    folder = tmp_path_factory.mktemp("boards")
    camera = random_camera(21)
    paths = []
    for index, image in enumerate(board_views(camera, BoardSpec(), 10, seed=21).images):
        path = folder / f"board_{index:02d}.png"
        cv2.imwrite(str(path), image)
        paths.append(path)
    return camera, paths


def test_wizard_calibrates_intrinsics_on_a_worker_and_can_be_cancelled(window, qtbot, board_images, tmp_path):
    from handmocap.app.gui.camera_wizard import CameraWizard

    truth, paths = board_images
    wizard = CameraWizard(window, window.cameras)
    qtbot.addWidget(wizard)
    wizard.show()
    wizard.set_images(paths)
    wizard.start_intrinsics()
    assert wizard.runner.is_busy() and wizard.cancel_button.isEnabled()
    wizard.cancel_button.click()
    qtbot.waitUntil(lambda: not wizard.runner.is_busy(), timeout=30_000)
    assert "cancelled" in wizard.status_label.text() and wizard.camera is None
    run_step(wizard, qtbot, wizard.start_intrinsics)
    assert "intrinsics from" in wizard.status_label.text(), wizard.status_label.text()
    assert abs(wizard.camera.focal[0] / truth.focal[0] - 1) < 0.005
    assert wizard.views_table.rowCount() == len(paths) and "Coverage" in wizard.coverage_label.text()
    cells = [wizard.views_table.item(row, column).text() for row in range(len(paths)) for column in range(4)]
    assert not [cell for cell in cells if "nan" in cell.lower()], cells     # a left-out view shows its error
    assert wizard.progress_bar.value() == 100                               # done: the bar is full, not back at 0
    assert wizard.save(tmp_path / "calibrated.json")
    from handmocap.core.camera.files import load_camera

    np.testing.assert_allclose(load_camera(tmp_path / "calibrated.json").matrix, wizard.camera.matrix)
    wizard.close()


def test_playback_keeps_the_video_in_step_with_the_take(window, qtbot, filmed, tmp_path):
    open_session_take(window, qtbot, session_with_camera(filmed, tmp_path / "session"))
    controller = window.cameras
    draws = []
    controller.view.canvas.set_content = (lambda original: lambda *args, **kwargs: (
        draws.append(window.app.frame), original(*args, **kwargs))[1])(controller.view.canvas.set_content)
    window.timeline.set_frame(0)
    frames_shown = []
    window.timeline.frame_changed.connect(frames_shown.append)
    window.timeline.play()   # real time, looping: on a loaded machine frames (and draws) are skipped, so wait
    qtbot.waitUntil(lambda: len(frames_shown) >= 60 and len(draws) >= 5, timeout=60_000)
    window.timeline.pause()
    qtbot.waitUntil(lambda: controller._shown_key is not None and controller._shown_key[3] == window.app.frame,
                    timeout=5000)
    assert controller._shown_key[2] == controller.camera_frame_at(window.app.frame)
    # the video followed (a new camera frame every few mocap frames), never more draws than frames shown
    assert len(draws) <= len(frames_shown) + 1


def test_rgbd_camera_toggles_between_colour_and_depth(window, qtbot, filmed, tmp_path):
    from handmocap.core.camera.writers import write_depth_frames

    files, simulated = filmed
    depth = tmp_path / "depth"
    depth.mkdir()
    write_depth_frames(depth, (simulated.render(k)[1] for k in range(6)), 1.0)
    folder = session_with_camera(filmed, tmp_path / "session", with_camera=False)
    session = Session.open(folder)
    add_camera(session, "t0001", simulated.camera, files / "video.avi", depth=depth, depth_unit_mm=1.0)
    session.close()
    open_session_take(window, qtbot, folder)
    controller = window.cameras
    window.timeline.set_frame(12)       # camera time 0.02 s: camera frame 1
    qtbot.waitUntil(lambda: controller._shown_key is not None and controller._shown_key[3] == 12, timeout=5000)
    assert controller.view.stream_box.isEnabled() and controller.view.canvas._image.array.ndim == 3
    controller.view.stream_box.setCurrentText("depth")
    qtbot.waitUntil(lambda: controller._shown_key[1] == "depth", timeout=5000)
    grey = controller.view.canvas._image.array
    assert grey.ndim == 2 and grey.dtype == np.uint8
    assert ((grey > 0) == (simulated.render(1)[1] > 0)).mean() > 0.95     # no depth is black
    assert np.isfinite(controller.view.canvas._pixels).any()                # the markers are drawn on depth too


def test_wizard_estimates_the_offset_of_a_registered_camera(window, qtbot, filmed, tmp_path):
    from handmocap.app.gui.camera_wizard import CameraWizard
    from handmocap.core.camera.model import CameraClock

    files, simulated = filmed
    folder = session_with_camera(filmed, tmp_path / "session", with_camera=False)
    session = Session.open(folder)
    add_camera(session, "t0001", simulated.camera.with_clock(CameraClock(OFFSET_S + 0.08)), files / "video.avi")
    session.close()
    open_session_take(window, qtbot, folder)
    wizard = CameraWizard(window, window.cameras)
    qtbot.addWidget(wizard)
    run_step(wizard, qtbot, wizard.start_offset)
    assert abs(wizard.camera.clock.offset_s - OFFSET_S) < 0.01, wizard.status_label.text()
    assert wizard.save()
    assert window.cameras.camera.camera.clock.offset_s == wizard.camera.clock.offset_s
    assert abs(take_cameras(Session.open(folder, read_only=True), "t0001")[0].camera.clock.offset_s - OFFSET_S) < 0.01
    wizard.close()


def test_demo_session_has_a_take_filmed_by_a_calibrated_camera(tmp_path):
    from handmocap.app.gui.demo import CAMERA_OFFSET_S, prepare_demo_session

    session = Session.open(prepare_demo_session(tmp_path / "demo"))
    [entry] = [entry for entry in session.takes if entry.cameras]
    [camera] = take_cameras(session, entry.id)
    assert camera.camera.registered and camera.camera.clock.offset_s == CAMERA_OFFSET_S
    assert session.folder in camera.media.parents
    with VideoFrames(camera.media) as video:
        assert video.size == (640, 480) and video.frame_rate == 30.0
        assert 3.0 <= video.count / video.frame_rate <= 5.0


def test_wizard_registers_an_unregistered_camera_from_the_takes_markers(window, qtbot, filmed, tmp_path):
    from handmocap.app.gui.camera_wizard import CameraWizard
    from handmocap.core.camera.model import Camera, rotation_angle_deg

    files, simulated = filmed
    truth = simulated.camera
    intrinsics_only = Camera(truth.matrix, truth.distortion, truth.size, clock=truth.clock, name="unregistered")
    folder = session_with_camera(filmed, tmp_path / "session", with_camera=False)
    session = Session.open(folder)
    add_camera(session, "t0001", intrinsics_only, files / "video.avi")
    session.close()
    open_session_take(window, qtbot, folder)
    frustum = getattr(window.viewport, "_frustum_actor", None)
    assert frustum is None or not frustum.visibility                # not registered: no frustum
    wizard = CameraWizard(window, window.cameras)
    qtbot.addWidget(wizard)
    camera = registered_camera(wizard, qtbot)
    assert np.linalg.norm(camera.centre - truth.centre) < 5.0
    assert rotation_angle_deg(camera.rotation, truth.rotation) < 0.5
    assert wizard.save() and window.cameras.camera.camera.registered
    assert window.viewport.view()._frustum_actor.visibility            # registered: the frustum is shown
    wizard.close()


def test_wizard_registers_from_a_marked_board_filmed_in_the_video(window, qtbot, tmp_path):
    import json

    from handmocap.app.gui.camera_wizard import CameraWizard
    from handmocap.core.camera.model import Camera, rotation_angle_deg
    from handmocap.core.io import Take

    truth = random_camera(31)                           # clock offset 0: camera frame k at mocap time k / 30 s
    views = board_views(truth, BoardSpec(), 8, seed=31)
    board_points = np.array([[0.0, 0.0, -5.0], [210.0, 0.0, -5.0], [0.0, 150.0, -5.0], [210.0, 150.0, -5.0]])
    positions = np.empty((26, 4, 3))
    for frame in range(26):                             # the board held still while each camera frame is taken
        view = min(int(round(frame / 100.0 * 30.0)), 7)
        positions[frame] = truth.to_mocap(board_points @ views.rotations[view].T + views.translations[view])
    names = [f"board{number}" for number in range(1, 5)]
    save_take(Take(names, positions, 100.0), tmp_path / "board.c3d")
    write_video(tmp_path / "board.avi", views.images, 30.0, truth.size)
    markers = dict(zip(names, board_points.tolist(), strict=True))
    (tmp_path / "board_markers.json").write_text(json.dumps({"markers": markers}))
    session = Session.create(tmp_path / "session")
    entry = session.add_take(tmp_path / "board.c3d")
    add_camera(session, entry.id, Camera(truth.matrix, truth.distortion, truth.size, name="board camera"),
               tmp_path / "board.avi")
    session.close()
    open_session_take(window, qtbot, tmp_path / "session")
    wizard = CameraWizard(window, window.cameras)
    qtbot.addWidget(wizard)
    wizard.method_box.setCurrentIndex(1)
    wizard.board_file_edit.setText(str(tmp_path / "missing.json"))
    wizard.start_registration()
    assert not wizard.runner.is_busy() and "missing.json" in wizard.status_label.text()
    wizard.board_file_edit.setText(str(tmp_path / "board_markers.json"))
    camera = registered_camera(wizard, qtbot)
    assert np.linalg.norm(camera.centre - truth.centre) < 2.0
    assert rotation_angle_deg(camera.rotation, truth.rotation) < 0.2
    assert "board corners" in wizard.register_label.text()
    wizard.close()
