"""Cameras stored with a session take (core.session.cameras): the camera file inside the session folder,
the media referenced, the manifest updated under its lock, and everything back on reopening."""

import json

import numpy as np
import pytest

from handmocap.core.camera.model import CameraClock
from handmocap.core.errors import InputError
from handmocap.core.io import save_take
from handmocap.core.session import Session
from handmocap.core.session.cameras import add_camera, camera_file, save_take_camera, take_cameras
from handmocap.core.simulate import simulate_take
from handmocap.core.simulate.camera import random_camera


@pytest.fixture
def session_with_take(tmp_path):
    take = simulate_take(layout="dense", n_frames=30, seed=2).take
    save_take(take, tmp_path / "take.c3d")
    session = Session.create(tmp_path / "session")
    entry = session.add_take(tmp_path / "take.c3d", take=take)
    video = tmp_path / "video.avi"
    video.write_bytes(b"not decoded here")
    return session, entry, video


def test_camera_is_stored_in_the_session_and_restored_on_reopening(session_with_take):
    session, entry, video = session_with_take
    camera = random_camera(5, clock=CameraClock(0.25, 1.0))
    stored = add_camera(session, entry.id, camera, video)
    path = camera_file(session, entry.id, stored.name)
    assert path.is_file() and session.folder in path.parents
    manifest = json.loads(session.manifest_path.read_text())
    item = manifest["takes"][0]["cameras"][0]
    assert item["name"] == camera.name and item["media"] == str(video) and item["camera"].startswith("takes/")

    reopened = Session.open(session.folder)
    [restored] = take_cameras(reopened, entry.id)
    assert restored.media == video.resolve()
    np.testing.assert_allclose(restored.camera.matrix, camera.matrix)
    np.testing.assert_allclose(restored.camera.rotation, camera.rotation)
    assert restored.camera.clock.offset_s == 0.25

    save_take_camera(reopened, entry.id, restored.camera.with_clock(CameraClock(0.3, 1.0)))
    assert take_cameras(Session.open(session.folder), entry.id)[0].camera.clock.offset_s == 0.3


def test_a_second_camera_of_the_same_name_gets_a_new_name(session_with_take):
    session, entry, video = session_with_take
    first = add_camera(session, entry.id, random_camera(1), video)
    second = add_camera(session, entry.id, random_camera(1), video)
    assert first.name != second.name
    assert [c.name for c in take_cameras(session, entry.id)] == [first.name, second.name]


def test_missing_media_and_depth_without_a_unit_are_refused(session_with_take, tmp_path):
    session, entry, video = session_with_take
    with pytest.raises(InputError, match="does not exist"):
        add_camera(session, entry.id, random_camera(1), tmp_path / "missing.avi")
    with pytest.raises(InputError, match="depth unit"):
        add_camera(session, entry.id, random_camera(1), video, depth=tmp_path)
    assert session.take(entry.id).cameras == []


def test_a_malformed_camera_item_is_a_damaged_manifest(session_with_take):
    session, entry, video = session_with_take
    add_camera(session, entry.id, random_camera(1), video)
    manifest = json.loads(session.manifest_path.read_text())
    manifest["takes"][0]["cameras"][0]["camera"] = 12
    session.manifest_path.write_text(json.dumps(manifest))
    with pytest.raises(InputError, match="damaged"):
        Session.open(session.folder)
