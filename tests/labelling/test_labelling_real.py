"""Automatic labelling of the real DFKI glove recording with its labels stripped (skipped without the data)."""


import numpy as np
import pytest

from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.evaluation.labelling import evaluate_real_recording, unlabelled_real_take

pytestmark = pytest.mark.skipif(not REAL_RECORDING.exists(), reason="shared data absent")


def test_stripped_take_hides_the_labels():
    take, point_marker, names = unlabelled_real_take(REAL_RECORDING, frames=100)
    assert all(name.startswith("point_") for name in take.marker_names)
    assert len(names) == 21 and "thumb_tip" in names
    ghosts = (point_marker < 0) & np.isfinite(take.marker_positions).all(axis=2)
    assert 0 < ghosts.any(axis=1).mean() < 0.2
    # shuffled: a marker does not keep its column
    thumb = names.index("thumb_tip")
    assert len({int(np.flatnonzero(row == thumb)[0]) for row in point_marker if (row == thumb).any()}) > 1


def test_real_recording_meets_the_targets():
    report = evaluate_real_recording(REAL_RECORDING, frames=600, compare_uncalibrated=False)
    assert report["hand_samples_correct_share"] >= 0.995, report
    assert report["other_marker_samples"] > 0 and report["other_marker_samples_given_hand_label"] == 0, report
    assert report["ghost_points"] > 0 and report["ghost_points_given_hand_label"] == 0, report
    assert report["mean_ik_residual_mm"] <= 3.0, report
    assert report["calibration"]["residual_after_mm"] < report["calibration"]["residual_before_mm"]
