"""The labelling's health warnings and noise estimate in the review: carried by ApplyLabelling, undone with
it, journalled, kept in snapshots, listed as problems (F3) and summed up for the status bar."""

import numpy as np
import pytest

from handmocap.core.io import save_take
from handmocap.core.labelling.health_warning import HealthWarning
from handmocap.core.labelling.result import SceneLabelling, SceneModel
from handmocap.core.review import ApplyLabelling, LabellingArrays, ReviewTake, UndoStack, command_from_json
from handmocap.core.review.synthetic import synthetic_labelling
from handmocap.core.session import Session
from handmocap.core.workflows.labelling import result_health

FRAMES = 200
WARNINGS = [HealthWarning("side_uncertain", "right", 0, 0, "the right hand was told from its mirror image by a "
                          "small margin (0.05): check the side"),
            HealthWarning("low_labelled_share", "right", 120, 159, "the right hand labels 20 % of its markers here")]


@pytest.fixture
def labelled():
    take, result, _truth = synthetic_labelling(frames=FRAMES, labels=5, ghosts=1, seed=1)
    arrays = LabellingArrays(list(result.marker_names), result.assignment, result.confidence, result.residuals_mm,
                             result.ghost_points, [], health=list(WARNINGS), noise_mm=0.42)
    return take, arrays


def test_apply_labelling_carries_health_and_undo_removes_it(labelled):
    take, arrays = labelled
    review = ReviewTake.unlabelled(take)
    stack = UndoStack(review)
    stack.push(ApplyLabelling(arrays))
    assert review.health == WARNINGS and review.noise_mm == pytest.approx(0.42)
    record = stack.commands[-1].to_json()
    again = ReviewTake.unlabelled(take)
    command_from_json(record).do(again)
    assert again.same_state(review)
    stack.undo()
    assert review.health == [] and review.noise_mm is None
    stack.redo()
    assert review.health == WARNINGS


def test_health_warnings_are_problems_and_summed_up(labelled):
    take, arrays = labelled
    review = ReviewTake.unlabelled(take)
    ApplyLabelling(arrays).do(review)
    problems = review.problems(["labelling"])
    assert [(p.start, p.stop) for p in problems] == [(0, 1), (120, 160)]
    assert all(p.text.startswith("Auto-label: ") for p in problems)
    assert f"frames {take.first_frame + 120}-{take.first_frame + 159}" in problems[1].text
    found = review.next_problem(60, kinds=["labelling"])
    assert found is not None and found.start == 120
    assert review.next_problem(130, kinds=["labelling"], forward=False).start == 120
    summary = review.health_summary()
    assert summary.startswith("Auto-label: 2 warnings — the right hand was told from its mirror image")
    assert ReviewTake.unlabelled(take).health_summary() == ""


def test_health_survives_journal_replay_snapshot_and_undo(tmp_path, labelled):
    take, arrays = labelled
    path = tmp_path / "raw.c3d"
    save_take(take, path)
    session = Session.create(tmp_path / "session")
    entry = session.add_take(path)
    opened = session.open_take(entry.id)
    opened.push(ApplyLabelling(arrays))
    opened.close(save=False)  # the process "dies" unsaved (the kernel releases its take lock)
    replayed = Session.open(tmp_path / "session").open_take(entry.id)
    assert replayed.replayed == 1 and replayed.review.health == WARNINGS
    assert replayed.review.noise_mm == pytest.approx(0.42)
    replayed.save()
    replayed.close()
    reopened = Session.open(tmp_path / "session").open_take(entry.id)
    assert reopened.replayed == 0 and reopened.review.health == WARNINGS
    reopened.undo()
    assert reopened.review.health == [] and reopened.review.noise_mm is None
    reopened.redo()
    assert reopened.review.health == WARNINGS


def _scene(assignment: np.ndarray, points: int) -> SceneLabelling:
    frames, markers = assignment.shape
    model = SceneModel("right", "right", slice(0, markers), init_frame=0)
    return SceneLabelling([f"m{i}" for i in range(markers)], np.zeros(markers, np.int64), [model], assignment,
                         np.zeros(assignment.shape), np.zeros(assignment.shape), np.zeros((frames, points), bool),
                         {"right": np.zeros((frames, 26))}, {}, np.zeros((frames, points, 3)))


def test_result_health_low_share_and_no_hand():
    frames, markers = 300, 10
    present = np.ones((frames, markers), dtype=bool)
    full = np.tile(np.arange(markers), (frames, 1))
    assert result_health(_scene(full, markers), present) == []
    half = full.copy()
    half[:, 6:] = -1                                   # 60 % labelled while every point is there
    kinds = [(w.kind, w.model, w.first_frame, w.last_frame) for w in result_health(_scene(half, markers), present)]
    assert kinds == [("low_labelled_share", "right", 0, frames - 1)]
    stray = np.full((frames, markers), -1)
    stray[:5, :6] = np.arange(6)                       # a hand fitted to stray points in 5 frames
    warnings = result_health(_scene(stray, markers), present)
    assert [w.kind for w in warnings] == ["no_hand"] and warnings[0].model == ""
