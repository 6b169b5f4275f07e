"""Exports of a review: labelled C3D read back by ezc3d, the c3d package and our reader; CSV; BVH."""

import warnings

import c3d
import ezc3d
import numpy as np
import pytest
from simulated_files import solved_review

from handmocap.core.errors import InputError
from handmocap.core.evaluation.data import REAL_RECORDING, VENDOR_C3D
from handmocap.core.io import load_take
from handmocap.core.io.errors import TakeFormatError
from handmocap.core.io.labelled_c3d import decode_runs, encode_runs, read_labelled_c3d, write_labelled_c3d
from handmocap.core.model import load_template
from handmocap.core.model.bvh import read_bvh, write_bvh
from handmocap.core.review import (
    AcceptFills,
    AssignLabel,
    GapFill,
    MarkGhost,
    ReviewTake,
    SetSolve,
    UndoStack,
    export_bvh,
    export_joint_angles_csv,
    export_labelled_c3d,
    review_from_labelled_c3d,
)
from handmocap.core.review.synthetic import synthetic_labelling
from handmocap.core.simulate.motion import simulate_joint_angles

FRAMES = 90


@pytest.fixture
def reviewed():
    """A review with a fill, a hand edit, a ghost and solved joint angles."""
    review, truth = solved_review(FRAMES, seed=4, ghosts=2)
    stack = UndoStack(review)
    start, length = FRAMES // 3, FRAMES // 6
    stack.push(AcceptFills([GapFill("M0", start, "model", truth[start:start + length, 0] + 0.25)]))
    stack.push(AssignLabel(70, int(review.assignment[70, 4]), "M4", scope="range", start=70, stop=80))
    stack.push(MarkGhost(label="M3", scope="range", start=5, stop=8))
    return review, truth


def _c3d_package_read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with open(path, "rb") as handle:
            reader = c3d.Reader(handle)
            labels = [label.strip() for label in reader.point_labels]
            frames = np.array([points for _, points, _ in reader.read_frames()])
    return labels, frames


def test_labelled_c3d_is_read_back_by_ezc3d_and_the_c3d_package(tmp_path, reviewed):
    review, truth = reviewed
    path = tmp_path / "labelled.c3d"
    export_labelled_c3d(review, path)
    unlabelled = np.flatnonzero(review.unlabelled_points().any(axis=0))
    expected_labels = review.label_names + [f"*{column}" for column in unlabelled]
    measured = review.assignment >= 0
    filled = review.provenance > 0
    positions = review.labelled_positions()

    ez = ezc3d.c3d(str(path))
    assert ez["parameters"]["POINT"]["LABELS"]["value"] == expected_labels
    points = ez["data"]["points"][:3].transpose(2, 1, 0)  # (F, P, 3)
    residuals = ez["data"]["meta_points"]["residuals"][0].T  # (F, P)
    labelled = points[:, :review.n_labels]
    assert np.array_equal(labelled[measured], review.measured_positions()[measured])  # bit for bit
    assert np.allclose(labelled[filled], positions[filled], atol=1e-4)
    assert (residuals[:, :review.n_labels][~(measured | filled)] < 0).all()
    assert (residuals[:, :review.n_labels][measured | filled] == 0).all()
    assert ez["parameters"]["PROVENANCE"]["LABELLED"]["value"][0] == review.n_labels

    labels, frames = _c3d_package_read(path)
    assert labels == expected_labels
    assert frames.shape == (FRAMES, len(expected_labels), 5)
    assert np.array_equal(frames[:, :review.n_labels, :3][measured], review.measured_positions()[measured])
    assert (frames[:, :review.n_labels, 3][~(measured | filled)] < 0).all()

    ours = load_take(path)
    assert ours.marker_names == expected_labels


def test_labelled_c3d_round_trip_into_a_review(tmp_path, reviewed):
    review, _ = reviewed
    path = tmp_path / "labelled.c3d"
    export_labelled_c3d(review, path)
    back = review_from_labelled_c3d(path)
    assert back.label_names == review.label_names
    assert np.array_equal(back.provenance, review.provenance)
    assert np.array_equal(back.edited, review.edited)
    assert np.array_equal(back.measured_positions(), review.measured_positions(), equal_nan=True)
    assert np.allclose(back.labelled_positions(), review.labelled_positions(), atol=1e-4, equal_nan=True)
    # the unlabelled points come back as unlabelled raw points, ghosts flagged
    assert back.unlabelled_points().sum() == review.unlabelled_points().sum()
    assert back.ghost.sum() == (review.ghost & review.unlabelled_points()).sum() > 0
    stats, back_stats = review.marker_stats(), back.marker_stats()
    assert np.array_equal(stats.gap_count, back_stats.gap_count)
    assert np.allclose(stats.observed_percent, back_stats.observed_percent)
    # a fill never counts as a raw point
    assert np.isnan(back.take.marker_positions[review.provenance[:, 0] > 0, 0]).all()
    # only labels, no unlabelled points
    export_labelled_c3d(review, path, unlabelled="none")
    assert read_labelled_c3d(path).take.marker_names == review.label_names
    export_labelled_c3d(review, path, unlabelled="non-ghost")
    assert not read_labelled_c3d(path).ghost.any()
    with pytest.raises(InputError):
        export_labelled_c3d(review, path, unlabelled="some")


def test_provenance_runs_are_split_into_parameters_of_at_most_255(tmp_path):
    rng = np.random.default_rng(0)
    frames, labels = 3000, 4
    positions = rng.normal(0.0, 100.0, (frames, labels, 3)).astype(np.float32).astype(np.float64)
    provenance = np.zeros((frames, labels), dtype=np.int64)
    provenance[::3, 1] = rng.integers(1, 6, frames // 3)  # 1000 runs
    provenance[100:400, 2] = -1
    positions[provenance == -1] = np.nan
    edited = rng.random((frames, labels)) < 0.1
    path = tmp_path / "many.c3d"
    write_labelled_c3d(path, ["a", "b", "c", "d"], positions, provenance, 100.0, first_frame=0, edited=edited)
    group = ezc3d.c3d(str(path))["parameters"]["PROVENANCE"]
    run_parameters = [name for name in group if name.startswith("RUNS")]
    assert len(run_parameters) >= 4
    assert all(max(group[name]["value"].shape) <= 255 for name in run_parameters)
    back = read_labelled_c3d(path)
    assert np.array_equal(back.provenance, provenance)
    assert np.array_equal(back.edited, edited)
    assert back.take.first_frame == 0


@pytest.mark.parametrize("seed", range(5))
def test_run_length_coding_round_trips(seed):
    rng = np.random.default_rng(seed)
    values = rng.integers(-1, 3, (int(rng.integers(1, 50)), int(rng.integers(1, 6))))
    runs = encode_runs(values, skip=0)
    assert (runs[3] != 0).all()
    assert np.array_equal(decode_runs(runs, values.shape, dtype=np.int64), values)


def test_a_foreign_labelled_c3d_reads_as_measured_labels(tmp_path):
    take, _, _ = synthetic_labelling(frames=20, shuffle=False, ghosts=0)
    path = tmp_path / "vendor.c3d"
    from handmocap.core.io import save_take

    save_take(take, path)
    back = review_from_labelled_c3d(path)
    assert back.label_names == take.marker_names
    assert (back.provenance[np.isfinite(take.marker_positions).all(axis=2)] == 0).all()


def test_damaged_provenance_group_is_a_clear_error(tmp_path):
    path = tmp_path / "damaged.c3d"
    positions = np.ones((5, 2, 3))
    write_labelled_c3d(path, ["a", "b"], positions, np.zeros((5, 2)), 100.0)
    c3d_file = ezc3d.c3d(str(path))
    c3d_file["parameters"]["PROVENANCE"]["RUNS"] = {"type": 4, "value": np.arange(5.0), "description": "",
                                                    "is_locked": False}
    c3d_file.write(str(path))
    with pytest.raises(TakeFormatError, match="damaged PROVENANCE"):
        read_labelled_c3d(path)


def test_joint_angles_csv(tmp_path, reviewed):
    review, _ = reviewed
    stack = UndoStack(review)
    stack.push(SetSolve(0, 10, np.full((2, 26), np.nan)))
    path = tmp_path / "angles.csv"
    export_joint_angles_csv(review, path)
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    assert header[:4] == ["frame", "time_s", "wrist_tx_mm", "wrist_ty_mm"] and header[5] == "wrist_rx_deg"
    assert len(header) == 28 and len(lines) == FRAMES + 1
    first = lines[1].split(",")
    assert first[0] == "1" and float(first[1]) == 0.0
    angles = review.hands[0].joint_angles
    assert np.isclose(float(first[8]), np.degrees(angles[0, 6]), atol=1e-5)
    assert np.isclose(float(first[2]), angles[0, 0], atol=1e-5)
    assert lines[11].split(",")[2:] == [""] * 26  # frame 10 not solved
    with pytest.raises(InputError, match="no solved hand"):
        export_joint_angles_csv(ReviewTake.unlabelled(review.take), path)


@pytest.mark.parametrize("side", ["right", "left"])
def test_bvh_forward_kinematics_matches_the_model(tmp_path, side):
    model = load_template(side)
    angles = simulate_joint_angles(40, 1, "mixed", 100.0)
    path = tmp_path / "hand.bvh"
    write_bvh(path, model.skeleton, angles, 100.0, prefix="R_" if side == "right" else "L_")
    motion = read_bvh(path)
    assert motion.n_frames == 40 and np.isclose(motion.frame_time, 0.01)
    assert len(motion.joint_names) == 16 and motion.joint_names[1].endswith("thumb_cmc")
    assert len(motion.end_sites) == 5
    positions = motion.world_positions()
    expected = np.array([model.chain.joint_transforms(theta)[1] for theta in angles])
    assert np.abs(positions - expected).max() < 1e-3
    # rotation channels are continuous (unwrapped)
    assert np.abs(np.diff(motion.motion[:, 3:], axis=0)).max() < 90.0
    write_bvh(path, model.skeleton, angles, 100.0, units="cm")
    assert np.abs(read_bvh(path).world_positions() * 10.0 - expected).max() < 1e-2


def test_bvh_export_of_a_review_and_bad_input(tmp_path, reviewed):
    review, _ = reviewed
    path = tmp_path / "review.bvh"
    UndoStack(review).push(SetSolve(0, 0, np.full((3, 26), np.nan)))
    export_bvh(review, path, load_template("right"))
    motion = read_bvh(path)
    assert motion.n_frames == FRAMES
    assert np.array_equal(motion.motion[0], motion.motion[3])  # unsolved frames hold the nearest solve
    with pytest.raises(InputError, match="right hand"):
        export_bvh(review, path, load_template("left"))
    with pytest.raises(InputError, match="no hand"):
        export_bvh(review, path, load_template("right"), hand=2)
    path.write_text("HIERARCHY\nROOT a\n{\nOFFSET 0 0\n")
    with pytest.raises(InputError, match="malformed BVH"):
        read_bvh(path)


@pytest.mark.skipif(not REAL_RECORDING.exists(), reason="shared data absent")
def test_real_recording_exports_its_measured_coordinates_unchanged(tmp_path):
    take = load_take(REAL_RECORDING)
    take.marker_positions = take.marker_positions[:300]
    review = ReviewTake.from_labelled_take(take)
    path = tmp_path / "real.c3d"
    export_labelled_c3d(review, path)
    back = read_labelled_c3d(path)
    assert back.label_names == take.marker_names
    present = np.isfinite(take.marker_positions).all(axis=2)
    assert np.array_equal(back.provenance == 0, present)
    stored = back.labelled_positions[present]
    assert np.array_equal(stored, take.marker_positions[present].astype(np.float32).astype(np.float64))


@pytest.mark.skipif(not VENDOR_C3D.is_dir(), reason="shared data absent")
@pytest.mark.parametrize("name", ["sample_00__Motion_Analysis_Corporation__Walk1.c3d", "sample_01__Eb015pi.c3d",
                                  "sample_02__dec_int.c3d", "sample_37__ART-Human_hands_real_no6dof.c3d"])
def test_vendor_files_export_unchanged_with_their_parameter_groups(tmp_path, name):
    path = VENDOR_C3D / name
    if not path.exists():
        pytest.skip(f"{name} absent")
    take = load_take(path)
    review = ReviewTake.from_labelled_take(take)
    out = tmp_path / "out.c3d"
    export_labelled_c3d(review, out)
    back = read_labelled_c3d(out)
    present = np.isfinite(take.marker_positions).all(axis=2)
    assert back.label_names == take.marker_names
    assert np.array_equal(back.labelled_positions[present],
                          take.marker_positions[present].astype(np.float32).astype(np.float64))
    assert set(take.parameters) - {"MANUFACTURER"} <= set(back.take.parameters)
    labels, frames = _c3d_package_read(out)
    assert labels == take.marker_names and frames.shape[:2] == (take.n_frames, take.n_markers)


def test_two_hands_export_prefixed_columns_and_joints(tmp_path, reviewed):
    from handmocap.core.review import HandTrack

    review, _ = reviewed
    angles = simulate_joint_angles(FRAMES, 2, "mixed", 100.0)
    review.hands = [HandTrack("right", "right", None, [0, 1, 2], angles),
                    HandTrack("left", "left", None, [3, 4], angles + 0.01)]
    path = tmp_path / "both.csv"
    export_joint_angles_csv(review, path)
    header = path.read_text().splitlines()[0].split(",")
    assert len(header) == 2 + 2 * 26 and header[2] == "R_wrist_tx_mm" and header[28] == "L_wrist_tx_mm"
    export_bvh(review, tmp_path / "left.bvh", load_template("left"), hand="left")
    motion = read_bvh(tmp_path / "left.bvh")
    assert motion.joint_names[0] == "L_wrist"
    expected = np.array([load_template("left").chain.joint_transforms(theta)[1] for theta in angles + 0.01])
    assert np.abs(motion.world_positions() - expected).max() < 1e-3
