"""The fusion evaluation's measured reason for the 0.5× target (issue 27 item 5): the hidden frames split into
those where the camera sees the hidden segments and those where it does not, and the ratio the fusion would
reach if it were exact wherever the camera sees them."""

from __future__ import annotations

import numpy as np

from handmocap.core.evaluation.fusion import _bound, evaluate_seed


def test_bound_counts_only_the_frames_the_camera_cannot_see():
    per_seed = [{"hidden_frames": 100, "seen_frames": 60, "occluded_unseen_fused": 2.0, "occluded_markers_only": 2.0},
                {"hidden_frames": 50, "seen_frames": 50, "occluded_unseen_fused": float("nan"),
                 "occluded_markers_only": 4.0}]
    assert _bound(per_seed) == round(40 * 2.0 / (100 * 2.0 + 50 * 4.0), 3)


def test_evaluate_seed_splits_the_hidden_frames_by_what_the_camera_sees():
    figures = evaluate_seed(1, n_frames=150, swarm=False)
    seen, hidden = figures["seen_frames"], figures["hidden_frames"]
    assert hidden > 0 and 0 <= seen <= hidden
    mixed = (seen * np.nan_to_num(figures["occluded_seen_fused"])
             + (hidden - seen) * np.nan_to_num(figures["occluded_unseen_fused"])) / hidden
    assert abs(mixed - figures["occluded_fused"]) < 1e-6          # the two parts make up the whole
    assert _bound([figures]) <= figures["occluded_fused"] / figures["occluded_markers_only"] + 1e-3   # rounded
