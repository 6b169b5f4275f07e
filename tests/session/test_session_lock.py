"""Two instances on one session: processes opening the same take at the same moment get exactly one writer
and lose no acknowledged edit; processes updating the manifest for different takes lose no update.
(The longer run with figures is tests/bench/bench_session_lock.py.)"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from bench_session_lock import lock_trials, make_session, manifest_rounds  # noqa: E402

from handmocap.core.errors import InputError  # noqa: E402
from handmocap.core.review import Unlabel  # noqa: E402
from handmocap.core.session import Session  # noqa: E402


def test_simultaneous_opens_give_one_writer_and_lose_no_acknowledged_edit(tmp_path):
    figures = lock_trials(trials=6, processes=4, edits=8, folder=tmp_path)
    assert figures["not_one_writer"] == 0, figures
    assert figures["acknowledged"] == 6 * 8, figures  # the writer's edits only: readers' edits are refused
    assert figures["lost"] == 0 and figures["accepted_read_only"] == 0, figures
    assert figures["readers_told_holder"] == figures["readers"] == 6 * 3, figures


def test_manifest_updates_of_two_processes_on_different_takes_are_all_kept(tmp_path):
    figures = manifest_rounds(rounds=4, updates=6, folder=tmp_path)
    assert figures["lost"] == 0, figures


def test_a_second_opening_in_the_same_process_is_read_only_until_the_first_closes(tmp_path):
    folder = make_session(tmp_path / "session", frames=40)
    first = Session.open(folder).open_take("t0001")
    second = Session.open(folder).open_take("t0001")
    assert not first.read_only and second.read_only and "process" in second.held_by
    try:
        second.push(Unlabel(label="thumb_tip", scope="take"))
        raise AssertionError("a read-only take accepted an edit")
    except InputError as error:
        assert "read-only" in str(error) and "\n" not in str(error)
    first.push(Unlabel(label="index_tip", scope="take"))
    first.close()
    third = Session.open(folder).open_take("t0001")
    assert not third.read_only and (third.review.assignment[:, 1] == -1).all()
    third.close()


def test_an_update_keeps_what_another_session_object_wrote_meanwhile(tmp_path):
    folder = make_session(tmp_path / "session", takes=2, frames=30)
    one, two = Session.open(folder), Session.open(folder)
    one.set_state("t0001", "reviewed")
    two.record_export("t0002", "c3d", tmp_path / "out.c3d")  # two's copy of the manifest is older
    assert two.take("t0001").state == "reviewed"  # read again before the change
    final = Session.open(folder)
    assert final.take("t0001").state == "reviewed" and final.take("t0002").exports
