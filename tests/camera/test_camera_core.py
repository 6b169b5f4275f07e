"""Camera model, files, frame sources, calibration, registration and synchronisation (issue 14)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from handmocap.core.camera.extrinsics import MarkerFrame, detect_blobs, register_from_markers
from handmocap.core.camera.files import load_camera, save_camera
from handmocap.core.camera.frames import DepthFolderFrames, ImageFolderFrames, VideoFrames
from handmocap.core.camera.intrinsics import BoardSpec, calibrate_intrinsics, detect_board
from handmocap.core.camera.model import Camera, CameraClock, rotation_angle_deg
from handmocap.core.camera.sync import sync_markers
from handmocap.core.errors import InputError
from handmocap.core.evaluation.data import RGBD_FRAMES
from handmocap.core.simulate.camera import (
    MARKER_RADIUS,
    OBJECT_MARKER_RADIUS,
    board_views,
    calibration_object_views,
    random_camera,
    simulate_camera_take,
)

SR305 = RGBD_FRAMES / "sr305_open_right_hand"


def test_projection_and_back_projection_round_trip_with_distortion():
    camera = random_camera(4)
    assert abs(camera.distortion[0]) > 1e-3
    points = camera.to_mocap(np.random.default_rng(0).uniform([-250, -180, 500], [250, 180, 1200], (200, 3)))
    pixels = camera.project(points)
    back = camera.back_project(pixels, camera.to_camera(points)[:, 2])
    assert np.abs(back - points).max() < 1e-6
    pinhole = Camera(camera.matrix, np.zeros(5), camera.size, camera.rotation, camera.translation, registered=True)
    assert np.abs(pinhole.project(points) - pixels).max() > 0.5   # distortion moves pixels
    assert np.isnan(camera.project(camera.to_mocap(np.array([[0.0, 0.0, -100.0]])))).all()   # behind


def test_camera_json_and_opencv_yaml_round_trip(tmp_path):
    camera = random_camera(5).with_clock(CameraClock(0.25, 1.001))
    save_camera(camera, tmp_path / "cam.json", {"note": 1})
    loaded = load_camera(tmp_path / "cam.json")
    assert np.allclose(loaded.matrix, camera.matrix) and np.allclose(loaded.distortion, camera.distortion)
    assert np.allclose(loaded.rotation, camera.rotation) and loaded.clock == camera.clock and loaded.registered
    storage = cv2.FileStorage(str(tmp_path / "cam.yaml"), cv2.FILE_STORAGE_WRITE)
    storage.write("image_width", 640)
    storage.write("image_height", 480)
    storage.write("camera_matrix", camera.matrix)
    storage.write("distortion_coefficients", camera.distortion.reshape(1, -1))
    storage.release()
    from_yaml = load_camera(tmp_path / "cam.yaml")
    assert np.allclose(from_yaml.matrix, camera.matrix) and np.allclose(from_yaml.distortion, camera.distortion)
    assert not from_yaml.registered and from_yaml.size == (640, 480)


@pytest.mark.parametrize("content", [b"{", b'{"format": "handmocap-camera", "version": 1}',
                                     json.dumps({"format": "handmocap-camera", "version": 1, "image_size": [640, 480],
                                                 "camera_matrix": [[-1, 0, 0], [0, 1, 0], [0, 0, 1]]}).encode()])
def test_bad_camera_files_give_one_line(tmp_path, content):
    path = tmp_path / "bad.json"
    path.write_bytes(content)
    with pytest.raises(InputError) as error:
        load_camera(path)
    assert "\n" not in str(error.value)


def test_hostile_and_undecodable_frames_give_one_line(tmp_path):
    (tmp_path / "video.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(4000))
    (tmp_path / "frames").mkdir()
    header = b"\x89PNG\r\n\x1a\n" + b"\x00\x00\x00\x0dIHDR" + (100000).to_bytes(4, "big") * 2 + bytes(20)
    (tmp_path / "frames" / "frame_0.png").write_bytes(header)
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "a.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00\x00\x00\x0dIHDR" + bytes(200))
    for opener in (lambda: VideoFrames(tmp_path / "video.mp4"), lambda: ImageFolderFrames(tmp_path / "frames"),
                   lambda: ImageFolderFrames(tmp_path / "junk"), lambda: DepthFolderFrames(tmp_path / "frames", 1.0)):
        with pytest.raises(InputError) as error:
            opener()
        assert "\n" not in str(error.value)


def test_video_random_access_matches_sequential_decode(tmp_path):
    from handmocap.core.camera.writers import write_video

    frames = [np.full((48, 64, 3), 10 * k, np.uint8) for k in range(20)]
    write_video(tmp_path / "v.avi", frames, 30.0, (64, 48))
    with VideoFrames(tmp_path / "v.avi") as video:
        assert video.count == 20 and video.frame_rate == 30.0
        for k in (15, 3, 4, 19, 0, 7):
            assert abs(float(video.frame(k).mean()) - 10 * k) < 3
        assert video.index_at(0.51) == 15


def test_charuco_intrinsics_within_targets():
    truth = random_camera(4)
    spec = BoardSpec()
    views = board_views(truth, spec, 14, 4)
    result = calibrate_intrinsics([detect_board(image, spec) for image in views.images], truth.size)
    focal = np.abs(np.array(result.camera.focal) / np.array(truth.focal) - 1).max() * 100
    principal = np.linalg.norm(np.array(result.camera.principal_point) - truth.principal_point)
    assert focal <= 0.5 and principal <= 2.0 and result.reprojection_px <= 0.5


def test_extrinsics_from_the_calibration_object_colour_and_depth():
    truth = random_camera(6)
    views = calibration_object_views(truth, 8, 6)
    intrinsics = Camera(truth.matrix, truth.distortion, truth.size)
    frames = [MarkerFrame(detect_blobs(truth, c, d, OBJECT_MARKER_RADIUS), m)
              for c, d, m in zip(views.colour, views.depth, views.markers, strict=True)]
    for use_depth in (False, True):
        result = register_from_markers(intrinsics, frames, use_depth=use_depth)
        assert np.linalg.norm(result.camera.centre - truth.centre) <= 2.0
        assert rotation_angle_deg(result.camera.rotation, truth.rotation) <= 0.2
        assert result.matched_share > 0.95


def test_sync_offset_within_one_mocap_frame():
    take = simulate_camera_take(seed=4, n_frames=250, offset_s=0.23)
    truth = take.camera
    blobs = [detect_blobs(truth, take.render(k, with_depth=False)[0], None, MARKER_RADIUS)
             for k in range(len(take.camera_times))]
    result = sync_markers(truth.with_clock(CameraClock()), blobs, take.camera_times,
                          take.simulated.truth["marker_positions"], 100.0, estimate_rate=False)
    assert abs(result.offset_frames - 23.0) <= 1.0 and result.quality > 0.5


@pytest.mark.skipif(not SR305.is_dir(), reason="shared SR305 depth frames absent")
def test_real_sr305_depth_back_projects_to_a_hand_sized_cloud():
    camera = Camera(np.array([[476.007, 0, 313.683], [0, 476.007, 242.755], [0, 0, 1]]), np.zeros(0), (640, 480))
    with DepthFolderFrames(SR305, unit_mm=0.125) as frames:
        assert frames.count == 8
        depth = frames.frame(3)   # the hand alone in front (in frames 0-2 the forearm is as near)
    valid = depth[depth > 0]
    assert 150 < np.percentile(valid, 1) < 1500           # mm, a hand in front of an SR305
    points, _ = camera.back_project_depth(depth, step=2)
    near = points[points[:, 2] < np.percentile(points[:, 2], 1) + 60]   # the nearest 6 cm: the hand
    extent = np.percentile(near, 98, axis=0) - np.percentile(near, 2, axis=0)   # robust to stray edge pixels
    assert 80 < extent[:2].max() < 300 and extent[2] < 80 and 450 < np.median(near[:, 2]) < 800
