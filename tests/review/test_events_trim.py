"""Events (named frames) and trim (issue 23 item 7): read from and written to the C3D EVENT group, undoable and
journalled, kept by the session, exported (C3D, the joint-angle CSV's event column), trimmed exports."""

from __future__ import annotations

import csv

import ezc3d
import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.io import load_take, save_take
from handmocap.core.io.c3d_events import TakeEvent, event_group, read_events
from handmocap.core.review import (
    AddEvent,
    RemoveEvent,
    ReviewTake,
    SetSolve,
    TrimTake,
    UndoStack,
    command_from_json,
    export_joint_angles_csv,
    export_labelled_c3d,
    review_from_labelled_c3d,
)
from handmocap.core.review.export import export_review
from handmocap.core.session import Session
from handmocap.core.simulate import simulate_take

FRAMES = 200


@pytest.fixture
def review():
    take = simulate_take(layout="dense", n_frames=FRAMES, seed=2, noise_mm=0.2).take
    take.first_frame = 101                                   # a file whose frames start at 101
    return ReviewTake.from_labelled_take(take)


def test_a_vendor_file_s_events_are_read(shared_data):
    path = shared_data / "c3d" / "sample_00__Motion_Analysis_Corporation__Walk1.c3d"
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    take = load_take(path)
    events = ReviewTake.from_labelled_take(take).events
    assert [event.name for event in events] == ["LHS", "RTO", "RHS", "LTO", "LHS", "RTO", "RHS", "LTO"]
    assert events[0].frame_number == round(0.56666666 * take.frame_rate) + 1


def test_the_event_group_reads_back():
    events = [TakeEvent("grasp on", 150, "Right"), TakeEvent("grasp off", 4000, "General", "release")]
    assert read_events({"EVENT": event_group(events, 120.0)}, 120.0) == events


def test_events_and_trim_are_undoable_steps_and_journal_as_json(review):
    stack = UndoStack(review)
    stack.push(AddEvent("grasp on", 150, "Right"))
    stack.push(AddEvent("grasp off", 180))
    assert [(event.name, event.frame_number) for event in review.events] == [("grasp on", 150), ("grasp off", 180)]
    assert review.next_event(0) == (49, review.events[0]) and review.next_event(49)[0] == 79
    assert review.next_event(49, forward=False)[0] == 79                   # wraps around
    assert stack.push(TrimTake(40, 120)).empty                             # nothing to re-solve
    assert review.trim == (40, 120) and review.frame_range() == (40, 120)
    assert stack.undo_text() == "trim the take to frames 141-220"
    stack.push(RemoveEvent("grasp on", 150))
    assert [event.name for event in review.events] == ["grasp off"]
    for _ in range(4):
        stack.undo()
    assert review.events == [] and review.trim is None
    for _ in range(4):
        stack.redo()
    assert review.trim == (40, 120) and [event.name for event in review.events] == ["grasp off"]
    replayed = ReviewTake.from_labelled_take(review.take)
    for command in stack.commands:
        command_from_json(command.to_json()).do(replayed)
    assert replayed.timeline_state() == review.timeline_state()
    with pytest.raises(InputError, match="outside the take"):
        AddEvent("late", 5000).do(review)
    with pytest.raises(InputError, match="fewer than 2 frames"):
        TrimTake(10, 11).do(review)


def test_events_and_trim_are_kept_by_the_session(tmp_path, review):
    path = tmp_path / "take.c3d"
    save_take(review.take, path)
    session = Session.create(tmp_path / "session")
    entry = session.add_take(path)
    opened = session.open_take(entry.id)
    opened.push(AddEvent("grasp on", 150))
    opened.push(TrimTake(20, 180))
    opened.close(save=False)                                 # killed: the journal has them
    again = Session.open(tmp_path / "session").open_take(entry.id)
    assert again.review.trim == (20, 180) and [event.name for event in again.review.events] == ["grasp on"]
    again.save()
    again.close()
    third = Session.open(tmp_path / "session").open_take(entry.id)   # from the snapshot
    assert third.review.trim == (20, 180) and third.review.events[0].frame_number == 150
    third.undo()
    assert third.review.trim is None
    third.close()


def test_a_trimmed_take_exports_its_range_with_its_events(tmp_path, review):
    hand = review.hands[0]
    angles = np.zeros((FRAMES, 26))
    stack = UndoStack(review)
    stack.push(SetSolve(0, 0, angles, np.zeros((FRAMES, len(hand.labels)))))
    stack.push(AddEvent("grasp on", 150, "Right"))
    stack.push(AddEvent("too early", 110))
    stack.push(TrimTake(20, 180))                            # frames 121..280
    out = tmp_path / "trimmed.c3d"
    export_labelled_c3d(review, out)
    read = review_from_labelled_c3d(out)
    assert read.n_frames == 160 and read.take.first_frame == 121
    assert [(event.name, event.frame_number, event.context) for event in read.events] == [("grasp on", 150, "Right")]
    c3d = ezc3d.c3d(str(out))
    assert c3d["header"]["points"]["first_frame"] + 1 == 121 and c3d["parameters"]["EVENT"]["USED"]["value"][0] == 1
    assert c3d["parameters"]["EVENT"]["LABELS"]["value"] == ["grasp on"]
    np.testing.assert_allclose(read.take.marker_positions, review.take.marker_positions[20:180], atol=1e-3)
    angles_csv = tmp_path / "angles.csv"
    export_joint_angles_csv(review, angles_csv)
    with angles_csv.open() as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 160 and rows[0]["frame"] == "121"
    assert [row["frame"] for row in rows if row["event"]] == ["150"] and rows[29]["event"] == "grasp on"
    trc = tmp_path / "trimmed.trc"
    export_review(review, trc, "trc")
    assert load_take(trc).n_frames == 160
