"""Auto-label keeps what the file knows: labels outside the layout stay labels (not ghosts, measured, in the
exported C3D), the file's hand labels are evidence (``relabel`` labels afresh), and a solve of the labelled
C3D uses the subject calibration auto-label made; solve and label refuse what they cannot do."""

import json

import numpy as np
import pytest

from handmocap.app.cli.main import main
from handmocap.core.errors import InputError
from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.io import Take, TakeFormatError, is_marker_label, load_take, save_take
from handmocap.core.io.labelled_c3d import (
    SUBJECT_GROUP,
    SubjectCalibration,
    read_labelled_c3d,
    subject_calibrations,
    subject_group,
)
from handmocap.core.model import load_layout, load_template, resolve_layout
from handmocap.core.review import MEASURED, ReviewTake, export_labelled_c3d
from handmocap.core.simulate import simulate_take
from handmocap.core.workflows.labelling import auto_label, subject_model
from handmocap.core.workflows.resolve import solve_labelled_take

OTHER = ["right_elbow", "back_top", "back_left", "back_right", "right_shoulder", "pillow_top", "pillow_left",
         "pillow_right"]


@pytest.mark.parametrize("name", ["hand_top", "pillow_left", "LASI", "R_thumb_tip", "marker_top", "M1_base",
                                  "Point of interest", "elbow2", "Marker1", "M7", "m7", "2003", "Channel103",
                                  "L-Wan-nei", "New 0001", "point 12", "ghost_1", "unnamed"])
def test_names_the_file_gives_are_labels(name):
    assert is_marker_label(name)


@pytest.mark.parametrize("name", ["", "  ", "point_000", "point_1204", "ghost_012", "*12", "*3_2", "uname*2",
                                  "Unlabeled 3", "Unlabeled 1003", "Unlabeled_1003", "Unlabeled:108",
                                  "unlabelled_4", "Unidentified 7"])
def test_vendor_placeholders_of_unlabelled_points_are_not_labels(name):
    assert not is_marker_label(name)


def _with_extra_labels(take: Take, frames: int, names: list[str], seed: int = 0) -> Take:
    """``take`` plus labelled columns ``names``: points drifting 400 mm away from the hand."""
    rng = np.random.default_rng(seed)
    extra = 400.0 + rng.uniform(-60, 60, (len(names), 3))[None] + np.cumsum(rng.normal(0, 0.3, (frames, 1, 3)), 0)
    return Take(list(take.marker_names) + names, np.concatenate([take.marker_positions, extra], axis=1),
                take.frame_rate, take.first_frame)


@pytest.fixture(scope="module")
def raw_with_body():
    simulated = simulate_take(layout="glove-13", n_frames=300, seed=3, noise_mm=0.3, ghost_rate=0.02,
                              unlabelled=True)
    return _with_extra_labels(simulated.take, 300, ["LELB", "RSHO", "pillow_top"]), simulated


def test_labels_outside_the_layout_are_kept(raw_with_body, tmp_path):
    take, _simulated = raw_with_body
    outcome = auto_label(take, "glove-13", "right")
    review = ReviewTake.unlabelled(take)
    outcome.command.do(review)
    columns = [take.marker_names.index(name) for name in ("LELB", "RSHO", "pillow_top")]
    labels = [review.label_index(name) for name in ("LELB", "RSHO", "pillow_top")]
    np.testing.assert_array_equal(review.assignment[:, labels], np.tile(columns, (300, 1)))
    assert (review.provenance[:, labels] == MEASURED).all()
    assert not review.ghost[:, columns].any()
    assert not (outcome.result.assignment[:, :13, None] == np.array(columns)).any()   # never hand candidates
    figures = outcome.report["file_labels"]
    assert figures["kept_labels"] == ["LELB", "RSHO", "pillow_top"] and figures["kept_samples"] == 900
    path = tmp_path / "labelled.c3d"
    export_labelled_c3d(review, path)
    back = read_labelled_c3d(path)
    assert back.label_names[-3:] == ["LELB", "RSHO", "pillow_top"]
    np.testing.assert_allclose(back.labelled_positions[:, -3:], take.marker_positions[:, columns], atol=1e-3)


def test_file_hand_labels_are_evidence_and_relabel_starts_afresh():
    simulated = simulate_take(layout="glove-13", n_frames=300, seed=5, noise_mm=0.3)
    take = simulated.take
    names = list(take.marker_names)
    first, second = names.index("ring_tip"), names.index("middle_tip")
    names[first], names[second] = names[second], names[first]          # the file swapped two fingertips
    swapped = Take(names, take.marker_positions, take.frame_rate, take.first_frame)
    kept = auto_label(swapped, "glove-13", "right")
    review = ReviewTake.unlabelled(swapped)
    kept.command.do(review)
    ring = review.label_index("ring_tip")
    present = np.isfinite(take.marker_positions[:, second]).all(axis=1)
    assert (review.assignment[present, ring] == second).all()             # the file's label wins
    assert kept.report["file_labels"]["disagreed_samples"] >= present.sum()
    fresh = auto_label(swapped, "glove-13", "right", relabel=True)
    review = ReviewTake.unlabelled(swapped)
    fresh.command.do(review)
    assert (review.assignment[present, ring] == first).mean() > 0.95     # the labeller's own labels
    assert review.n_labels == 13 and fresh.report["file_labels"]["disagreed_samples"] >= present.sum()


def test_a_take_labelled_for_another_layout_is_refused_unless_relabelled(tmp_path, capsys):
    simulated = simulate_take(layout="glove-13", n_frames=100, seed=2)
    body = Take([f"B{name}" for name in simulated.take.marker_names], simulated.take.marker_positions, 100.0)
    with pytest.raises(InputError, match="only 0 point columns of the take are left to label"):
        auto_label(body, "glove-13", "right")
    fresh = auto_label(body, "glove-13", "right", relabel=True)
    assert fresh.report["labelled_share"] > 0.9 and fresh.report["file_labels"]["kept_labels"] == []
    path = tmp_path / "glove.c3d"
    save_take(simulated.take, path)
    assert main(["label", str(path), "--layout", "dense", "--out", str(tmp_path / "o.c3d"), "--quiet"]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "outside layout 'dense'" in error


def test_cli_label_hands_auto_default_relabel_and_solve_with_the_subject(raw_with_body, tmp_path, capsys):
    from handmocap.app.cli.main import build_parser

    args = build_parser().parse_args(["label", "x.c3d", "--layout", "glove-13", "--out", "y.c3d"])
    assert args.hands == "auto" and args.relabel is False
    take, _simulated = raw_with_body
    raw, labelled, report = tmp_path / "raw.c3d", tmp_path / "labelled.c3d", tmp_path / "report.json"
    save_take(take, raw)
    assert main(["label", str(raw), "--layout", "glove-13", "--hands", "right", "--out", str(labelled),
                 "--report", str(report), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "marker noise σ" in out and "kept from the file: 3 labels outside the layout" in out
    figures = json.loads(report.read_text())
    assert "noise_mm" in figures and isinstance(figures["health"], list)
    assert figures["subject_calibration"] == ["right"]
    subjects = subject_calibrations(load_take(labelled).parameters)
    assert [(s.side, s.layout, s.offsets_mm.shape) for s in subjects] == [("right", "glove-13", (13, 3))]
    assert main(["solve", str(labelled), "--layout", "glove-13", "--out", str(tmp_path / "s.npz"), "--quiet"]) == 0
    assert "subject's right hand calibrated by auto-label" in capsys.readouterr().out
    assert main(["solve", str(labelled), "--layout", "glove-13", "--out", str(tmp_path / "t.npz"), "--quiet",
                 "--template"]) == 0
    assert "right template hand" in capsys.readouterr().out


def test_cli_solve_refuses_a_layout_that_matches_few_names(tmp_path, capsys):
    simulated = simulate_take(layout="glove-13", n_frames=30, seed=1)
    path = tmp_path / "take.c3d"
    save_take(simulated.take, path)
    assert main(["solve", str(path), "--layout", "dense", "--out", str(tmp_path / "s.npz"), "--quiet"]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "only 4 of the 24 markers of layout 'dense'" in error
    assert "missing" in error and not (tmp_path / "s.npz").exists()


def test_cli_label_take_without_a_hand_is_refused(tmp_path, capsys):
    rng = np.random.default_rng(1)
    points = rng.uniform(-200, 200, (15, 3))[None] + np.cumsum(rng.normal(0, 0.5, (200, 1, 3)), axis=0)
    path = tmp_path / "nohand.c3d"
    save_take(Take([f"point_{i:03d}" for i in range(15)], points, 100.0), path)
    assert main(["label", str(path), "--layout", "glove-13", "--out", str(tmp_path / "o.c3d"), "--quiet"]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "hand" in error and not (tmp_path / "o.c3d").exists()


@pytest.mark.skipif(not REAL_RECORDING.exists(), reason="the real recording is not in ../shared")
def test_real_recording_keeps_its_other_markers_and_solves_with_the_subject():
    take = load_take(REAL_RECORDING)
    outcome = auto_label(take, "glove-13", "right")
    review = ReviewTake.unlabelled(take)
    outcome.command.do(review)
    columns = [take.marker_names.index(name) for name in OTHER]
    labels = [review.label_index(name) for name in OTHER]
    present = np.isfinite(take.marker_positions[:, columns]).all(axis=2)
    assert (review.assignment[:, labels][present] == np.tile(columns, (take.n_frames, 1))[present]).all()
    assert outcome.report["file_labels"]["kept_samples"] == present.sum()
    assert outcome.report["ghost_points"] < 200 and not review.ghost[:, columns].any()
    layout = load_layout("glove-13")
    labelled = review.labelled_take()
    template = load_template("right")
    before = solve_labelled_take(labelled, template, resolve_layout(template, layout)).mean_residual_mm
    after = solve_labelled_take(labelled, outcome.models["right"], outcome.marker_sets["right"]).mean_residual_mm
    assert after < before - 0.3, (before, after)


def test_subject_calibration_round_trips_and_a_damaged_group_is_one_line():
    layout = load_layout("glove-13")
    calibration = SubjectCalibration("left", "glove-13", tuple(layout.names), np.linspace(0.9, 1.1, 15),
                                     np.arange(39.0).reshape(13, 3) / 10)
    for back in (SubjectCalibration.from_dict(calibration.as_dict()),
                 subject_calibrations({SUBJECT_GROUP: subject_group([calibration])})[0]):
        assert (back.side, back.layout, back.marker_names) == ("left", "glove-13", tuple(layout.names))
        np.testing.assert_allclose(back.offsets_mm, calibration.offsets_mm)
        np.testing.assert_allclose(back.scales, calibration.scales)
    damaged = subject_group([calibration])
    damaged["LEFT_OFFSETS"] = damaged["LEFT_OFFSETS"][:7]
    with pytest.raises(TakeFormatError, match="damaged HAND_SUBJECT"):
        subject_calibrations({SUBJECT_GROUP: damaged}, "x.c3d")
    with pytest.raises(InputError, match="made with layout 'glove-13', not 'dense'"):
        subject_model(calibration, load_layout("dense"))


def test_cli_label_claims_nothing_when_only_stray_points_fit_a_hand(tmp_path, capsys, monkeypatch):
    from handmocap.core.labelling.result import SceneLabelling, SceneModel
    from handmocap.core.workflows import labelling

    rng = np.random.default_rng(2)
    frames, count = 200, 13
    points = rng.uniform(-300, 300, (count, 3))[None] + np.cumsum(rng.normal(0, 0.5, (frames, 1, 3)), axis=0)
    take = Take([f"point_{i:03d}" for i in range(count)], points, 100.0)

    def stray_hand(offered, **_options):
        assignment = np.full((frames, count), -1)
        assignment[:4, :7] = np.arange(7)                    # a hand fitted to stray points in 4 frames
        shape = (frames, count)
        return SceneLabelling(list(load_layout("glove-13").names), np.zeros(count, np.int64),
                             [SceneModel("right", "right", slice(0, count), init_frame=0)], assignment,
                             np.ones(shape), np.ones(shape), np.zeros(shape, bool),
                             {"right": np.zeros((frames, 26))}, {}, offered.marker_positions)

    monkeypatch.setattr(labelling, "label_scene", stray_hand)
    path, report = tmp_path / "stray.c3d", tmp_path / "report.json"
    save_take(take, path)
    assert main(["label", str(path), "--layout", "glove-13", "--out", str(tmp_path / "o.c3d"), "--report",
                 str(report), "--quiet"]) == 0
    captured = capsys.readouterr()
    assert "no hand found, nothing labelled" in captured.out and "not used (no hand found)" in captured.out
    assert "handmocap: warning: no_hand" in captured.err
    figures = json.loads(report.read_text())
    assert figures["labelled_share"] == 0.0 and figures["subject_calibration"] == []
    assert read_labelled_c3d(tmp_path / "o.c3d").provenance.max() == -1     # no label holds a point
