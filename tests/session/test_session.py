"""Session folders: manifest, takes, journal replay, crash (SIGKILL) recovery, damaged and read-only folders."""

import contextlib
import copy
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.io import save_take
from handmocap.core.model import load_layout
from handmocap.core.review import (
    AcceptFills,
    ApplyLabelling,
    AssignLabel,
    GapFill,
    LabellingArrays,
    ReviewTake,
    SetSolve,
    SwapLabels,
    UndoStack,
    Unlabel,
)
from handmocap.core.review.synthetic import synthetic_labelling
from handmocap.core.session import Session
from handmocap.core.session.journal import JOURNAL_NAME

ROOT = Path(__file__).resolve().parents[2]
FRAMES = 200


@pytest.fixture
def raw(tmp_path):
    take, result, truth = synthetic_labelling(frames=FRAMES, labels=5, ghosts=1, seed=1)
    path = tmp_path / "data" / "raw_take.c3d"
    path.parent.mkdir()
    save_take(take, path)
    return path, result


def _new_session_take(tmp_path, path):
    """A new session at ``tmp_path/session`` with the raw take ``path`` added and opened."""
    session = Session.create(tmp_path / "session")
    entry = session.add_take(path)
    return session, entry, session.open_take(entry.id)


def _die(session_take):
    """The process holding ``session_take`` "dies": its journal and take lock are released, nothing is saved
    (the kernel does the same when a process ends)."""
    session_take.close(save=False)


def _edits(session_take):
    """A fixed series of operations on an open take (returns the reviews' states after each)."""
    states = []
    review = session_take.review
    session_take.push(SwapLabels("M1", "M2", 10, 30))
    states.append(copy.deepcopy(review))
    column = review.assignment[50, 3]  # numpy integers, as a GUI passes them, journal as plain JSON
    session_take.push(AssignLabel(np.int64(50), column, "M4", scope="range", start=np.int64(40), stop=60))
    session_take.attach(SetSolve(0, 40, np.full((20, 26), 0.25), np.full((20, 5), 1.5)))
    states.append(copy.deepcopy(review))
    session_take.undo()
    states.append(copy.deepcopy(review))
    session_take.redo()
    states.append(copy.deepcopy(review))
    start = FRAMES // 3
    session_take.push(AcceptFills([GapFill("M0", start, "spline", np.full((FRAMES // 6, 3), 7.0))]))
    states.append(copy.deepcopy(review))
    return states


def test_create_add_and_manifest(tmp_path, raw):
    path, _ = raw
    session = Session.create(tmp_path / "session", name="pilot")
    with pytest.raises(InputError, match="already holds a session"):
        Session.create(tmp_path / "session")
    entry = session.add_take(path, subject="S01", layout="dense", hands=["right"])
    assert entry.id == "t0001" and entry.state == "raw" and not entry.labelled_source
    assert entry.frames == FRAMES and entry.points == 6 and entry.frame_rate == 100.0
    assert Path(entry.source).is_absolute() and entry.source_relative == "../data/raw_take.c3d"
    second = session.add_take(path)
    assert second.id == "t0002" and second.name == "raw_take (2)"
    layout_path = session.save_layout(load_layout("glove-13"))
    assert layout_path.exists() and session.layout_path("glove-13") == layout_path
    from handmocap.core.model import load_template

    model_path = session.save_subject_model("S01", load_template())
    assert model_path.exists()
    assert session.load_subject_model("S01").skeleton.side == "right"
    session.set_state(entry.id, "reviewed")
    with pytest.raises(InputError, match="unknown take state"):
        session.set_state(entry.id, "done")
    manifest = json.loads((tmp_path / "session" / "session.json").read_text())
    assert manifest["format"] == "handmocap-session" and manifest["version"] == 1
    assert [t["state"] for t in manifest["takes"]] == ["reviewed", "raw"]
    assert manifest["subjects"] == [{"name": "S01", "model": "models/S01.npz", "notes": ""}]
    assert manifest["layouts"] == [{"name": "glove-13", "path": "layouts/glove-13.json"}]
    assert (tmp_path / "session" / "session.json.bak").exists()
    reopened = Session.open(tmp_path / "session")
    assert [t.name for t in reopened.takes] == ["raw_take", "raw_take (2)"]
    reopened.remove_take("t0002")
    assert [t.id for t in Session.open(tmp_path / "session").takes] == ["t0001"]
    with pytest.raises(InputError, match="no take"):
        reopened.take("t0009")


def test_session_moved_with_its_data_finds_the_raw_file(tmp_path, raw):
    path, _ = raw
    session = Session.create(tmp_path / "session")
    entry = session.add_take(path)
    shutil.move(tmp_path, tmp_path.with_name(tmp_path.name + "_moved"))
    moved = tmp_path.with_name(tmp_path.name + "_moved")
    try:
        session = Session.open(moved / "session")
        assert session.source_path(entry.id) == (moved / "data" / "raw_take.c3d").resolve()
        session.open_take(entry.id)
    finally:
        shutil.move(moved, tmp_path)


def test_missing_or_changed_raw_file(tmp_path, raw):
    path, _ = raw
    session = Session.create(tmp_path / "session")
    entry = session.add_take(path)
    moved = path.with_name("elsewhere.c3d")
    path.rename(moved)
    with pytest.raises(InputError, match="raw file of take 'raw_take' is missing"):
        session.open_take(entry.id)
    take, _, _ = synthetic_labelling(frames=FRAMES + 5)
    other = path.with_name("other.c3d")
    save_take(take, other)
    with pytest.raises(InputError, match="frames"):
        session.relink_take(entry.id, other)
    session.relink_take(entry.id, moved)
    assert session.open_take(entry.id).review.n_frames == FRAMES


def test_labelled_source_opens_with_its_columns_as_labels(tmp_path):
    take, _, _ = synthetic_labelling(frames=30, shuffle=False, ghosts=0)
    take.marker_names = ["thumb_tip", "index_tip", "middle_tip", "ring_tip", "little_tip"]
    path = tmp_path / "labelled.c3d"
    save_take(take, path)
    session = Session.create(tmp_path / "session")
    entry = session.add_take(path)
    assert entry.labelled_source
    review = session.open_take(entry.id).review
    assert review.label_names == take.marker_names
    assert np.array_equal(review.labelled_positions(), take.marker_positions, equal_nan=True)


def test_journal_replays_edits_after_a_crash_and_save_keeps_history(tmp_path, raw):
    path, result = raw
    session, entry, opened = _new_session_take(tmp_path, path)
    assert opened.review.n_labels == 0 and opened.replayed == 0
    opened.push(ApplyLabelling(result))
    states = _edits(opened)
    texts = opened.stack.texts()
    assert (opened.folder / "blobs").is_dir()  # the joint angles of the labelling are large
    _die(opened)  # no save: the process "dies" here
    again = Session.open(tmp_path / "session").open_take(entry.id)
    assert again.replayed == 7 and again.warnings == []
    assert again.review.same_state(states[-1])
    assert again.stack.texts() == texts and again.stack.index == 4
    again.undo()
    assert again.review.same_state(states[-2])
    again.redo()
    again.save()
    assert (opened.folder / JOURNAL_NAME).read_bytes() == b""
    assert list((opened.folder / "blobs").iterdir())  # kept: an older snapshot may need the journal since it
    _die(again)
    third = Session.open(tmp_path / "session").open_take(entry.id)
    assert third.replayed == 0 and third.review.same_state(states[-1])
    assert third.stack.texts() == texts and third.stack.is_clean()
    third.undo()
    assert third.review.same_state(states[3])  # before the fill
    third.undo()
    assert third.review.same_state(states[0])  # before the assign and its solve
    third.undo()
    third.undo()  # the auto-label
    assert third.review.n_labels == 0
    assert Session.open(tmp_path / "session").take(entry.id).state == "labelled"


def test_rigid_bodies_of_a_labelling_survive_replay_save_and_undo(tmp_path, raw):
    path, result = raw
    session, entry, opened = _new_session_take(tmp_path, path)
    arrays = LabellingArrays(list(result.marker_names), result.assignment, result.confidence, result.residuals_mm,
                             result.ghost_points, [], rigid_bodies={"cup": [2, 3, 4]})
    opened.push(ApplyLabelling(arrays))
    assert opened.review.rigid_bodies == {"cup": [2, 3, 4]}
    _die(opened)
    replayed = Session.open(tmp_path / "session").open_take(entry.id)       # the process "died" unsaved
    assert replayed.replayed == 1 and replayed.review.rigid_bodies == {"cup": [2, 3, 4]}
    replayed.save()
    replayed.close()
    reopened = Session.open(tmp_path / "session").open_take(entry.id)
    assert reopened.replayed == 0 and reopened.review.rigid_bodies == {"cup": [2, 3, 4]}
    reopened.undo()
    assert reopened.review.rigid_bodies == {} and reopened.review.n_labels == 0
    reopened.redo()
    assert reopened.review.rigid_bodies == {"cup": [2, 3, 4]}


def test_crash_between_snapshot_and_journal_restart_does_not_apply_twice(tmp_path, raw):
    path, result = raw
    session, entry, opened = _new_session_take(tmp_path, path)
    opened.push(ApplyLabelling(result))
    opened.push(Unlabel(label="M3", scope="range", start=0, stop=50))
    journal = (opened.folder / JOURNAL_NAME).read_bytes()
    blobs = {p.name: p.read_bytes() for p in (opened.folder / "blobs").iterdir()}
    expected = copy.deepcopy(opened.review)
    opened.save()
    _die(opened)
    (opened.folder / JOURNAL_NAME).write_bytes(journal)  # as if the restart never happened
    for name, data in blobs.items():
        (opened.folder / "blobs" / name).write_bytes(data)
    again = Session.open(tmp_path / "session").open_take(entry.id)
    assert again.replayed == 0 and again.review.same_state(expected)
    again.push(SwapLabels("M0", "M1", 0, 10))  # numbering continues after the snapshot's entries
    lines = (opened.folder / JOURNAL_NAME).read_text().splitlines()
    assert json.loads(lines[-1])["seq"] == 3


def test_torn_and_damaged_journal_lines(tmp_path, raw):
    path, result = raw
    session, entry, opened = _new_session_take(tmp_path, path)
    opened.push(ApplyLabelling(result))
    opened.push(Unlabel(label="M3", scope="range", start=0, stop=50))
    expected = copy.deepcopy(opened.review)
    journal_path = opened.folder / JOURNAL_NAME
    _die(opened)
    with open(journal_path, "ab") as handle:
        handle.write(b'{"seq":3,"op":"do","command":{"type":"unla')  # killed while writing
    again = Session.open(tmp_path / "session").open_take(entry.id)
    assert again.replayed == 2 and again.review.same_state(expected)
    assert any("incomplete" in warning for warning in again.warnings)
    again.push(Unlabel(label="M2", scope="range", start=0, stop=5))
    assert all(json.loads(line) for line in journal_path.read_text().splitlines())
    # a damaged line in the middle: it is skipped, the edits before and after it come back, the file is kept
    # aside
    expected = copy.deepcopy(again.review)
    _die(again)
    lines = journal_path.read_bytes().splitlines(keepends=True)
    journal_path.write_bytes(lines[0] + b"garbage\n" + b"".join(lines[1:]))
    third = Session.open(tmp_path / "session").open_take(entry.id)
    assert third.review.same_state(expected) and any("damaged" in warning for warning in third.warnings)
    assert list(opened.folder.glob("journal.jsonl.damaged-*"))
    _die(third)
    fourth = Session.open(tmp_path / "session").open_take(entry.id)
    assert fourth.review.same_state(third.review) and fourth.warnings == []


KILL_CHILD = textwrap.dedent("""
    import sys
    import numpy as np
    from handmocap.core.review import ApplyLabelling, AssignLabel, SwapLabels, Unlabel, AcceptFills, GapFill
    from handmocap.core.session import Session
    from handmocap.core.review.synthetic import synthetic_labelling

    def operations(count):
        rng = np.random.default_rng(7)
        ops = [("do", "labelling")]
        for index in range(count):
            kind = rng.integers(6)
            start = int(rng.integers(0, 150))
            if kind == 0:
                ops.append(("undo", None))
            elif kind == 1:
                ops.append(("redo", None))
            elif kind == 2:
                a, b = rng.choice(5, 2, replace=False)
                ops.append(("do", ("swap", f"M{a}", f"M{b}", start, start + int(rng.integers(1, 40)))))
            elif kind == 3:
                ops.append(("do", ("unlabel", f"M{rng.integers(5)}", start, start + int(rng.integers(1, 40)))))
            else:
                ops.append(("do", ("assign", int(rng.integers(0, 200)), int(rng.integers(5)))))
        return ops

    def apply(opened, op, result):
        action, spec = op
        if action == "undo":
            return opened.undo()
        if action == "redo":
            return opened.redo()
        if spec == "labelling":
            return opened.push(ApplyLabelling(result))
        if spec[0] == "swap":
            return opened.push(SwapLabels(*spec[1:]))
        if spec[0] == "unlabel":
            return opened.push(Unlabel(label=spec[1], scope="range", start=spec[2], stop=spec[3]))
        frame, label = spec[1:]
        columns = np.flatnonzero(np.isfinite(opened.review.take.marker_positions[frame]).all(axis=1))
        column = int(columns[label % len(columns)])
        return opened.push(AssignLabel(frame, column, f"M{label}", scope="fragment"))

    if __name__ == "__main__":
        session = Session.open(sys.argv[1])
        opened = session.open_take("t0001")
        result = synthetic_labelling(frames=200, labels=5, ghosts=1, seed=1)[1]
        from handmocap.core.errors import InputError
        for number, op in enumerate(operations(100000)):
            try:
                apply(opened, op, result)
            except InputError:
                pass
            if number % 20 == 19:
                opened.save()  # snapshots and journal restarts happen between (and under) the kills too
            print(number, flush=True)
""")


def test_killing_the_process_mid_edits_loses_nothing(tmp_path, raw):
    path, result = raw
    session = Session.create(tmp_path / "session")
    session.add_take(path)
    script = tmp_path / "child.py"
    script.write_text(KILL_CHILD)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    child = subprocess.Popen([sys.executable, str(script), str(tmp_path / "session")], cwd=ROOT, env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    printed = -1
    watchdog = threading.Timer(300.0, child.kill)  # never hang the suite
    watchdog.start()
    try:
        for line in child.stdout:
            printed = int(line)
            if printed >= 60:
                os.kill(child.pid, signal.SIGKILL)
                break
    finally:
        watchdog.cancel()
        child.kill()
        child.wait(timeout=60)
    # read through the same buffered stream: lines it already read ahead are not in the pipe any more
    remaining, errors = child.stdout.read(), child.stderr.read()
    child.stdout.close()
    child.stderr.close()
    assert printed >= 60, errors
    printed = max([printed] + [int(line) for line in remaining.split()])
    assert child.returncode == -signal.SIGKILL
    recovered = Session.open(tmp_path / "session").open_take("t0001")
    assert recovered.review.n_labels == 5 and recovered.stack.index > 20  # the history came back too
    assert recovered.warnings == [] or all("incomplete" in w for w in recovered.warnings)
    # the same operations in memory: the recovered state is after `printed + 1` or `printed + 2` of them
    namespace: dict = {}
    exec(compile(KILL_CHILD, "child", "exec"), namespace)
    reference_session = Session.open(tmp_path / "session", read_only=True)
    reference = ReviewTake.unlabelled(reference_session.open_take("t0001").review.take)
    stack = UndoStack(reference)

    class Facade:
        review = reference

        def push(self, command):
            return stack.push(command)

        def undo(self):
            return stack.undo()

        def redo(self):
            return stack.redo()

    facade = Facade()
    matches = []
    for number, op in enumerate(namespace["operations"](printed + 1)):
        with contextlib.suppress(InputError):
            namespace["apply"](facade, op, result)
        if number >= printed:
            matches.append(recovered.review.same_state(reference))
    assert any(matches), (f"the recovered take must equal the state after the last journalled edit "
                          f"(printed {printed}, recovered step {recovered.stack.index}, {recovered.warnings})")


def test_damaged_manifest_is_kept_and_backup_restored(tmp_path, raw):
    path, _ = raw
    folder = tmp_path / "session"
    session = Session.create(folder)
    session.add_take(path)
    session.set_state("t0001", "labelled")
    manifest = folder / "session.json"
    manifest.write_text('{"format": "handmocap-session", "takes": [')  # truncated by a crash elsewhere
    damaged = manifest.read_bytes()
    with pytest.raises(InputError, match=r"session.json is damaged.*left untouched.*session.json.bak"):
        Session.open(folder)
    assert manifest.read_bytes() == damaged
    Session.restore_backup(folder)
    restored = Session.open(folder)
    assert [t.id for t in restored.takes] == ["t0001"]
    assert list(folder.glob("session.json.damaged-*"))
    manifest.write_text('{"format": "something else"}')
    with pytest.raises(InputError, match="damaged"):
        Session.open(folder)
    manifest.write_text('{"format": "handmocap-session", "takes": [{"id": "t1"}]}')
    with pytest.raises(InputError, match="damaged session manifest"):
        Session.open(folder)
    with pytest.raises(InputError, match="not a session folder"):
        Session.open(tmp_path / "data")


def _make_read_only(folder: Path) -> bool:
    """Make ``folder`` unwritable even for root (chattr +i); False when not possible."""
    folder.chmod(0o555)
    probe = folder / ".probe"
    try:
        probe.write_bytes(b"")
    except OSError:
        return True
    probe.unlink()
    done = subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode == 0
    return done


def _make_writable(folder: Path) -> None:
    subprocess.run(["chattr", "-i", str(folder)], capture_output=True)
    folder.chmod(0o755)


def test_read_only_session_folder(tmp_path, raw):
    path, result = raw
    folder = tmp_path / "session"
    session = Session.create(folder)
    entry = session.add_take(path)
    opened = session.open_take(entry.id)
    opened.push(ApplyLabelling(result))
    opened.save()
    opened.close()
    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    take_folder = opened.folder
    if not _make_read_only(folder) or not _make_read_only(take_folder):
        _make_writable(take_folder)
        _make_writable(folder)
        pytest.skip("cannot make a folder read-only here")
    try:
        with pytest.raises(InputError, match="not writable.*read-only"):
            Session.open(folder)
        with pytest.raises(InputError, match="cannot create the session folder|not writable"):
            Session.create(folder / "inner")
        viewer = Session.open(folder, read_only=True)
        view = viewer.open_take(entry.id)
        assert view.review.n_labels == 5
        with pytest.raises(InputError, match="read-only.*not applied"):
            view.push(Unlabel(label="M0", scope="take"))  # refused, not kept in memory only to be lost
        assert view.review.n_labels == 5 and view.read_only
        with pytest.raises(InputError, match="read-only"):
            view.save()
        with pytest.raises(InputError, match="read-only"):
            viewer.set_state(entry.id, "reviewed")
    finally:
        _make_writable(take_folder)
        _make_writable(folder)
    after = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    assert after == before


def test_journal_write_failure_reverts_the_edit(tmp_path, raw):
    path, result = raw
    session, entry, opened = _new_session_take(tmp_path, path)
    opened.push(ApplyLabelling(result))
    before = copy.deepcopy(opened.review)
    opened.journal.close()
    opened.journal.path = tmp_path / "no such folder" / "journal.jsonl"
    with pytest.raises(InputError, match="cannot write the edit journal.*not applied"):
        opened.push(Unlabel(label="M0", scope="take"))
    assert opened.review.same_state(before) and opened.stack.index == 1


HOLD_TAKE = textwrap.dedent("""
    import sys, time
    from handmocap.core.session import Session
    opened = Session.open(sys.argv[1]).open_take("t0001")
    print("held", flush=True)
    time.sleep(60)
""")


def test_a_take_open_in_another_process_opens_read_only(tmp_path, raw):
    path, _ = raw
    session = Session.create(tmp_path / "session")
    entry = session.add_take(path)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    other = subprocess.Popen([sys.executable, "-c", HOLD_TAKE, str(tmp_path / "session")], cwd=ROOT, env=env,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert other.stdout.readline().strip() == "held"
        view = session.open_take(entry.id)
        assert view.read_only and f"(process {other.pid})" in view.held_by
        with pytest.raises(InputError, match=rf"open read-only: .* \(process {other.pid}\) since .*not applied"):
            view.push(Unlabel(label="M0", scope="take"))
        view.close()
    finally:
        other.kill()
        other.wait()
        other.stdout.close()
    opened = session.open_take(entry.id)  # the holder died: the kernel released its lock
    assert not opened.read_only and opened.held_by is None
    lock = session.take_folder(entry.id) / "lock"
    assert f'"pid": {os.getpid()}' in lock.read_text()
    opened.close()
    assert lock.read_text() == ""  # emptied, never deleted (a waiting process would lock a stale file)


def test_labelled_take_with_a_layout_gets_its_hand_and_names_decide_labelled(tmp_path):
    from handmocap.core.simulate.take import simulate_take

    simulated = simulate_take("glove-13", n_frames=20, seed=0)
    path = tmp_path / "glove.c3d"
    save_take(simulated.take, path)
    session = Session.create(tmp_path / "session")
    entry = session.add_take(path, layout="glove-13")
    assert entry.labelled_source
    review = session.open_take(entry.id).review
    assert len(review.hands) == 1 and review.hands[0].layout == "glove-13"
    assert [review.label_names[i] for i in review.hands[0].labels] == load_layout("glove-13").names
    take, _, _ = synthetic_labelling(frames=20)
    save_take(take, tmp_path / "raw.c3d")  # point_000...: raw points
    assert not session.add_take(tmp_path / "raw.c3d").labelled_source
    take.marker_names = ["LFHD", "RFHD", "LBHD", "RBHD", "C7", "T10"]
    save_take(take, tmp_path / "vicon.c3d")  # real labels of another layout
    assert session.add_take(tmp_path / "vicon.c3d").labelled_source
    updated = session.update_take(entry.id, subject="S02", hands=["left"], name="glove take")
    assert (updated.subject, updated.hands, updated.name) == ("S02", ["left"], "glove take")
    with pytest.raises(InputError):
        session.update_take(entry.id, hands=["both"])
    with pytest.raises(InputError):
        session.update_take(entry.id, name="raw")
    assert Session.open(tmp_path / "session").take(entry.id).subject == "S02"


def test_an_edit_that_cannot_be_replayed_keeps_the_ones_before(tmp_path, raw):
    path, result = raw
    session, entry, opened = _new_session_take(tmp_path, path)
    opened.push(ApplyLabelling(result))
    opened.push(Unlabel(label="M1", scope="take"))
    expected = copy.deepcopy(opened.review)
    opened.push(Unlabel(label="M2", scope="take"))
    journal_path = opened.folder / JOURNAL_NAME
    lines = journal_path.read_text().splitlines()
    entry_3 = json.loads(lines[2])
    entry_3["command"]["label"] = "no such label"
    journal_path.write_text("\n".join(lines[:2] + [json.dumps(entry_3)]) + "\n")
    _die(opened)
    again = Session.open(tmp_path / "session").open_take(entry.id)
    assert again.review.same_state(expected)
    assert any("could not be replayed" in warning and "unknown label" in warning for warning in again.warnings)
    assert any("no such label" in kept.read_text() for kept in opened.folder.glob("journal-*.jsonl"))  # kept
    assert journal_path.read_bytes() == b""  # what was recovered is saved in the snapshot
    _die(again)
    assert Session.open(tmp_path / "session").open_take(entry.id).review.same_state(expected)


def test_autosave_close_and_exports_in_the_manifest(tmp_path, raw):
    path, result = raw
    session, entry, opened = _new_session_take(tmp_path, path)
    assert not opened.is_modified() and not opened.autosave_due(0.0)
    opened.push(ApplyLabelling(result))
    assert opened.is_modified() and opened.autosave_due(0.0) and not opened.autosave_due(3600.0)
    assert opened.autosave(0.0) and not opened.is_modified()
    assert entry.state == "labelled" and entry.results["review"] == f"takes/{entry.id}/review.npz"
    opened.push(Unlabel(label="M1", scope="take"))
    expected = copy.deepcopy(opened.review)
    session.close()
    assert opened.closed and (opened.folder / JOURNAL_NAME).read_bytes() == b""
    with pytest.raises(InputError, match="closed"):
        opened.push(Unlabel(label="M2", scope="take"))
    session.record_export(entry.id, "c3d", tmp_path / "out.c3d")
    reopened = Session.open(tmp_path / "session")
    assert reopened.take(entry.id).state == "exported"
    assert reopened.take(entry.id).exports == {"c3d": str(tmp_path / "out.c3d")}
    assert reopened.open_take(entry.id).review.same_state(expected)
