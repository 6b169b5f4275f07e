"""The review data model (stats, lanes, problems) and its undoable edits on a small synthetic take."""

import copy
import json

import numpy as np
import pytest

from handmocap.core.errors import InputError
from handmocap.core.review import (
    LANE_EDITED,
    LANE_FILLED,
    LANE_GAP,
    LANE_LOW_CONFIDENCE,
    LANE_NONE,
    LANE_OBSERVED,
    AcceptFills,
    ApplyLabelling,
    AssignLabel,
    CompoundCommand,
    GapFill,
    MarkGhost,
    RejectFills,
    ReviewTake,
    SetSolve,
    SwapLabels,
    UndoStack,
    Unlabel,
    command_from_json,
)
from handmocap.core.review.events import Change, ReviewChanged
from handmocap.core.review.synthetic import synthetic_labelling

FRAMES = 60


@pytest.fixture
def labelled():
    take, result, truth = synthetic_labelling(frames=FRAMES, labels=5, ghosts=1, seed=3)
    return ReviewTake.from_labelling(take, result, layout="test"), result, truth


def test_labelled_positions_stats_and_lanes(labelled):
    review, result, truth = labelled
    positions = review.labelled_positions()
    visible = result.assignment >= 0
    assert np.array_equal(positions[visible], truth[visible])
    assert np.isnan(positions[~visible]).all()
    stats = review.marker_stats()
    gap = FRAMES // 6
    assert stats.gap_count.tolist() == [1, 1, 0, 0, 0]
    assert stats.longest_gap.tolist() == [gap, gap, 0, 0, 0]
    assert np.allclose(stats.observed_percent[:2], 100.0 * (FRAMES - gap) / FRAMES)
    assert np.allclose(stats.mean_residual_mm, 0.5)
    assert np.allclose(stats.lowest_confidence_mm, 8.0)
    lanes = review.lane_states()
    assert (lanes[FRAMES // 3:FRAMES // 3 + gap, 0] == LANE_GAP).all()
    assert (lanes[:FRAMES // 3, 0] == LANE_OBSERVED).all()
    assert review.ghost.sum() == result.ghost_points.sum()
    assert [p.kind for p in review.problems()] == ["gap", "gap"]


def test_lanes_outside_the_labels_span_are_empty_and_edits_show(labelled):
    review, _, _ = labelled
    stack = UndoStack(review)
    stack.push(Unlabel(label="M2", scope="range", start=0, stop=10))
    lanes = review.lane_states()
    assert (lanes[:10, 2] == LANE_EDITED).all()
    stack.undo()
    assert not review.edited.any()
    stack.push(Unlabel(label="M3", scope="range", start=50, stop=FRAMES))
    review.edited[:] = False  # pretend the edit flags were saved away: a label that ends early
    review.changed()
    assert (review.lane_states()[50:, 3] == LANE_NONE).all()
    assert review.marker_stats().gap_count[3] == 0


def test_low_confidence_problems_and_navigation(labelled):
    review, result, _ = labelled
    result.confidence[40:43, 4] = 0.5
    result.confidence[10, 3] = 1.0
    review = ReviewTake.from_labelling(review.take, result)
    lanes = review.lane_states()
    assert (lanes[40:43, 4] == LANE_LOW_CONFIDENCE).all()
    problems = review.problems(["low_confidence"])
    assert [(p.label, p.start, p.stop) for p in problems] == [(3, 10, 11), (4, 40, 43)]
    assert review.next_problem(0, ["low_confidence"]).start == 10
    assert review.next_problem(10, ["low_confidence"]).start == 40
    assert review.next_problem(40, ["low_confidence"]).start == 10  # wraps around
    assert review.next_problem(40, ["low_confidence"], forward=False).start == 10
    assert review.next_problem(0, ["gap"]).kind == "gap"
    assert review.marker_stats().lowest_confidence_mm[4] == 0.5
    with pytest.raises(InputError):
        review.problems(["nonsense"])


def test_swap_suspect_is_found_and_fixed_by_a_swap(labelled):
    review, result, _ = labelled
    swapped = result.assignment.copy()
    swapped[20:26, [2, 3]] = swapped[20:26, [3, 2]]
    result.assignment = swapped
    review = ReviewTake.from_labelling(review.take, result)
    swaps = review.problems(["swap"])
    assert swaps, "a 6-frame swap of neighbouring labels must be suspected"
    assert {swaps[0].label, swaps[0].other} == {2, 3}
    assert swaps[0].start == 20
    assert "swap suspect" in swaps[0].text
    stack = UndoStack(review)
    span = stack.push(SwapLabels("M2", "M3", 20, 26))
    assert span == (20, 26)
    assert review.problems(["swap"]) == []
    assert review.edited[20:26, [2, 3]].all() and review.edited.sum() == 12


def test_assign_label_to_the_end_of_the_fragment(labelled):
    review, result, _ = labelled
    stack = UndoStack(review)
    frame = 5
    column = int(review.assignment[frame, 0])
    old_m1 = review.assignment[:, 1].copy()
    span = stack.push(AssignLabel(frame, column, "M1"))
    gap_start = FRAMES // 3
    assert span == (frame, gap_start)  # M0's fragment ends where its gap starts
    assert np.array_equal(review.assignment[frame:gap_start, 1], result.assignment[frame:gap_start, 0])
    assert (review.assignment[frame:gap_start, 0] == -1).all()
    assert np.array_equal(review.assignment[:frame, 0], result.assignment[:frame, 0])
    assert np.array_equal(review.assignment[gap_start:, 1], old_m1[gap_start:])
    # M1's displaced points are now unlabelled, not ghosts
    unlabelled = review.unlabelled_points()
    assert unlabelled[np.arange(frame, gap_start), old_m1[frame:gap_start]].all()
    assert not review.ghost[np.arange(frame, gap_start), old_m1[frame:gap_start]].any()
    assert stack.undo_text().startswith("label 'M0' at frames 6-")
    stack.undo()
    assert np.array_equal(review.assignment, result.assignment)


def test_unlabelled_points_are_followed_frame_to_frame(labelled):
    review, result, _ = labelled
    stack = UndoStack(review)
    stack.push(Unlabel(label="M4", scope="take"))
    assert (review.assignment[:, 4] == -1).all()
    frame = 30
    column = int(result.assignment[frame, 4])
    assert review.label_of_point(frame, column) == -1
    span = stack.push(AssignLabel(frame, column, "M4", scope="take"))
    assert span == (0, FRAMES)
    assert np.array_equal(review.assignment[:, 4], result.assignment[:, 4])
    stack.undo()
    stack.push(AssignLabel(frame, column, "M4", scope="fragment"))
    assert (review.assignment[:frame, 4] == -1).all()
    assert np.array_equal(review.assignment[frame:, 4], result.assignment[frame:, 4])
    stack.undo()
    stack.push(AssignLabel(frame, column, "M4", scope="range", start=25, stop=35))
    assert np.array_equal(np.flatnonzero(review.assignment[:, 4] >= 0), np.arange(25, 35))


def test_mark_ghost_and_assign_clears_it(labelled):
    review, _, _ = labelled
    stack = UndoStack(review)
    frame, column = 12, int(review.assignment[12, 2])
    stack.push(MarkGhost(frame, column, scope="range", start=10, stop=15))
    assert (review.assignment[10:15, 2] == -1).all()
    assert review.ghost[frame, column]
    assert stack.undo_text() == "mark ghost 'M2' at frames 11-15"
    stack.push(AssignLabel(frame, column, "M2", scope="fragment"))
    assert not review.ghost[frame, column]
    assert review.assignment[frame, 2] == column


def test_fills_accept_reject(labelled):
    review, _, truth = labelled
    stack = UndoStack(review)
    start, length = FRAMES // 3, FRAMES // 6
    fill = np.linspace(truth[start - 1, 0], truth[start + length, 0], length + 2)[1:-1]
    with pytest.raises(InputError, match="measured points"):
        stack.push(AcceptFills([GapFill("M0", start - 1, "linear", fill)]))
    with pytest.raises(InputError, match="unknown fill method"):
        stack.push(AcceptFills([GapFill("M0", start, "magic", fill)]))
    assert stack.index == 0
    span = stack.push(AcceptFills([GapFill("M0", start, "linear", fill),
                                   GapFill("M1", start + 3, "model", truth[start + 3:start + 3 + length, 1])]))
    assert span == (start, start + 3 + length)
    assert stack.undo_text() == "fill 2 gaps"
    assert (review.provenance[start:start + length, 0] == 1).all()
    assert (review.provenance[start + 3:start + 3 + length, 1] == 5).all()
    assert np.array_equal(review.labelled_positions()[start:start + length, 0], fill)
    assert (review.lane_states()[start:start + length, 0] == LANE_FILLED).all()
    assert review.marker_stats().gap_count[:2].tolist() == [0, 0]
    assert review.problems(["gap"]) == []
    stack.push(RejectFills("M0", 0, FRAMES))
    assert (review.provenance[:, 0] <= 0).all() and np.isnan(review.filled_positions[:, 0]).all()
    assert (review.provenance[start + 3:start + 3 + length, 1] == 5).all()
    with pytest.raises(InputError, match="no accepted fill"):
        stack.push(RejectFills("M0", 0, FRAMES))
    # a measured point assigned inside a fill replaces the fill there
    stack.push(RejectFills(None, 0, FRAMES))
    assert (review.provenance <= 0).all()


def test_assigning_a_point_over_a_fill_drops_the_fill(labelled):
    review, result, truth = labelled
    stack = UndoStack(review)
    start, length = FRAMES // 3, FRAMES // 6
    stack.push(AcceptFills([GapFill("M0", start, "spline", truth[start:start + length, 0])]))
    ghost_frame = next(f for f in range(start, start + length - 1) if result.ghost_points[f].any())
    column = int(np.flatnonzero(result.ghost_points[ghost_frame])[0])
    assert review.ghost[ghost_frame, column]
    stack.push(AssignLabel(ghost_frame, column, "M0", scope="range", start=ghost_frame, stop=ghost_frame + 1))
    assert review.provenance[ghost_frame, 0] == 0 and np.isnan(review.filled_positions[ghost_frame, 0]).all()
    assert not review.ghost[ghost_frame, column]
    assert review.provenance[ghost_frame + 1, 0] == 2
    assert review.lane_states()[ghost_frame, 0] == LANE_EDITED


def test_bad_edits_raise_and_change_nothing(labelled):
    review, _, _ = labelled
    before = copy.deepcopy(review)
    stack = UndoStack(review)
    bad = [
        AssignLabel(5, int(review.assignment[5, 0]), "nope"),
        AssignLabel(FRAMES + 3, 0, "M1"),
        AssignLabel(5, 99, "M1"),
        Unlabel(label="M0", scope="range", start=40, stop=30),
        Unlabel(5, int(review.assignment[5, 0]), scope="sideways"),
        SwapLabels("M0", "M0", 0, 10),
        SetSolve(3, 0, np.zeros((4, 26))),
        SetSolve(0, FRAMES - 2, np.zeros((4, 26))),
        ApplyLabelling(synthetic_labelling(frames=FRAMES + 1)[1]),
    ]
    missing_column = int(np.flatnonzero(np.isnan(review.take.marker_positions[1]).any(axis=1))[0])
    bad.append(AssignLabel(1, missing_column, "M1"))
    for command in bad:
        with pytest.raises(InputError):
            stack.push(command)
    assert review.same_state(before)
    assert stack.index == 0 and not stack.can_undo()


def _random_command(review, rng):
    names = review.label_names
    frame = int(rng.integers(review.n_frames))
    present = np.flatnonzero(np.isfinite(review.take.marker_positions[frame]).all(axis=1))
    column = int(rng.choice(present))
    start = int(rng.integers(0, review.n_frames - 5))
    stop = start + int(rng.integers(1, 20))
    scope = str(rng.choice(["fragment", "range", "take"]))
    kind = rng.integers(7)
    if kind == 0:
        return AssignLabel(frame, column, str(rng.choice(names)), scope=scope, start=start, stop=stop)
    if kind == 1:
        first, second = rng.choice(len(names), 2, replace=False)
        return SwapLabels(names[first], names[second], start, stop)
    if kind == 2:
        return MarkGhost(frame, column, scope=scope, start=start, stop=stop)
    if kind == 3:
        return Unlabel(label=str(rng.choice(names)), scope="range", start=start, stop=stop)
    if kind == 4:
        label = int(rng.integers(len(names)))
        missing = np.flatnonzero(review.assignment[:, label] < 0)
        if not missing.size:
            return Unlabel(label=names[label], scope="take")
        first = int(missing[0])
        length = 1
        while first + length < review.n_frames and review.assignment[first + length, label] < 0 and length < 8:
            length += 1
        return AcceptFills([GapFill(names[label], first, str(rng.choice(["linear", "model"])),
                                    rng.normal(size=(length, 3)) * 10.0)])
    if kind == 5:
        return RejectFills(None, 0, review.n_frames)
    return SetSolve(0, start, rng.normal(size=(stop - start, 26)) if stop <= review.n_frames else
                    rng.normal(size=(1, 26)), None)


@pytest.mark.parametrize("seed", range(6))
def test_random_edit_sequences_undo_and_redo_exactly(labelled, seed):
    review, _, _ = labelled
    rng = np.random.default_rng(seed)
    stack = UndoStack(review)
    states = [copy.deepcopy(review)]
    applied = []
    while len(applied) < 10:
        command = _random_command(review, rng)
        try:
            stack.push(command)
        except InputError:
            assert review.same_state(states[-1])
            continue
        applied.append(command)
        states.append(copy.deepcopy(review))
        if rng.random() < 0.3:  # a re-solve attached to the edit
            span = command.span
            stack.attach(SetSolve(0, span.start, rng.normal(size=(span.stop - span.start, 26)),
                                  rng.normal(size=(span.stop - span.start, 5))))
            states[-1] = copy.deepcopy(review)
    for state in reversed(states[:-1]):
        stack.undo()
        assert review.same_state(state)
    assert not stack.can_undo()
    for state in states[1:]:
        stack.redo()
        assert review.same_state(state)
    # every command survives JSON and replays to the same state on a fresh copy
    fresh = copy.deepcopy(states[0])
    replay = UndoStack(fresh)
    for command in stack.commands:
        data = json.loads(json.dumps(command.to_json()))
        replay.push(command_from_json(data))
    assert fresh.same_state(review)


def test_apply_labelling_is_undoable(labelled):
    review, result, _ = labelled
    empty = ReviewTake.unlabelled(review.take)
    stack = UndoStack(empty)
    stack.push(ApplyLabelling(result))
    assert empty.label_names == result.marker_names
    assert np.array_equal(empty.assignment, result.assignment)
    assert len(empty.hands) == 1 and empty.hands[0].labels.tolist() == [0, 1, 2, 3, 4]
    stack.undo()
    assert empty.n_labels == 0 and empty.hands == []
    stack.redo()
    assert empty.same_state(review) is False  # layout name differs: "test" vs None
    assert np.array_equal(empty.assignment, review.assignment)


def test_attached_solve_is_undone_with_its_edit(labelled):
    review, _, _ = labelled
    stack = UndoStack(review)
    angles_before = review.hands[0].joint_angles.copy()
    span = stack.push(Unlabel(label="M2", scope="range", start=10, stop=20))
    stack.attach(SetSolve(0, span.start, np.ones((10, 26)), np.full((10, 5), 2.0)))
    assert stack.texts() == ["unlabel 'M2' at frames 11-20"]
    assert (review.hands[0].joint_angles[10:20] == 1.0).all()
    assert np.isnan(review.residuals_mm[10:20, 2]).all() and (review.residuals_mm[10:20, 3] == 2.0).all()
    assert isinstance(stack.commands[0], CompoundCommand)
    stack.undo()
    assert np.array_equal(review.hands[0].joint_angles, angles_before)
    stack.redo()
    assert (review.hands[0].joint_angles[10:20] == 1.0).all()


def test_undo_stack_state_listeners_limit_and_recorder(labelled):
    review, _, _ = labelled
    events = []
    stack = UndoStack(review, limit=3)
    stack.add_listener(lambda change: events.append((change.operation, tuple(change.span))))
    assert stack.is_clean() and not stack.can_undo() and not stack.can_redo()
    for label in ("M0", "M1", "M2", "M3"):
        stack.push(Unlabel(label=label, scope="range", start=0, stop=5))
    assert len(stack.texts()) == 3 and stack.texts()[0].startswith("unlabel 'M1'")
    assert not stack.is_clean()
    stack.set_clean()
    assert stack.is_clean()
    stack.undo()
    assert not stack.is_clean() and stack.can_redo() and stack.redo_text().startswith("unlabel 'M3'")
    stack.redo()
    assert stack.is_clean()
    assert events[0] == ("do", (0, 5)) and ("undo", (0, 5)) in events and events[-1][0] == "redo"
    # a failing recorder (e.g. the journal cannot be written) leaves the review unchanged
    before = copy.deepcopy(review)

    def failing(operation, command):
        raise InputError("disk full")

    stack.recorder = failing
    with pytest.raises(InputError, match="disk full"):
        stack.push(Unlabel(label="M4", scope="take"))
    with pytest.raises(InputError, match="disk full"):
        stack.undo()
    assert review.same_state(before) and stack.index == 3


def test_an_edit_its_undo_and_its_redo_each_announce_what_changed(labelled):
    review, result, _ = labelled
    stack = UndoStack(review)
    heard: list[ReviewChanged] = []
    stack.add_listener(heard.append)
    stack.push(Unlabel(label="M1", scope="range", start=10, stop=20))
    edit = ReviewChanged("do", (10, 20), Change.LABELS | Change.FILLS | Change.SOLVE)
    assert heard == [edit]
    stack.attach(SetSolve(0, 10, np.zeros((10, 26))))
    assert heard[-1] == ReviewChanged("attach", (10, 20), Change.SOLVE)
    stack.undo()
    assert heard[-1] == ReviewChanged("undo", (10, 20), edit.what) and not heard[-1].structure
    stack.redo()
    assert heard[-1] == ReviewChanged("redo", (10, 20), edit.what)
    stack.push(AcceptFills([GapFill("M0", FRAMES // 3, "linear", np.ones((2, 3)))]))
    assert heard[-1] == ReviewChanged("do", (FRAMES // 3, FRAMES // 3 + 2), Change.FILLS)
    stack.undo()
    assert heard[-1].operation == "undo" and heard[-1].what == Change.FILLS
    stack.push(ApplyLabelling(result))                       # auto-label again: the whole review
    assert heard[-1].what == Change.ALL and heard[-1].structure and heard[-1].span == (0, FRAMES)
    stack.undo()
    assert heard[-1] == ReviewChanged("undo", (0, FRAMES), Change.ALL)
    stack.set_clean()
    assert heard[-1] == ReviewChanged("clean", (0, 0), Change.NONE)
    stack.remove_listener(heard.append)
    stack.redo()
    assert heard[-1].operation == "clean"


def test_scene_labelling_result_gives_one_track_per_hand(labelled):
    review, result, _ = labelled

    class Model:
        def __init__(self, name, kind, markers):
            self.name, self.kind, self.markers = name, kind, markers

    class Scene:
        marker_names = ["R_a", "R_b", "L_a", "L_b", "box_1"]
        assignment, confidence = result.assignment, result.confidence
        residuals_mm, ghost_points = result.residuals_mm, result.ghost_points
        joint_angles = {"right": np.ones((FRAMES, 26)), "left": np.zeros((FRAMES, 26))}
        models = [Model("right", "right", slice(0, 2)), Model("left", "left", slice(2, 4)),
                  Model("box", "object", slice(4, 5))]
        rigid_bodies = {"box": [2, 3, 4]}

    scene = ReviewTake.from_labelling(review.take, Scene(), layout="glove-13")
    assert [(h.name, h.side, h.layout, h.labels.tolist()) for h in scene.hands] == [
        ("right", "right", "glove-13", [0, 1]), ("left", "left", "glove-13", [2, 3])]
    assert (scene.hands[0].joint_angles == 1).all() and scene.hand_of_label(4) == -1
    assert scene.hand_of_label(3) == 1
    # a rigid body is drawn as a line between every two of its labels seen in the frame
    assert scene.rigid_bodies == {"box": [2, 3, 4]}
    positions = scene.labelled_positions()
    frame = int(np.flatnonzero(np.isfinite(positions[:, 2:5]).all(axis=(1, 2)))[0])
    segments = scene.rigid_body_segments(frame)
    assert segments.shape == (3, 2, 3)
    np.testing.assert_array_equal(segments[0], positions[frame, [2, 3]])
    UndoStack(scene).push(Unlabel(label="box_1", scope="range", start=0, stop=10))   # one marker hidden
    assert scene.rigid_body_segments(5).shape == (1, 2, 3) and len(scene.rigid_body_segments(10)) == 3
    with pytest.raises(InputError, match="rigid body 'box'"):
        ReviewTake(**{**scene.__dict__, "rigid_bodies": {"box": [7]}, "_cache": {}})


def test_undo_keeps_only_what_changed(labelled):
    review, _, _ = labelled
    stack = UndoStack(review)
    stack.push(SwapLabels("M1", "M2", 0, FRAMES))
    saved = stack.commands[0].saved_state()[1]
    stored = sum(value.size for value in saved.values())
    assert stored < 12 * FRAMES * 2  # the two labels' columns only, not the whole take
    assert set(saved) >= {"assignment.index", "assignment.values"}


def test_define_a_hand_on_a_labelled_take(labelled):
    from handmocap.core.review import DefineHand

    review, _, _ = labelled
    take = review.labelled_take()
    labelled_review = ReviewTake.from_labelled_take(take)
    assert labelled_review.hands == []
    stack = UndoStack(labelled_review)
    stack.push(DefineHand("right", "right", ["M2", "M0", "M1"], "glove-13"))
    hand = labelled_review.hands[0]
    assert hand.labels.tolist() == [2, 0, 1] and hand.layout == "glove-13"
    assert np.isnan(hand.joint_angles).all() and hand.joint_angles.shape == (FRAMES, 26)
    stack.push(SetSolve(0, 0, np.zeros((FRAMES, 26)), np.ones((FRAMES, 3))))
    assert (labelled_review.residuals_mm[:, 2][labelled_review.assignment[:, 2] >= 0] == 1).all()
    stack.push(DefineHand("right", "right", ["M3"], None))  # replaces the hand of that name
    assert len(labelled_review.hands) == 1 and labelled_review.hands[0].labels.tolist() == [3]
    with pytest.raises(InputError):
        stack.push(DefineHand("left", "middle", ["M3"]))
    with pytest.raises(InputError):
        stack.push(DefineHand("left", "left", ["nope"]))
    stack.undo()
    stack.undo()
    assert labelled_review.hands[0].labels.tolist() == [2, 0, 1]
    stack.undo()
    assert labelled_review.hands == []
