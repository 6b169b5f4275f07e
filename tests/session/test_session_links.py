"""Symbolic links planted in a session folder are never followed: opening, editing, saving and cleaning up
refuse with one clear line, and nothing outside the session folder is written or deleted."""

import os
import shutil
import time
from contextlib import contextmanager

import pytest
from simulated_files import labelled_session

from handmocap.core.errors import InputError
from handmocap.core.review import ApplyLabelling, Unlabel
from handmocap.core.session import Session

TAKE = "t0001"


@pytest.fixture
def session_folder(tmp_path):
    """A saved session with one reviewed take (blobs, journal, snapshot, lock) and an outside folder."""
    opened, result = labelled_session(tmp_path, frames=200, seed=2)
    opened.save()
    opened.push(ApplyLabelling(result))  # blobs and a journal line after the snapshot
    opened.close(save=False)
    assert list((tmp_path / "session" / "takes" / TAKE / "blobs").iterdir())
    outside = tmp_path / "outside"
    outside.mkdir()
    for name in ("precious.txt", "1-0.npy", ".old.tmp", "journal.jsonl"):
        (outside / name).write_bytes(b"keep me " + name.encode())
        os.utime(outside / name, (time.time() - 3600, time.time() - 3600))
    return tmp_path / "session", outside, result


def _contents(folder):
    return {path.name: path.read_bytes() for path in folder.iterdir()}


def _replace_by_link(path, target):
    if path.is_dir():
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()
    path.symlink_to(target)


def _one_line_link_error(raised):
    text = str(raised.value)
    assert "symbolic link" in text and "\n" not in text, text


@contextmanager
def _refused(outside):
    """The block raises a one-line InputError about a symbolic link and leaves ``outside`` as it was."""
    before = _contents(outside)
    with pytest.raises(InputError) as raised:
        yield
    _one_line_link_error(raised)
    assert _contents(outside) == before


@pytest.mark.parametrize("entry, target", [
    ("takes/t0001/blobs", "outside"),
    ("takes/t0001/journal.jsonl", "outside/journal.jsonl"),
    ("takes/t0001/review.npz", "outside/precious.txt"),
    ("takes/t0001/lock", "outside/precious.txt"),
    ("takes/t0001/.planted.tmp", "outside/.old.tmp"),
    ("takes/t0001", "outside"),
])
def test_a_link_in_a_take_folder_is_refused_on_open(session_folder, entry, target):
    folder, outside, _ = session_folder
    _replace_by_link(folder / entry, folder.parent / target)
    session = Session.open(folder)
    with _refused(outside):
        session.open_take(TAKE)
    with _refused(outside):
        Session.open(folder, read_only=True).open_take(TAKE)  # not even read through it


@pytest.mark.parametrize("entry, target", [
    ("session.json", "outside/precious.txt"),
    ("session.json.bak", "outside/precious.txt"),
    ("session.lock", "outside/precious.txt"),
    ("takes", "outside"),
    ("models", "outside"),
    ("layouts", "outside"),
])
def test_a_link_where_the_session_keeps_its_files_is_refused_on_open(session_folder, entry, target):
    folder, outside, _ = session_folder
    if (folder / entry).exists():
        (folder / entry).rename(folder / f"{entry}.moved")
    (folder / entry).symlink_to(folder.parent / target)
    with _refused(outside):
        Session.open(folder)


def test_links_planted_while_a_take_is_open_are_not_followed(session_folder):
    folder, outside, result = session_folder
    before = _contents(outside)
    opened = Session.open(folder).open_take(TAKE)
    blobs = opened.folder / "blobs"
    _replace_by_link(blobs, outside)
    with pytest.raises(InputError) as raised:
        opened.push(ApplyLabelling(result))  # its arrays would go to blobs/
    assert "symbolic link" in str(raised.value) and "not applied" in str(raised.value)
    opened.push(Unlabel(label="M0", scope="take"))  # a small edit needs no blob
    with pytest.raises(InputError) as raised:
        opened.save()  # the save would clean blobs/ up
    _one_line_link_error(raised)
    assert _contents(outside) == before
    blobs.unlink()
    opened.save()  # with the link gone, the edits are saved
    opened.close()
    assert (Session.open(folder).open_take(TAKE).review.assignment[:, 0] == -1).all()
    assert _contents(outside) == before


def test_stale_temporaries_are_removed_but_never_through_a_link(session_folder):
    folder, outside, _ = session_folder
    before = _contents(outside)
    stale = [folder / ".session.json.abcd1234.tmp", folder / ".session.0123456789abcdef.tmp.json"]
    for path in stale:
        path.write_bytes(b"left by a crash")
        os.utime(path, (time.time() - 3600, time.time() - 3600))
    fresh = folder / ".session.fedcba9876543210.tmp.json"  # another process may be writing it right now
    fresh.write_bytes(b"being written")
    (folder / ".planted.0123456789abcdef.tmp").symlink_to(outside / ".old.tmp")
    Session.open(folder)
    assert not any(path.exists() for path in stale) and fresh.exists()
    assert (folder / ".planted.0123456789abcdef.tmp").is_symlink()
    assert _contents(outside) == before


def test_a_models_folder_made_a_link_after_opening_is_refused_on_save(session_folder):
    from handmocap.core.model import load_template

    folder, outside, _ = session_folder
    session = Session.open(folder)
    (folder / "models").symlink_to(outside)
    with _refused(outside):
        session.save_subject_model("S01", load_template())


def test_a_fifo_in_place_of_the_journal_is_refused_without_blocking(session_folder):
    folder, _, _ = session_folder
    journal = folder / "takes" / TAKE / "journal.jsonl"
    journal.unlink()
    os.mkfifo(journal)
    with pytest.raises(InputError, match="not a regular file"):
        Session.open(folder).open_take(TAKE)
