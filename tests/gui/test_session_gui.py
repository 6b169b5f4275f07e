"""Sessions in the main window: create, add a raw take, open it, auto-label, edit; the edits survive a
crash (the journal is replayed); a damaged manifest gives a message and is left alone."""

import numpy as np
import pytest
from simulated_files import save_raw_take

from handmocap.app.gui.review.dialogs import AutoLabelSettings
from handmocap.core.session import Session

pytestmark = pytest.mark.gui


@pytest.fixture(scope="module")
def raw_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("raw") / "session_raw.c3d"
    save_raw_take(path, n_frames=200, seed=4)
    return path


def wait_loader(window, qtbot):
    qtbot.waitUntil(lambda: not window.loader.is_busy(), timeout=30_000)


def test_session_take_edits_survive_a_crash(window, qtbot, raw_file, tmp_path):
    folder = tmp_path / "session"
    assert window.sessions.create_session(folder)
    window.sessions.add_takes([str(raw_file)])
    wait_loader(window, qtbot)
    session = window.sessions.session
    assert [row.name for row in window.sessions.browser.rows()] == ["session_raw"]
    take_id = session.takes[0].id
    assert session.takes[0].state == "raw"
    window.sessions.open_take(take_id)
    wait_loader(window, qtbot)
    document = window.document
    assert document.session_take_id == take_id and document.open_take is not None
    window.review.start_auto_label(AutoLabelSettings(layout="dense", hands="right"))
    qtbot.waitUntil(lambda: not window.review.jobs.is_busy(), timeout=120_000)
    assert not window.messages, window.messages
    assert session.take(take_id).state == "labelled"              # saved after the auto-label
    assert window.sessions.browser.rows()[0].state == "labelled"
    assert (document.open_take.folder / "labelling_hand_right.npz").exists()   # the subject-calibrated hand
    # an edit goes to the journal at once
    review = document.review
    window.review.select_label(3)
    window.review.scope_box.setCurrentIndex(window.review.scope_box.findData("take"))
    window.timeline.set_frame(int(np.flatnonzero(review.assignment[:, 3] >= 0)[0]))
    window.review.select_label(3)
    window.review.unlabel()
    assert (review.assignment[:, 3] == -1).all()
    expected = review.assignment.copy()
    # "crash": the window's take is never saved or closed; another process opens the folder
    recovered = Session.open(folder).open_take(take_id)
    assert recovered.replayed >= 1
    np.testing.assert_array_equal(recovered.review.assignment, expected)
    recovered.close(save=False)


def test_damaged_manifest_gives_a_message_and_is_kept(window, tmp_path):
    folder = tmp_path / "broken"
    Session.create(folder).close()
    manifest = folder / "session.json"
    manifest.write_text("{ not json", encoding="utf-8")
    assert not window.sessions.open_session(folder)
    assert window.messages and "damaged" in window.messages[-1]
    assert manifest.read_text(encoding="utf-8") == "{ not json"
    assert window.sessions.session is None


def test_adding_a_bad_file_reports_it(window, qtbot, tmp_path):
    assert window.sessions.create_session(tmp_path / "s")
    bad = tmp_path / "garbage.c3d"
    bad.write_bytes(b"this is not a c3d file at all" * 10)
    window.sessions.add_takes([str(bad)])
    wait_loader(window, qtbot)
    assert window.messages and "garbage.c3d" in window.messages[-1]
    assert window.sessions.session.takes == []
